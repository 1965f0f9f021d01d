// Time per step of the reference scenes without the instrument, on one and on two threads (Google
// Benchmark); the replay with contact is in replay_bench.cpp.
// `make bench` reports medians over repetitions.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <functional>
#include <sstream>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "io/scene/SceneReader.h"
#include "tests/support/SceneFiles.h"

using namespace viscera;

namespace {

// Drops exporters so that the benchmark measures the mechanics only.
void dropExporters(ElementDesc& el) {
  auto& c = el.children;
  c.erase(std::remove_if(c.begin(), c.end(), [&](const ElementDesc& e) { return test_support::isExporter(e.tag); }), c.end());
  for (auto& ch : c) dropExporters(ch);
}

void replaceTag(ElementDesc& el, const std::string& from, const std::string& to) {
  for (auto& ch : el.children) {
    if (ch.tag == from) {
      ch.tag = to;
      ch.attrs.clear();
    }
    replaceTag(ch, from, to);
  }
}

// Drops the instrument and the contact handling: the per-step cost of the deformable body alone.
void dropContact(ElementDesc& el) {
  static const char* tags[] = {"CollisionPipeline", "FreeMotionAnimationLoop", "GenericConstraintSolver",
                               "BruteForceBroadPhase", "BVHNarrowPhase", "LocalMinDistance", "MinProximityIntersection",
                               "CollisionResponse", "TriangleCollisionModel", "PrecomputedConstraintCorrection"};
  auto& c = el.children;
  c.erase(std::remove_if(c.begin(), c.end(),
                         [](const ElementDesc& e) {
                           if (e.tag == "Node") {
                             for (const auto& a : e.attrs)
                               if (a.name == "name" && a.value == "instrument") return true;
                             return false;
                           }
                           return std::find(std::begin(tags), std::end(tags), e.tag) != std::end(tags);
                         }),
          c.end());
  for (auto& ch : c) dropContact(ch);
}

// The phantom without its instrument, loaded as before the instrument existed: a 0.5 N press on a
// patch in the middle of the top face (z up), CG from zero each step (25 iterations).
void pressPhantom(SceneDesc& d) {
  ElementDesc* phantom = &d.element("phantom");
  std::istringstream lo(d.get("phantom/grid.min")->value), hi(d.get("phantom/grid.max")->value);
  double x0, y0, z0, x1, y1, z1;
  lo >> x0 >> y0 >> z0;
  hi >> x1 >> y1 >> z1;
  std::ostringstream patch;
  patch << x0 + 0.35 * (x1 - x0) << " " << y0 + 0.2 * (y1 - y0) << " " << z1 - 0.5 << " " << x0 + 0.65 * (x1 - x0)
        << " " << y0 + 0.7 * (y1 - y0) << " " << z1 + 0.5;
  ElementDesc box, press;
  box.tag = "BoxROI";
  box.set("name", "press");
  box.set("box", patch.str());
  press.tag = "ConstantForceField";
  press.set("indices", "@press.indices");
  press.set("totalForce", "0 0 -0.5 N");
  phantom->children.push_back(box);
  phantom->children.push_back(press);
  d.element("linear").set("warmStart", "false");
}

void runScene(benchmark::State& state, const std::string& file, const std::function<void(SceneDesc&)>& edit) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(state.range(0)));
  SceneDesc desc = io::readScene(std::string(VISCERA_SOURCE_DIR) + "/scenes/" + file);
  dropExporters(desc.root);
  dropContact(desc.root);
  if (file.rfind("gel_phantom", 0) == 0) pressPhantom(desc);
  if (edit) edit(desc);
  auto scene = buildScene(desc);
  Simulation sim(*scene);
  for (int i = 0; i < 5; ++i) sim.step();  // warm up
  for (auto _ : state) {
    auto bad = sim.step();
    if (bad) {
      state.SkipWithError(bad->str().c_str());
      break;
    }
  }
  state.counters["cg_iterations"] = sim.lastLinearIterations();
}

void BM_GelPhantom_CG25(benchmark::State& s) { runScene(s, "gel_phantom.xml", nullptr); }
void BM_GelPhantom_CG25_MatrixFree(benchmark::State& s) {
  runScene(s, "gel_phantom.xml", [](SceneDesc& d) { d.element("linear").set("assembled", "false"); });
}
void BM_GelPhantom_Cholmod(benchmark::State& s) {
  runScene(s, "gel_phantom.xml", [](SceneDesc& d) { replaceTag(d.root, "CGLinearSolver", "SparseLDLSolver"); });
}
void BM_GelPhantomCoarse_CG25(benchmark::State& s) { runScene(s, "gel_phantom_coarse.xml", nullptr); }
void BM_Beam_CG25(benchmark::State& s) { runScene(s, "beam.xml", nullptr); }
void BM_Beam_Cholmod(benchmark::State& s) {
  runScene(s, "beam.xml", [](SceneDesc& d) { replaceTag(d.root, "CGLinearSolver", "SparseLDLSolver"); });
}

}  // namespace

BENCHMARK(BM_GelPhantom_CG25)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);
BENCHMARK(BM_GelPhantom_CG25_MatrixFree)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);
BENCHMARK(BM_GelPhantom_Cholmod)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);
BENCHMARK(BM_GelPhantomCoarse_CG25)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(BM_Beam_CG25)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(BM_Beam_Cholmod)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
