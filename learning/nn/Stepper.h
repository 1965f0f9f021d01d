// The learned stepper (dissertation §4.4): a graph U-Net that maps a body's nodes at one frame and
// the instrument at the next to the nodes at the next frame, in place of the FEM's steps between
// two frames. Node features: offset from rest (in cells), rest position (in the body's box), a
// fixed flag, and at the node nearest the instrument, when the instrument is within reach of it,
// the instrument's position relative to that node and its velocity. The output is a per-node
// update limited to `maxStep` cells along each axis by a scaled sigmoid; fixed nodes do not move.
//
// A model is a folder: weights.pt (the network), optimizer.pt (the optimiser's state, to resume
// training) and config.json (architecture, normalisers, the mesh's fingerprint, units, frame
// period, how it was trained), checked on load. The network runs in LibTorch's backend, a plugin
// loaded on first use (learning/nn/Backend.h), so that nothing else pays for loading LibTorch.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "learning/data/Rollout.h"

namespace viscera::learning {

// True when LibTorch's backend can be loaded (the learned components work); otherwise they refuse
// to, saying why (learning/nn/Backend.h).
bool torchAvailable();
// LibTorch's threads for the layers' products (0 leaves the current setting).
void setTorchThreads(int threads);

struct StepperArchitecture {
  int width = 256;      // features of every hidden layer
  int levels = 3;       // pooling levels below the mesh
  int matchings = 2;    // node-pair matchings per level (each about halves the nodes)
  double maxStep = 1;   // largest update per frame, in cells along each axis
  // The network's output at the rest shape with no instrument in reach is subtracted from its
  // output: a body at rest and left alone stays exactly at rest (its rest shape is its equilibrium).
  bool restAnchored = true;
  // Which nodes see the instrument: only the nearest within reach (the dissertation), or every
  // node within reach, each with the instrument's position relative to itself.
  bool instrumentAtAllInReach = false;
  // What the network's output means. Update: each node's update (the dissertation's). NextOffset:
  // the next offset from rest (the current offset is subtracted inside the clamp, so a zero output
  // returns a node to rest, as a quasi-static body does within a few frames once the instrument
  // lets go).
  enum class Output { Update, NextOffset };
  Output output = Output::Update;
};

// "update", "next offset" (config.json's architecture.output).
const char* outputName(StepperArchitecture::Output o);

// Inputs are scaled by these before they reach the network; stored with the model.
struct StepperNormalisers {
  Eigen::Vector3d cell = Eigen::Vector3d::Ones();     // cell size along each axis
  Eigen::Vector3d boxMin = Eigen::Vector3d::Zero(), boxMax = Eigen::Vector3d::Ones();  // rest box
  double reach = 1;          // the instrument is seen by its nearest node within this distance
  double velocityScale = 1;  // instrument speeds are divided by this
};

// The instrument at the frame being predicted.
struct InstrumentInput {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
};

class Stepper {
 public:
  // What a backend implements (LibTorch's, in a plugin loaded on first use: learning/nn/Backend.h).
  struct Impl {
    virtual ~Impl() = default;
    virtual void checkMesh(const RestMesh& mesh, const std::string& what) const = 0;
    virtual void save(const std::string& folder, const std::string& training) const = 0;
    virtual Eigen::Matrix3Xd step(const Eigen::Matrix3Xd& x, const InstrumentInput& instrument) const = 0;
    virtual const RestMesh& mesh() const = 0;
    virtual const StepperArchitecture& architecture() const = 0;
    virtual const StepperNormalisers& normalisers() const = 0;
    virtual double framePeriod() const = 0;
    virtual const std::string& units() const = 0;
    virtual std::int64_t parameters() const = 0;
    virtual const std::string& training() const = 0;
  };

  // A new network with weights drawn from `seed`.
  Stepper(const RestMesh& mesh, const StepperArchitecture& arch, const StepperNormalisers& norm, double framePeriod,
          const std::string& units, std::uint64_t seed);
  // Loads a model folder; throws Error naming the folder's file for anything missing or malformed.
  static Stepper load(const std::string& folder);
  explicit Stepper(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

  // Throws Error when `mesh` is not the mesh the model was made for, naming both (`what` says whose
  // mesh it is: a scene's node, a recording).
  void checkMesh(const RestMesh& mesh, const std::string& what) const { impl_->checkMesh(mesh, what); }

  // Writes the model folder (mesh.bin, weights.pt, config.json): each file through a temporary and
  // a rename, config.json last. `training` (JSON text) says how it was trained.
  void save(const std::string& folder, const std::string& training) const { impl_->save(folder, training); }

  // The nodes at the next frame from the nodes `x` (3 x #nodes) and the instrument then.
  Eigen::Matrix3Xd step(const Eigen::Matrix3Xd& x, const InstrumentInput& instrument) const { return impl_->step(x, instrument); }

  const RestMesh& mesh() const { return impl_->mesh(); }
  const StepperArchitecture& architecture() const { return impl_->architecture(); }
  const StepperNormalisers& normalisers() const { return impl_->normalisers(); }
  double framePeriod() const { return impl_->framePeriod(); }
  const std::string& units() const { return impl_->units(); }
  std::int64_t parameters() const { return impl_->parameters(); }
  // The training record of a loaded model (JSON text; empty for a new one).
  const std::string& training() const { return impl_->training(); }

  Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

// How the learning rate changes over the epochs: halved whenever the held-out rollout error has not
// improved for `patience` epochs, or along a half cosine from the initial rate towards zero at the
// last epoch (a fixed schedule: a noisy held-out error does not cut it early).
enum class RateSchedule { Plateau, Cosine };

// Training on recorded rollouts (learning/data/Rollout.h).
struct StepperTrainOptions {
  std::vector<std::string> data;  // recording folders (one mesh, one frame rate)
  std::string out;                // the model folder (created; with `resume`, continued)
  StepperArchitecture architecture;
  int epochs = 30;
  int batch = 32;
  double learningRate = 1e-3;
  int warmup = 5;               // epochs before half the inputs become the model's own predictions
  int unroll = 3;               // those predictions chain 1 to `unroll` frames of the model
  double noise = 0.03;          // RMS of the smooth random displacement added to inputs, in cells
  double validation = 0.1;      // share of the rollouts held out (at least one)
  double validationTime = 20;   // time of each held-out rollout the model is rolled out over
  RateSchedule schedule = RateSchedule::Plateau;
  int patience = 3;             // epochs without a better rollout error before the rate halves (Plateau)
  double reachCells = 1;        // the instrument's reach: its radius plus this many cells
  std::uint64_t seed = 1;
  int threads = 0;              // 0: every core
  bool resume = false;
  std::string command;          // the command line, recorded in config.json
};

struct EpochReport {
  int epoch = 0, epochs = 0;
  double trainLoss = 0;        // mean squared update error, in cells^2
  double validationLoss = 0;   // the same on the held-out rollouts' frames
  double rolloutError = 0;     // mean node distance to the FEM over the held-out rollouts' rollout
  double baselineError = 0;    // the same for the rest mesh (no motion)
  double learningRate = 0;
  double seconds = 0;
  bool best = false;           // the model folder now holds this epoch's weights
};

// Trains and writes the model folder after every epoch that improves the held-out rollout error
// (and a checkpoint to resume from after every epoch). Throws Error for bad options or data.
void trainStepper(const StepperTrainOptions& options, const std::function<void(const EpochReport&)>& progress);

// Rolling a model out over a recorded rollout: the error against the FEM per segment of time.
struct SegmentError {
  double t0 = 0, t1 = 0;
  int frames = 0;
  double mean = 0, stddev = 0;            // mean node distance model - FEM, and its spread over frames
  double baselineMean = 0;                // the rest mesh (no motion) against the FEM
};
struct RolloutEvaluation {
  std::string file;
  std::vector<double> time, error, baseline;  // per frame: mean node distance to the FEM
  std::vector<SegmentError> segments;
  double mean = 0, baselineMean = 0, seconds = 0;  // seconds: wall time of the model's frames
};
RolloutEvaluation evaluateRollout(const Stepper& model, const std::vector<RolloutFrame>& frames, double segment,
                                  double maxTime = 0);
// Rolls the model from each rollout's first frame, driven by its recorded instrument, for at most
// `maxTime` (0: whole rollouts); `segment` is the length of the reporting segments.
std::vector<RolloutEvaluation> evaluateStepper(const Stepper& model, const RolloutSet& data, double segment,
                                               double maxTime = 0);

}  // namespace viscera::learning

namespace viscera::learning {

// The speed of LibTorch's single-precision matrix product (m x k by k x n) on the current threads,
// in GFLOP/s (median of `repeats`), and the BLAS library it runs in (the file the dynamic linker
// resolved sgemm_ to, symbolic links followed: Debian's alternatives pick it).
struct GemmSpeed {
  double gflops = 0, milliseconds = 0;
  std::string blas;
};
GemmSpeed measureGemm(int m, int k, int n, int repeats = 50);

}  // namespace viscera::learning
