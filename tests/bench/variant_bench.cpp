// Scene variants as a batch study makes them: building and initialising a variant of the coarse
// phantom from an in-memory description, with its input files and symbolic factorisations cached
// (as every variant after the first finds them) and cold (both caches cleared each time); the
// throughput of variant runs on one and on two threads (each run one worker: the batch parallelism
// is across runs), and of simulations of one built model.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <string>
#include <thread>
#include <vector>

#include "builtin/Builtins.h"
#include "engine/Run.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "io/scene/InputCache.h"
#include "io/scene/SceneReader.h"
#include "solvers/linear/LinearSolver.h"
#include "tests/support/SceneFiles.h"

using namespace viscera;

namespace {

SceneDesc coarsePhantom() {
  SceneDesc d = io::readScene(std::string(VISCERA_SOURCE_DIR) + "/scenes/gel_phantom_coarse.xml");
  auto& c = d.element("phantom").children;
  c.erase(std::remove_if(c.begin(), c.end(), [](const ElementDesc& e) { return test_support::isExporter(e.tag); }), c.end());
  return d;
}

// Build + init of a variant (a new Young's modulus each time).
void variantBuild(benchmark::State& state, bool cached) {
  SceneDesc desc = coarsePhantom();
  int k = 0;
  for (auto _ : state) {
    if (!cached) {
      io::clearInputCache();
      CholmodSolver::clearSharedAnalyses();
    }
    desc.set("phantom/fem.youngModulus", std::to_string(4 + (k++ % 5)) + " kPa");
    auto scene = buildScene(desc);
    Simulation sim(*scene);
    benchmark::DoNotOptimize(sim.time());
  }
}
void BM_CoarseVariantBuild_Cached(benchmark::State& s) { variantBuild(s, true); }
void BM_CoarseVariantBuild_Cold(benchmark::State& s) { variantBuild(s, false); }

// Variants of the coarse phantom, 300 steps each (2 s of palpation), run by `threads` threads at
// once; items/s is variants per second.
void BM_CoarseVariantRuns(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  const SceneDesc base = coarsePhantom();
  auto one = [&](int k) {
    SceneDesc d = base;
    d.set("phantom/fem.youngModulus", std::to_string(4 + k % 5) + " kPa");
    auto scene = buildScene(d);
    RunOptions o;
    o.steps = 300;
    o.threads = 1;
    o.recordWrench = false;
    run(*scene, o);
  };
  long variants = 0;
  for (auto _ : state) {
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(one, t);
    for (auto& t : pool) t.join();
    variants += threads;
  }
  state.SetItemsProcessed(variants);
}

// Simulations of one built model (no variant, no build per run): `threads` of them step 300
// times at once, each with its own state; items/s is runs per second.
void BM_CoarseModelRuns(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  auto scene = buildScene(coarsePhantom());
  { Simulation first(*scene); }  // initialise the model once
  auto one = [&] {
    Simulation sim(*scene);
    RunOptions o;
    o.steps = 300;
    o.threads = 1;
    o.recordWrench = false;
    run(sim, o);
  };
  long runs = 0;
  for (auto _ : state) {
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(one);
    for (auto& t : pool) t.join();
    runs += threads;
  }
  state.SetItemsProcessed(runs);
}

}  // namespace

BENCHMARK(BM_CoarseModelRuns)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);
BENCHMARK(BM_CoarseVariantBuild_Cached)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(BM_CoarseVariantBuild_Cold)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(BM_CoarseVariantRuns)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);
