#include "engine/Simulation.h"

#include "engine/collision/Collision.h"

namespace viscera {

Simulation::Simulation(Scene& scene) : scene_(scene) {
  scene_.init();
  drivers_ = scene_.all<Driver>();
  auto pipes = scene_.all<CollisionPipeline>();
  if (!pipes.empty()) pipeline_ = pipes.front();
  auto cs = scene_.all<ConstraintSolver>();
  if (!cs.empty()) constraints_ = cs.front();
  if (!pipeline_ && (!scene_.all<SphereCollisionModel>().empty() || !scene_.all<SurfaceCollisionModel>().empty()))
    scene_.addNote("note: the scene has collision models but no CollisionPipeline: nothing collides");
  solvers_ = scene_.all<OdeSolver>();
  mappings_ = scene_.all<Mapping>();
  observers_ = scene_.all<Observer>();
  time_ = scene_.startTime();
}

void Simulation::begin() {
  if (begun_) return;
  begun_ = true;
  for (Mapping* m : mappings_) m->apply();
  for (Observer* o : observers_) o->begin(time_);
}

std::optional<Diverged> Simulation::step() {
  begin();
  const double dt = scene_.dt();
  const double tEnd = scene_.startTime() + (steps_ + 1) * dt;
  // Instruments to their end-of-step pose, contacts against the tissue at the step start, the
  // (free) motion of every body, then the contact constraints.
  for (Driver* d : drivers_) d->drive(tEnd);
  if (pipeline_) pipeline_->detect();
  for (OdeSolver* s : solvers_)
    if (auto bad = s->step(time_, dt, steps_ + 1)) return bad;
  if (pipeline_ && constraints_)
    if (auto bad = constraints_->solve(*pipeline_, dt, steps_ + 1, tEnd)) return bad;
  if (pipeline_) pipeline_->finish();
  ++steps_;
  // Accumulate the time from the step count so that long runs do not drift.
  time_ = scene_.startTime() + steps_ * dt;
  for (Mapping* m : mappings_) m->apply();
  for (Observer* o : observers_) o->observe(time_, steps_);
  return std::nullopt;
}

void Simulation::end() {
  if (ended_) return;
  ended_ = true;
  for (Observer* o : observers_) o->end(time_, steps_);
}

int Simulation::lastLinearIterations() const {
  int n = 0;
  for (OdeSolver* s : solvers_) n += s->lastLinearIterations();
  return n;
}

}  // namespace viscera
