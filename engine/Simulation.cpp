#include "engine/Simulation.h"

#include <exception>

#include "engine/collision/Collision.h"
#include "core/Text.h"

#include <mutex>
#include <set>

namespace viscera {

namespace {

// Preparing a model (init, state slots, assembly patterns) happens once, whichever simulation of
// it comes first; the scene observers each simulation holds.
std::mutex& modelMutex() {
  static std::mutex m;
  return m;
}
std::set<const Observer*>& heldObservers() {
  static std::set<const Observer*> held;
  return held;
}

}  // namespace

Simulation::Simulation(Scene& scene) : scene_(scene) {
  std::lock_guard<std::mutex> lock(modelMutex());
  scene_.init();
  observers_ = scene_.all<Observer>();
  for (const Observer* o : observers_)
    if (heldObservers().count(o)) {
      const auto& c = dynamic_cast<const Component&>(*o);
      throw c.error("the " + c.typeName() + " '" + c.name() + "' already serves another simulation of this scene: a "
                    "scene's outputs are written by one simulation at a time (remove them to run the model in parallel)");
    }
  heldObservers().insert(observers_.begin(), observers_.end());
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
  for (size_t i = 0; i < stateful_.size(); ++i) {
    const auto& c = dynamic_cast<const Component&>(*stateful_[i]);
    statefulNames_.push_back(c.node().path() + "/" + c.name() + " (" + c.typeName() + ")");
    // Set by the model's first simulation, the same for every other.
    if (stateful_[i]->stateSlot() != static_cast<int>(i)) stateful_[i]->setStateSlot(static_cast<int>(i));
    state_.add(statefulNames_.back(), stateful_[i]->initialState());
  }
  state_.time = scene_.startTime();
}

Simulation::~Simulation() {
  std::lock_guard<std::mutex> lock(modelMutex());
  for (const Observer* o : observers_) heldObservers().erase(o);
}

void Simulation::begin() {
  if (begun_) return;
  begun_ = true;
  for (Mapping* m : mappings_) m->apply(state_);
  for (Observer* o : observers_) o->begin(state_, state_.time);
}

std::optional<Diverged> Simulation::step() {
  begin();
  const double dt = scene_.dt();
  State& st = state_;
  const int next = st.steps + 1;
  const double tEnd = scene_.startTime() + next * dt;
  // Instruments to their end-of-step pose, contacts against the tissue at the step start, the
  // (free) motion of every body, then the contact constraints.
  bool restored = false;
  for (auto c = corrections_.rbegin(); c != corrections_.rend(); ++c) restored |= (*c)->restore(st);
  if (restored)  // mapped states (collision surfaces on them) follow the state the solvers left
    for (Mapping* m : mappings_) m->apply(st);
  for (Driver* d : drivers_) d->drive(st, tEnd, dt);
  auto failed = [this](std::optional<Diverged> bad) {
    for (Observer* o : observers_) o->diverged(state_, state_.time, state_.steps);
    return bad;
  };
  if (pipeline_)
    if (auto bad = pipeline_->detect(st, next, st.time)) return failed(bad);
  for (OdeSolver* s : solvers_)
    if (auto bad = s->step(st, st.time, dt, next)) {
      double k = 0;
      const auto* solver = dynamic_cast<const Component*>(s);
      if (const int held = pipeline_ && solver && pipeline_->settings().response == ContactSettings::Response::Penalty
                               ? pipeline_->heldContacts(st, solver->node(), k) : 0)
        bad->reason += "; " + std::to_string(held) + " penalty contact(s) between two integrated bodies held their force "
                       "over the step (stiffness up to " + formatNumber(k) + "), which is stable only while k h^2 / m "
                       "stays well below 1 for the node masses m they act on: lower contactStiffness or the time step";
      return failed(bad);
    }
  if (constraints_)
    if (auto bad = constraints_->solve(st, pipeline_, dt, next, tEnd)) return failed(bad);
  if (pipeline_) pipeline_->finish(st);
  for (Correction* c : corrections_) c->correct(st, tEnd, next);
  st.steps = next;
  // Accumulate the time from the step count so that long runs do not drift.
  st.time = scene_.startTime() + next * dt;
  for (Mapping* m : mappings_) m->apply(st);
  for (Observer* o : observers_) o->observe(st, st.time, st.steps);
  return std::nullopt;
}

void Simulation::end() {
  if (ended_) return;
  ended_ = true;
  // Every observer ends, even after one fails (an exporter's write error must not cost another
  // its finished series); the first error is reported.
  std::exception_ptr first;
  for (Observer* o : observers_) {
    try {
      o->end(state_, state_.time, state_.steps);
    } catch (...) {
      if (!first) first = std::current_exception();
    }
  }
  if (first) std::rethrow_exception(first);
}

void Simulation::restoreState(const State& s) {
  // Check the whole state against the model before changing anything.
  if (s.blockCount() != stateful_.size())
    throw Error("the state has " + std::to_string(s.blockCount()) + " component blocks; this model has " +
                std::to_string(stateful_.size()) + ": it belongs to another model");
  for (size_t i = 0; i < stateful_.size(); ++i)
    if (s.component(i) != statefulNames_[i])
      throw Error("the state's block " + std::to_string(i) + " is of " + s.component(i) + ", this model has " +
                  statefulNames_[i] + " there: it belongs to another model");
  // Each block is read into a fresh one of this model's (so a block of other sizes is refused)
  // and the simulation's state replaced only once all fit.
  State next;
  for (size_t i = 0; i < stateful_.size(); ++i) {
    std::unique_ptr<ComponentState> block = stateful_[i]->initialState();
    const std::vector<char> bytes = s.bytesOf(i);
    StateReader r(bytes, statefulNames_[i]);
    block->load(r);
    r.finish();
    next.add(statefulNames_[i], std::move(block));
  }
  next.time = s.time;
  next.steps = s.steps;
  state_ = std::move(next);
  for (Mapping* m : mappings_) m->apply(state_);
}

int Simulation::lastLinearIterations() const {
  int n = 0;
  for (OdeSolver* s : solvers_) n += s->lastLinearIterations(state_);
  return n;
}

}  // namespace viscera
