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
  // One ODE solver a node: two would integrate the same bodies twice a step.
  for (size_t i = 0; i < solvers_.size(); ++i)
    for (size_t j = 0; j < i; ++j) {
      const auto& a = dynamic_cast<const Component&>(*solvers_[j]);
      const auto& b = dynamic_cast<const Component&>(*solvers_[i]);
      if (&a.node() == &b.node())
        throw b.error("a second ODE solver in node " + b.node().path() + " (the first is the " + a.typeName() + " at " +
                      a.loc().str() + "): the node would be integrated twice per step");
    }
  corrections_ = scene_.all<Correction>();
  mappings_ = scene_.all<Mapping>();
  stateful_ = scene_.all<Stateful>();
  for (Stateful* s : stateful_) {
    const auto& c = dynamic_cast<const Component&>(*s);
    statefulNames_.push_back(c.node().path() + "/" + c.name() + " (" + c.typeName() + ")");
  }
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
  for (Driver* d : drivers_) d->drive(tEnd, dt);
  auto failed = [this](std::optional<Diverged> bad) {
    for (Observer* o : observers_) o->diverged(time_, steps_);
    return bad;
  };
  if (pipeline_)
    if (auto bad = pipeline_->detect(steps_ + 1, time_)) return failed(bad);
  for (OdeSolver* s : solvers_)
    if (auto bad = s->step(time_, dt, steps_ + 1)) return failed(bad);
  if (pipeline_ && constraints_)
    if (auto bad = constraints_->solve(*pipeline_, dt, steps_ + 1, tEnd)) return failed(bad);
  if (pipeline_) pipeline_->finish();
  for (Correction* c : corrections_) c->correct(tEnd, steps_ + 1);
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

State Simulation::captureState() const {
  State s;
  s.time = time_;
  s.steps = steps_;
  s.blocks.resize(stateful_.size());
  for (size_t i = 0; i < stateful_.size(); ++i) {
    s.blocks[i].component = statefulNames_[i];
    StateWriter w(s.blocks[i].bytes);
    stateful_[i]->saveState(w);
  }
  return s;
}

void Simulation::restoreState(const State& s) {
  // Check the whole state against the model before changing anything.
  if (s.blocks.size() != stateful_.size())
    throw Error("the state has " + std::to_string(s.blocks.size()) + " component blocks; this model has " +
                std::to_string(stateful_.size()) + ": it belongs to another model");
  for (size_t i = 0; i < stateful_.size(); ++i)
    if (s.blocks[i].component != statefulNames_[i])
      throw Error("the state's block " + std::to_string(i) + " is of " + s.blocks[i].component + ", this model has " +
                  statefulNames_[i] + " there: it belongs to another model");
  const State before = captureState();
  try {
    for (size_t i = 0; i < stateful_.size(); ++i) {
      StateReader r(s.blocks[i].bytes, statefulNames_[i]);
      stateful_[i]->loadState(r);
      r.finish();
    }
  } catch (const Error&) {
    // A block that does not fit (other sizes): leave the simulation as it was.
    for (size_t i = 0; i < stateful_.size(); ++i) {
      StateReader r(before.blocks[i].bytes, statefulNames_[i]);
      stateful_[i]->loadState(r);
    }
    throw;
  }
  time_ = s.time;
  steps_ = s.steps;
  for (Mapping* m : mappings_) m->apply();
}

int Simulation::lastLinearIterations() const {
  int n = 0;
  for (OdeSolver* s : solvers_) n += s->lastLinearIterations();
  return n;
}

}  // namespace viscera
