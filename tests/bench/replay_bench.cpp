// The 80 s gel-phantom palpation replay with contact (scenes/gel_phantom.xml), on one thread: wall
// time against the 80 s of simulated time, and (a separate, long benchmark) its accuracy against a
// run with a ten times smaller time step, as the largest node distance over the 30 Hz frames.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"
#include "tests/support/SceneFiles.h"

using namespace viscera;

namespace {

void dropExporters(ElementDesc& el) {
  auto& c = el.children;
  c.erase(std::remove_if(c.begin(), c.end(), [](const ElementDesc& e) { return test_support::isExporter(e.tag); }), c.end());
  for (auto& ch : c) dropExporters(ch);
}

// The scene, with its time step replaced by `dt` when that is positive.
std::unique_ptr<Scene> loadPhantom(double dt = 0) {
  SceneDesc desc = io::readScene(std::string(VISCERA_SOURCE_DIR) + "/scenes/gel_phantom.xml");
  dropExporters(desc.root);
  if (dt > 0) {
    std::ostringstream text;
    text << std::setprecision(17) << dt << " s";
    desc.root.set("dt", text.str());
  }
  return buildScene(desc);
}

MechanicalObject& phantomState(Scene& s) {
  for (MechanicalObject* m : s.all<MechanicalObject>())
    if (m->name() == "dofs") return *m;
  throw std::runtime_error("no 'dofs' in gel_phantom.xml");
}

void BM_PalpationReplay(benchmark::State& state) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
  for (auto _ : state) {
    auto scene = loadPhantom();
    Simulation sim(*scene);
    const double duration = 80.0;
    const int steps = static_cast<int>(std::llround(duration / scene->dt()));
    auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < steps; ++i)
      if (auto bad = sim.step()) {
        state.SkipWithError(bad->str().c_str());
        return;
      }
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    state.counters["steps"] = steps;
    state.counters["dt_ms"] = scene->dt() * 1e3;
    state.counters["ms_per_step"] = 1e3 * wall / steps;
    state.counters["realtime_factor"] = duration / wall;
    state.counters["max_penetration_mm"] = sim.pipeline()->maxPenetration(sim.state());
    state.counters["max_contacts"] = sim.pipeline()->maxContacts(sim.state());
  }
}

// Lockstep: a step of 1/(30 n) s (n = the second argument; 0: the scene's own step) against ten
// steps of a tenth of it, compared every 30 Hz frame over the first `duration` seconds.
void BM_PalpationReplayAccuracy(benchmark::State& state) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
  const double duration = static_cast<double>(state.range(0));
  const double dt = state.range(1) > 0 ? 1.0 / (30.0 * state.range(1)) : loadPhantom()->dt();
  for (auto _ : state) {
    auto coarse = loadPhantom(dt), fine = loadPhantom(dt / 10);
    Simulation a(*coarse), b(*fine);
    MechanicalObject &xa = phantomState(*coarse), &xb = phantomState(*fine);
    const double frame = 1.0 / 30.0;
    const int perFrame = static_cast<int>(std::llround(frame / coarse->dt()));
    const int frames = static_cast<int>(std::llround(duration / frame));
    double worst = 0, worstTime = 0, sumFrame = 0;
    for (int f = 0; f < frames; ++f) {
      for (int i = 0; i < perFrame; ++i) {
        if (auto bad = a.step()) return state.SkipWithError(bad->str().c_str());
        for (int k = 0; k < 10; ++k)
          if (auto bad = b.step()) return state.SkipWithError(bad->str().c_str());
      }
      const double d = (xa.x(a.state()) - xb.x(b.state())).colwise().norm().maxCoeff();
      sumFrame += d;
      if (d > worst) {
        worst = d;
        worstTime = a.time();
      }
    }
    state.counters["max_node_distance_mm"] = worst;
    state.counters["at_time_s"] = worstTime;
    state.counters["mean_frame_max_mm"] = sumFrame / std::max(frames, 1);
    state.counters["dt_ms"] = coarse->dt() * 1e3;
    state.counters["fine_dt_ms"] = fine->dt() * 1e3;
  }
}

}  // namespace

BENCHMARK(BM_PalpationReplay)->Iterations(1)->Repetitions(1)->Unit(benchmark::kSecond)->UseRealTime();

BENCHMARK(BM_PalpationReplayAccuracy)->Args({80, 0})->Iterations(1)->Repetitions(1)->Unit(benchmark::kSecond)->UseRealTime();
