// Time per step of SOFA's MatrixAssembly benchmark scenes (a cantilever of 2.5k tetrahedra, the
// same beam assembled or not, solved by CG or LDL), loaded unchanged from SOFA's examples, so that
// the figures sit beside those SOFA's pull request #2208 quotes for them. Skipped without the suite.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

void BM_SofaMatrixAssembly(benchmark::State& state, const std::string& scene) {
  const std::string path = std::string(VISCERA_SOURCE_DIR) +
                           "/../shared/data/sofa-suite/examples/Benchmark/Performance/MatrixAssembly/" + scene;
  if (!std::filesystem::exists(path)) {
    state.SkipWithError(("no SOFA suite: " + path).c_str());
    return;
  }
  const SceneDesc desc = io::readScene(path);
  auto s = buildScene(desc);
  Simulation sim(*s);
  for (int i = 0; i < 10; ++i) sim.step();  // the first factorisation and warm caches
  // One step per iteration: the reported time is the time per step.
  for (auto _ : state)
    if (sim.step()) {
      state.SkipWithError("diverged");
      break;
    }
}

}  // namespace

BENCHMARK_CAPTURE(BM_SofaMatrixAssembly, matrixfreeCG, std::string("MatrixAssembly_matrixfreeCG.scn"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SofaMatrixAssembly, assembledCG, std::string("MatrixAssembly_assembledCG.scn"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SofaMatrixAssembly, assembledCG_blocs, std::string("MatrixAssembly_assembledCG_blocs.scn"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SofaMatrixAssembly, direct, std::string("MatrixAssembly_direct.scn"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SofaMatrixAssembly, direct_blocs, std::string("MatrixAssembly_direct_blocs.scn"))->Unit(benchmark::kMillisecond);
