// A simulation run as one library call: a scene (or its description) and run options in, a
// result out (status, steps, times, per-object figures, per-instrument wrench history and peaks,
// contact figures). The command line, the camera command and every batch study use it; what a
// run writes (summary, wrench table, progress) is done by observers or from the result.
#pragma once

#include <Eigen/Core>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/Roles.h"
#include "core/State.h"
#include "core/SceneDesc.h"

namespace viscera {

class RigidObject;
class Scene;
class Simulation;
struct RunResult;

// Watches a run: told before the first step, after every step and at the end. Recorders,
// progress lines and batch bookkeeping are run observers; the scene's own observers (exporters,
// cameras) are components and run inside the simulation.
class RunObserver {
 public:
  virtual ~RunObserver() = default;
  virtual void begin(const Simulation& sim, int totalSteps) {}
  virtual void step(const Simulation& sim) {}
  virtual void end(const Simulation& sim, const RunResult& result) {}
  // Asked after every step: a reason ends the run there with status Stopped (a time budget, a
  // batch that was cancelled), or Interrupted when `interrupts()` (a signal).
  virtual std::optional<std::string> stopReason() const { return std::nullopt; }
  virtual bool interrupts() const { return false; }
};

// Ends a run at the next step boundary when SIGINT or SIGTERM arrives, while it exists (the
// previous handlers are restored after); the run's status is then Interrupted. A second signal of
// the same kind ends the process the default way.
class SignalStop : public RunObserver {
 public:
  SignalStop();
  ~SignalStop() override;
  SignalStop(const SignalStop&) = delete;
  SignalStop& operator=(const SignalStop&) = delete;
  std::optional<std::string> stopReason() const override;
  bool interrupts() const override { return true; }
  int signal() const;  // the signal received, 0 if none
  // The shell's exit code for the signal received: 128 + signal (130 for SIGINT, 143 for SIGTERM).
  int exitCode() const { return 128 + signal(); }
};

struct RunOptions {
  // How long: `steps`, else `time` (in the scene's time unit, rounded to whole steps), else 100
  // steps.
  std::optional<int> steps;
  std::optional<double> time;
  // Worker threads for this run's parallel loops (0: all cores). Runs in several threads each
  // get their own arena, so two runs with one thread each use two cores.
  int threads = 0;
  // Keep every step's wrench on each instrument in the result (RunResult::Instrument::history).
  bool recordWrench = true;
  // Start from this state (captured from a simulation of the same model) instead of the scene's.
  const State* initialState = nullptr;
  std::vector<RunObserver*> observers;
};

// One step's contact wrench on an instrument (world frame, torque about its centre).
struct WrenchSample {
  double t = 0;
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
  int contacts = 0;
};

struct RunResult {
  enum class Status { Ok, Diverged, Stopped, Interrupted };
  Status status = Status::Ok;
  std::optional<Diverged> failure;
  std::string stopReason;               // Stopped or Interrupted: what the observer gave
  int steps = 0;                        // steps taken (by this run)
  double dt = 0, startTime = 0, endTime = 0;
  double wallSeconds = 0;
  std::string units;                    // the scene's unit system ("mm g s")

  struct Object {
    std::string name;
    int nodes = 0;
    double maxDisplacement = 0;         // largest |x - x0| at the end
  };
  std::vector<Object> objects;

  struct Instrument {
    std::string name;
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    WrenchSample last;
    double peakForce = 0, peakForceTime = 0;
    long stepsInContact = 0;
    std::vector<WrenchSample> history;  // every step, when RunOptions::recordWrench
  };
  std::vector<Instrument> instruments;

  struct ContactFigures {
    std::string response;               // "penalty" or "constraint"
    int maxContacts = 0;
    double maxPenetration = 0, contactDistance = 0;
  };
  std::optional<ContactFigures> contact;  // when the scene has a collision pipeline
  // The state at the end, from run(scene, ...) (whose simulation ends with the call).
  std::optional<State> finalState;

  bool ok() const { return status == Status::Ok; }
  double simulatedTime() const { return endTime - startTime; }
  double msPerStep() const { return steps ? 1000.0 * wallSeconds / steps : 0.0; }
};

// Runs `sim` (already built and initialised) for the options' steps.
RunResult run(Simulation& sim, const RunOptions& options);
// Initialises `scene` and runs a simulation of it; the result keeps its final state.
RunResult run(Scene& scene, const RunOptions& options);

// The run summary as JSON (what `viscera run --summary` writes); `scene` names the scene file.
std::string summaryJson(const RunResult& r, const std::string& scene);
// The wrench history as CSV: t, then fx,fy,fz,tx,ty,tz,contacts per instrument (prefixed with
// the instrument's name when there are several).
std::string wrenchCsv(const RunResult& r);

// The same table streamed while the run steps, to `path` + ".partial", a row per step, flushed, so
// that a run killed outright (kill -9, a power cut) leaves every step it finished. The caller writes
// the finished table with wrenchCsv at `path` as before; the partial file is removed when the
// stream is destroyed (a run that ends, however it ends, short of the process being killed).
class WrenchStream : public RunObserver {
 public:
  explicit WrenchStream(std::string path);
  ~WrenchStream() override;
  WrenchStream(const WrenchStream&) = delete;
  WrenchStream& operator=(const WrenchStream&) = delete;
  void begin(const Simulation& sim, int totalSteps) override;
  void step(const Simulation& sim) override;

 private:
  std::string partial_;
  std::FILE* file_ = nullptr;
  std::vector<const RigidObject*> bodies_;
};

// A progress line on standard error (steps, simulated time, steps/s, ETA), refreshed at most
// four times a second; silent when standard error is not a terminal or under CI.
class ProgressLine : public RunObserver {
 public:
  ProgressLine();
  void begin(const Simulation& sim, int totalSteps) override;
  void step(const Simulation& sim) override;
  void end(const Simulation& sim, const RunResult& result) override;
  bool enabled() const { return enabled_; }

 private:
  bool enabled_ = false;
  int total_ = 0, done_ = 0;
  double t0_ = 0, last_ = -1;
};

// "12.3 s", "4.5 min", "2.1 h".
std::string formatDuration(double seconds);

}  // namespace viscera
