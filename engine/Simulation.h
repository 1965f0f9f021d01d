// The step loop: drivers -> collision -> each solver node integrates (with its health check) ->
// contact constraints -> corrections -> mappings -> observers. One explicit loop, no visitors.
#pragma once

#include <optional>
#include <vector>

#include "engine/Roles.h"
#include "engine/State.h"
#include "core/Scene.h"

namespace viscera {

class CollisionPipeline;
class ConstraintSolver;

class Simulation {
 public:
  // Initialises the scene if needed and collects its solvers and observers.
  explicit Simulation(Scene& scene);

  // Observers see the initial state.
  void begin();
  // One time step; on failure the state stays at the last good step and nothing is observed.
  std::optional<Diverged> step();
  // Observers finish (write indices, close files).
  void end();

  // Everything that changes while stepping, as one value (see State.h).
  State captureState() const;
  // Continues from `state`, captured from a simulation of the same model (same scene structure
  // and sizes; parameters may differ). Mappings are re-applied; observers are not told.
  void restoreState(const State& state);

  // A correction run after every step's solve, after the scene's own corrections (not owned).
  void addCorrection(Correction& c) { corrections_.push_back(&c); }

  double time() const { return time_; }
  int steps() const { return steps_; }
  Scene& scene() { return scene_; }
  const Scene& scene() const { return scene_; }
  // Linear iterations of the last step, summed over solvers.
  int lastLinearIterations() const;
  // The collision pipeline, if the scene has one.
  CollisionPipeline* pipeline() const { return pipeline_; }
  ConstraintSolver* constraintSolver() const { return constraints_; }

 private:
  Scene& scene_;
  std::vector<Driver*> drivers_;
  CollisionPipeline* pipeline_ = nullptr;
  ConstraintSolver* constraints_ = nullptr;
  std::vector<OdeSolver*> solvers_;
  std::vector<Correction*> corrections_;
  std::vector<Mapping*> mappings_;
  std::vector<Stateful*> stateful_;
  std::vector<std::string> statefulNames_;  // path and type of each, to check a restored state
  std::vector<Observer*> observers_;
  double time_ = 0;
  int steps_ = 0;
  bool begun_ = false, ended_ = false;
};

}  // namespace viscera
