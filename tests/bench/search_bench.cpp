// One candidate of a parameter search as `viscera search` runs it: the coarse phantom replaying 60 s
// of a dataset (frames at 10 Hz, a force sensor) on one thread, scored per frame and per wrench
// sample; and, as the baseline in the same run, the same 60 s simulated without scoring. The
// dataset is made once by `viscera dataset make` (3.2 kPa, off any grid).
#include <benchmark/benchmark.h>
#include <stdlib.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Run.h"
#include "io/scene/SceneReader.h"
#include "study/Replay.h"

using namespace viscera;

namespace {

const std::string kScene = std::string(VISCERA_SOURCE_DIR) + "/scenes/gel_phantom_coarse.xml";

const study::PreparedDataset& dataset() {
  static const study::PreparedDataset data = [] {
    const std::string dir = (std::filesystem::temp_directory_path() / "viscera_bench_dataset").string();
    std::filesystem::remove_all(dir);
    const std::string cmd = std::string("'") + VISCERA_BINARY + "' dataset make '" + kScene + "' --out '" + dir +
                            "' --time 60 --set phantom/fem.youngModulus=3.2kPa --position '34 -200 300' --look-at "
                            "'34 18 20' --force-noise '2 mN' --quiet";
    if (std::system(cmd.c_str()) != 0) throw std::runtime_error("viscera dataset make failed");
    return study::prepareDataset(dir);
  }();
  return data;
}

void BM_SearchCandidate_Coarse60s(benchmark::State& state) {
  const study::PreparedDataset& data = dataset();
  const SceneDesc desc = study::replayDescription(io::readScene(kScene), data.data);
  study::ReplayOptions o;
  o.threads = 1;
  for (auto _ : state) {
    const study::ReplayScore s = study::replay(desc, data, o);
    if (!s.ok()) state.SkipWithError(s.reason.c_str());
    benchmark::DoNotOptimize(s.metric);
  }
}
BENCHMARK(BM_SearchCandidate_Coarse60s)->Unit(benchmark::kSecond)->Iterations(1);

// The baseline: the same replay description run for the same time, nothing scored.
void BM_SearchCandidate_Coarse60s_SimulationOnly(benchmark::State& state) {
  const study::PreparedDataset& data = dataset();
  const SceneDesc desc = study::replayDescription(io::readScene(kScene), data.data);
  for (auto _ : state) {
    auto scene = buildScene(desc);
    RunOptions ro;
    ro.time = data.data.end();
    ro.threads = 1;
    ro.recordWrench = false;
    benchmark::DoNotOptimize(run(*scene, ro).steps);
  }
}
BENCHMARK(BM_SearchCandidate_Coarse60s_SimulationOnly)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
