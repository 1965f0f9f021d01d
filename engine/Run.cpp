#include "engine/Run.h"

#include <tbb/task_arena.h>
#include <unistd.h>

#include <signal.h>

#include <algorithm>
#include <csignal>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>

#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "core/Error.h"
#include "core/Text.h"

namespace viscera {

namespace {

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

int stepsOf(const RunOptions& o, const Scene& scene) {
  if (o.steps) {
    if (*o.steps < 0) throw Error("a run needs a number of steps >= 0, got " + std::to_string(*o.steps));
    return *o.steps;
  }
  if (o.time) {
    const double n = *o.time / scene.dt();
    if (!(n >= 0) || n > 2e9) throw Error("a run time of " + formatNumber(*o.time) + " is not a usable duration");
    return static_cast<int>(std::llround(n));
  }
  return 100;
}

RunResult runLoop(Simulation& sim, const RunOptions& o) {
  Scene& scene = sim.scene();
  if (o.initialState) sim.restoreState(*o.initialState);
  const int total = stepsOf(o, scene);
  auto bodies = scene.all<RigidObject>();
  RunResult r;
  r.dt = scene.dt();
  r.startTime = sim.time();
  r.units = scene.units().str();
  r.instruments.resize(bodies.size());
  for (size_t k = 0; k < bodies.size(); ++k) {
    r.instruments[k].name = bodies[k]->name();
    if (o.recordWrench) r.instruments[k].history.reserve(total);
  }
  const double t0 = now();
  sim.begin();
  for (RunObserver* ob : o.observers) ob->begin(sim, total);
  const int first = sim.steps();
  try {
    for (int i = 0; i < total; ++i) {
      if ((r.failure = sim.step())) break;
      for (size_t k = 0; k < bodies.size(); ++k) {
        const RigidObject::Live& b = bodies[k]->live(sim.state());
        RunResult::Instrument& in = r.instruments[k];
        in.last = {sim.time(), b.force, b.torque, b.contacts};
        if (b.force.norm() > in.peakForce) {
          in.peakForce = b.force.norm();
          in.peakForceTime = sim.time();
        }
        in.stepsInContact += b.contacts > 0;
        if (o.recordWrench) in.history.push_back(in.last);
      }
      for (RunObserver* ob : o.observers) ob->step(sim);
      bool interrupted = false;
      for (RunObserver* ob : o.observers)
        if (auto why = ob->stopReason()) {
          r.stopReason = *why;
          interrupted = ob->interrupts();
          break;
        }
      if (!r.stopReason.empty()) {
        r.status = interrupted ? RunResult::Status::Interrupted : RunResult::Status::Stopped;
        break;
      }
    }
  } catch (...) {
    // An error mid-run (an exporter's write error, an observer's): the other observers still end,
    // so that their outputs are finished, and the first error is the one reported.
    try {
      sim.end();
    } catch (...) {
    }
    throw;
  }
  sim.end();
  r.wallSeconds = now() - t0;
  if (r.failure) r.status = RunResult::Status::Diverged;
  r.steps = sim.steps() - first;
  r.endTime = sim.time();
  for (const MechanicalObject* s : scene.all<MechanicalObject>())
    r.objects.push_back({s->name(), s->size(), s->size() ? (s->x(sim.state()) - s->x0).colwise().norm().maxCoeff() : 0.0});
  for (size_t k = 0; k < bodies.size(); ++k) r.instruments[k].position = bodies[k]->live(sim.state()).p;
  if (const CollisionPipeline* p = sim.pipeline())
    r.contact = RunResult::ContactFigures{
        p->settings().response == ContactSettings::Response::Penalty ? "penalty" : "constraint", p->maxContacts(sim.state()),
        p->maxPenetration(sim.state()), p->settings().contactDistance};
  for (RunObserver* ob : o.observers) ob->end(sim, r);
  return r;
}

using Json = nlohmann::ordered_json;

// One value per line at the top, each object of a list and each number list on one line: the
// summary reads like a table. Invalid UTF-8 (in a scene path) is replaced rather than refused.
std::string layoutJson(const Json& j, int depth) {
  auto leaf = [](const Json& v) { return v.dump(-1, ' ', false, Json::error_handler_t::replace); };
  auto flat = [](const Json& v) {
    if (!v.is_structured()) return true;
    if (!v.is_array()) return false;
    return std::none_of(v.begin(), v.end(), [](const Json& e) { return e.is_structured(); });
  };
  if (!j.is_structured()) return leaf(j);
  std::string out;
  if (j.is_array() && flat(j)) {
    for (const auto& e : j) out += (out.empty() ? "" : ", ") + leaf(e);
    return "[" + out + "]";
  }
  if (j.is_object() && depth > 0 && std::all_of(j.begin(), j.end(), flat)) {
    for (const auto& [k, v] : j.items()) out += (out.empty() ? "" : ", ") + leaf(Json(k)) + ": " + layoutJson(v, depth + 1);
    return "{" + out + "}";
  }
  const std::string pad(2 * (depth + 1), ' ');
  if (j.is_object())
    for (const auto& [k, v] : j.items()) out += (out.empty() ? "\n" : ",\n") + pad + leaf(Json(k)) + ": " + layoutJson(v, depth + 1);
  else
    for (const auto& e : j) out += (out.empty() ? "\n" : ",\n") + pad + layoutJson(e, depth + 1);
  const bool obj = j.is_object();
  if (out.empty()) return obj ? "{}" : "[]";
  return (obj ? "{" : "[") + out + "\n" + std::string(2 * depth, ' ') + (obj ? "}" : "]");
}

}  // namespace

RunResult run(Simulation& sim, const RunOptions& o) {
  if (o.threads <= 0) return runLoop(sim, o);
  // A run's own arena: its parallel loops use at most `threads` workers, whatever other runs in
  // other threads do.
  tbb::task_arena arena(o.threads);
  RunResult r;
  arena.execute([&] { r = runLoop(sim, o); });
  return r;
}

RunResult run(Scene& scene, const RunOptions& o) {
  Simulation sim(scene);
  RunResult r = run(sim, o);
  r.finalState = sim.captureState();
  return r;
}

std::string summaryJson(const RunResult& r, const std::string& scene) {
  auto vec = [](const Eigen::Vector3d& v) { return Json::array({v.x(), v.y(), v.z()}); };
  Json j;
  j["scene"] = scene;
  j["status"] = r.ok()                                        ? "ok"
                : r.failure                                   ? "diverged"
                : r.status == RunResult::Status::Interrupted ? "interrupted"
                                                              : "stopped";
  if (r.failure) j["failure"] = r.failure->str();
  if (!r.stopReason.empty()) j["stop_reason"] = r.stopReason;
  j["steps"] = r.steps;
  j["dt"] = r.dt;
  j["simulated_time"] = r.simulatedTime();
  j["wall_time_s"] = r.wallSeconds;
  j["ms_per_step"] = r.msPerStep();
  j["units"] = r.units;
  j["objects"] = Json::array();
  for (const auto& o : r.objects)
    j["objects"].push_back({{"name", o.name}, {"nodes", o.nodes}, {"max_displacement", o.maxDisplacement}});
  j["instruments"] = Json::array();
  for (const auto& in : r.instruments)
    j["instruments"].push_back({{"name", in.name},
                                {"position", vec(in.position)},
                                {"force", vec(in.last.force)},
                                {"torque", vec(in.last.torque)},
                                {"contacts", in.last.contacts},
                                {"peak_force", in.peakForce},
                                {"peak_force_time", in.peakForceTime},
                                {"steps_in_contact", in.stepsInContact}});
  if (r.contact)
    j["contact"] = {{"response", r.contact->response},
                    {"max_contacts", r.contact->maxContacts},
                    {"max_penetration", r.contact->maxPenetration},
                    {"contact_distance", r.contact->contactDistance}};
  return layoutJson(j, 0) + "\n";
}

namespace {

// The wrench table's header and rows, one format for the finished table and the streamed one.
void wrenchHeader(std::ostream& o, const std::vector<std::string>& names) {
  o << "t";
  for (const auto& name : names)
    for (const char* c : {"fx", "fy", "fz", "tx", "ty", "tz", "contacts"}) o << "," << (names.size() > 1 ? name + "." : "") << c;
  o << "\n";
}

template <typename SampleOf>
void wrenchRow(std::ostream& o, double t, size_t instruments, SampleOf&& sample) {
  o << std::setprecision(9) << t;
  for (size_t k = 0; k < instruments; ++k) {
    const WrenchSample w = sample(k);
    o << "," << w.force.x() << "," << w.force.y() << "," << w.force.z() << "," << w.torque.x() << "," << w.torque.y()
      << "," << w.torque.z() << "," << w.contacts;
  }
  o << "\n";
}

}  // namespace

std::string wrenchCsv(const RunResult& r) {
  std::ostringstream o;
  std::vector<std::string> names;
  for (const auto& in : r.instruments) names.push_back(in.name);
  wrenchHeader(o, names);
  const size_t rows = r.instruments.empty() ? 0 : r.instruments.front().history.size();
  for (size_t i = 0; i < rows; ++i)
    wrenchRow(o, r.instruments.front().history[i].t, r.instruments.size(),
              [&](size_t k) { return r.instruments[k].history[i]; });
  return o.str();
}

WrenchStream::WrenchStream(std::string path) : partial_(std::move(path) + ".partial") {}

WrenchStream::~WrenchStream() {
  if (file_) {
    std::fclose(file_);
    std::remove(partial_.c_str());
  }
}

void WrenchStream::begin(const Simulation& sim, int) {
  for (const RigidObject* b : sim.scene().all<RigidObject>()) bodies_.push_back(b);
  file_ = std::fopen(partial_.c_str(), "w");
  if (!file_) throw Error(SourceLoc{partial_}, std::string("cannot write the streamed wrench table: ") + std::strerror(errno));
  std::ostringstream o;
  std::vector<std::string> names;
  for (const RigidObject* b : bodies_) names.push_back(b->name());
  wrenchHeader(o, names);
  std::fputs(o.str().c_str(), file_);
}

void WrenchStream::step(const Simulation& sim) {
  if (!file_) return;
  std::ostringstream o;
  wrenchRow(o, sim.time(), bodies_.size(), [&](size_t k) {
    const RigidObject::Live& b = bodies_[k]->live(sim.state());
    return WrenchSample{sim.time(), b.force, b.torque, b.contacts};
  });
  // One write per row, flushed: a process killed between steps leaves whole rows.
  std::fputs(o.str().c_str(), file_);
  std::fflush(file_);
}

std::string formatDuration(double s) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(s < 10 ? 1 : 0);
  if (s < 120) o << s << " s";
  else if (s < 7200) o << s / 60 << " min";
  else o << s / 3600 << " h";
  return o.str();
}

ProgressLine::ProgressLine() : enabled_(isatty(STDERR_FILENO) && !std::getenv("CI")) {}

void ProgressLine::begin(const Simulation& sim, int totalSteps) {
  total_ = totalSteps;
  done_ = 0;
  t0_ = now();
  last_ = -1;
}

void ProgressLine::step(const Simulation& sim) {
  ++done_;
  if (!enabled_) return;
  const double t = now();
  if (t - last_ < 0.25 && done_ != total_) return;
  last_ = t;
  const double rate = done_ / std::max(t - t0_, 1e-9);
  std::fprintf(stderr, "\rstep %d/%d  t = %.6g s  %.0f steps/s  ETA %s   ", done_, total_, sim.time(), rate,
               formatDuration((total_ - done_) / rate).c_str());
  std::fflush(stderr);
}

void ProgressLine::end(const Simulation& sim, const RunResult& result) {
  if (enabled_ && done_ > 0) std::fprintf(stderr, "\n");
}

namespace {
volatile std::sig_atomic_t g_signal = 0;
extern "C" void onStopSignal(int sig) {
  if (g_signal == sig) {  // the second one: the default way
    std::signal(sig, SIG_DFL);
    std::raise(sig);
  }
  g_signal = sig;
}
struct sigaction g_previousInt, g_previousTerm;
}  // namespace

SignalStop::SignalStop() {
  g_signal = 0;
  struct sigaction a {};
  a.sa_handler = onStopSignal;
  sigemptyset(&a.sa_mask);
  // Installed even over a signal ignored at start (a background job of a script has SIGINT
  // ignored): `kill -INT` is then how the script asks the run to stop.
  sigaction(SIGINT, &a, &g_previousInt);
  sigaction(SIGTERM, &a, &g_previousTerm);
}

SignalStop::~SignalStop() {
  sigaction(SIGINT, &g_previousInt, nullptr);
  sigaction(SIGTERM, &g_previousTerm, nullptr);
}

std::optional<std::string> SignalStop::stopReason() const {
  if (g_signal == 0) return std::nullopt;
  return std::string("interrupted by ") + (g_signal == SIGINT ? "SIGINT" : "SIGTERM");
}

int SignalStop::signal() const { return g_signal; }

}  // namespace viscera
