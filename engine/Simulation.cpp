#include "engine/Simulation.h"

namespace viscera {

Simulation::Simulation(Scene& scene) : scene_(scene) {
  scene_.init();
  solvers_ = scene_.all<OdeSolver>();
  observers_ = scene_.all<Observer>();
  time_ = scene_.startTime();
}

void Simulation::begin() {
  if (begun_) return;
  begun_ = true;
  for (Observer* o : observers_) o->begin(time_);
}

std::optional<Diverged> Simulation::step() {
  begin();
  const double dt = scene_.dt();
  for (OdeSolver* s : solvers_)
    if (auto bad = s->step(time_, dt, steps_ + 1)) return bad;
  ++steps_;
  // Accumulate the time from the step count so that long runs do not drift.
  time_ = scene_.startTime() + steps_ * dt;
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
