// The step loop: drivers -> collision -> each solver node integrates (with its health check) ->
// contact constraints -> corrections -> mappings -> observers. One explicit loop, no visitors.
//
// A simulation is a model (a built, initialised scene, read-only while stepping) and its own State.
// Several simulations of one model step at once in threads; a scene's observers (exporters,
// cameras) serve one of them at a time.
#pragma once

#include <optional>
#include <vector>

#include "engine/Roles.h"
#include "core/State.h"
#include "core/Scene.h"

namespace viscera {

class CollisionPipeline;
class ConstraintSolver;

class Simulation {
 public:
  // Initialises the scene if needed, collects its solvers and observers and makes the initial
  // state. Throws if the scene has observers and another simulation of it is alive.
  explicit Simulation(Scene& scene);
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  // Observers see the initial state.
  void begin();
  // One time step; on failure the state stays at the last good step and nothing is observed.
  std::optional<Diverged> step();
  // Observers finish (write indices, close files).
  void end();

  // Everything that changes while stepping (see State.h), live.
  State& state() { return state_; }
  const State& state() const { return state_; }
  // A copy of the state.
  State captureState() const { return state_; }
  // Continues from `state`, captured from a simulation of the same model (same scene structure
  // and sizes; parameters may differ). Mappings are re-applied; observers are not told.
  void restoreState(const State& state);

  // A correction run after every step's solve, after the scene's own corrections (not owned).
  void addCorrection(Correction& c) { corrections_.push_back(&c); }

  double time() const { return state_.time; }
  int steps() const { return state_.steps; }
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
  State state_;
  bool begun_ = false, ended_ = false;
};

}  // namespace viscera
