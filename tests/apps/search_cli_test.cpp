// `viscera dataset` and `viscera search` as a user runs them: outputs, resuming, merging shards,
// and bad input that exits 2 with a clear message and writes nothing.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "tests/apps/cli_helpers.h"

namespace viscera_test {
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define VISCERA_TEST_UNDER_ASAN 1
#endif
#endif
#ifdef VISCERA_TEST_UNDER_ASAN
constexpr bool kUnderAddressSanitizer = true;
#else
constexpr bool kUnderAddressSanitizer = false;
#endif

namespace {

std::string blockScene() { return sourcePath("tests/data/study/block.xml"); }

// A results table's rows, sorted, each up to its figures (stage, values, status, metric ...
// force_rms_free): everything but the wall time, which differs between runs.
std::vector<std::string> resultsTable(const std::string& dir) {
  std::vector<std::string> rows;
  for (const auto& l : lines(slurp(fs::path(dir) / "results.csv"))) {
    size_t end = 0;
    for (int f = 0; f < 13 && end != std::string::npos; ++f) end = l.find(',', end + 1);
    rows.push_back(l.substr(0, end));
  }
  std::sort(rows.begin(), rows.end());
  return rows;
}

class SearchCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("viscera_search_cli");
    const RunResult r = runViscera({"dataset", "make", blockScene(), "--out", *dir_ / "data", "--time", "2", "--set",
                                    "block/fem.youngModulus=3.2 kPa", "--position", "20 -200 250", "--look-at",
                                    "20 10 10", "--force-noise", "0.001 N", "--quiet"});
    ASSERT_EQ(r.rc, 0) << r;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string data() { return *dir_ / "data"; }
  TempDir tmp_;
  static TempDir* dir_;
};
TempDir* SearchCli::dir_ = nullptr;

TEST_F(SearchCli, DatasetMakeWritesACompleteDatasetThatChecks) {
  for (const char* f : {"trajectory.csv", "camera/index.csv", "camera_to_scene.txt", "wrench.csv", "README.txt"})
    EXPECT_TRUE(fs::exists(fs::path(data()) / f)) << f;
  EXPECT_FALSE(fs::exists(fs::path(data()) / "block.pvd"));  // the scene's exporter is not run
  const RunResult r = runViscera({"dataset", "check", data()});
  EXPECT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.out.find("camera: 21 frames"), std::string::npos) << r;
  EXPECT_NE(r.out.find("wrench: 200 samples"), std::string::npos) << r;
}

TEST_F(SearchCli, DatasetMakeNeverWritesIntoAnExistingFolder) {
  fs::create_directories(tmp_.path() / "taken");
  std::ofstream(tmp_.path() / "taken" / "keep.txt") << "mine";
  const RunResult r = runViscera({"dataset", "make", blockScene(), "--out", tmp_ / "taken", "--time", "0.1", "--position",
                                  "20 -200 250", "--look-at", "20 10 10"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("already exists"), std::string::npos) << r;
  EXPECT_EQ(slurp(tmp_.path() / "taken" / "keep.txt"), "mine");
}

TEST_F(SearchCli, DatasetCheckRejectsAFolderThatIsNotADataset) {
  fs::create_directories(tmp_.path() / "empty");
  const RunResult r = runViscera({"dataset", "check", tmp_ / "empty"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("trajectory.csv: missing"), std::string::npos) << r;
}

TEST_F(SearchCli, SearchWritesResultsSummaryAndPlot) {
  const RunResult r = runViscera({"search", blockScene(), "--data", data(), "--param",
                                  "block/fem.youngModulus=log:1kPa:10kPa:3", "--out", tmp_ / "s", "--jobs", "2"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.err.find("[3/3]"), std::string::npos) << r;
  const auto j = nlohmann::json::parse(slurp(tmp_.path() / "s" / "summary.json"));
  EXPECT_NEAR(j["best"]["block/fem.youngModulus"].get<double>(), 3162.28, 0.01);
  EXPECT_TRUE(j["bracket"]["block/fem.youngModulus"]["identifiable"].get<bool>());
  EXPECT_EQ(j["candidates"]["ok"].get<int>(), 3);
  EXPECT_EQ(j["units"].get<std::string>(), "mm g s");
  EXPECT_GT(fs::file_size(tmp_.path() / "s" / "search.png"), 1000u);
  // results.csv: the identity line, the header, three rows.
  const std::string csv = slurp(tmp_.path() / "s" / "results.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5) << csv;

  // Run again: nothing is redone. With another spec into the same folder: refused, untouched.
  const RunResult again = runViscera({"search", blockScene(), "--data", data(), "--param",
                                      "block/fem.youngModulus=log:1kPa:10kPa:3", "--out", tmp_ / "s"});
  EXPECT_EQ(again.rc, 0) << again;
  EXPECT_NE(again.err.find("3 already in results.csv"), std::string::npos) << again;
  const RunResult other = runViscera({"search", blockScene(), "--data", data(), "--param",
                                      "block/fem.youngModulus=log:1kPa:10kPa:4", "--out", tmp_ / "s"});
  EXPECT_EQ(other.rc, 2) << other;
  EXPECT_NE(other.err.find("another search"), std::string::npos) << other;
  EXPECT_EQ(slurp(tmp_.path() / "s" / "results.csv"), csv);
}

TEST_F(SearchCli, ShardsMergeIntoTheWholeGrid) {
  const std::vector<std::string> base = {"search", blockScene(), "--data", data(), "--param",
                                         "block/fem.youngModulus=log:1kPa:10kPa:3", "--no-plot", "--quiet"};
  auto with = [&](std::vector<std::string> extra) {
    auto a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    return runViscera(a);
  };
  ASSERT_EQ(with({"--out", tmp_ / "whole"}).rc, 0);
  ASSERT_EQ(with({"--out", tmp_ / "s0", "--shard", "0/2"}).rc, 0);
  ASSERT_EQ(with({"--out", tmp_ / "s1", "--shard", "1/2"}).rc, 0);
  const RunResult m = runViscera({"search", "merge", tmp_ / "s0", tmp_ / "s1", "--out", tmp_ / "merged", "--no-plot"});
  ASSERT_EQ(m.rc, 0) << m;
  const auto whole = nlohmann::json::parse(slurp(tmp_.path() / "whole" / "summary.json"));
  const auto merged = nlohmann::json::parse(slurp(tmp_.path() / "merged" / "summary.json"));
  EXPECT_EQ(whole["best"], merged["best"]);
  EXPECT_EQ(whole["metric"], merged["metric"]);
  EXPECT_EQ(merged["candidates"]["total"].get<int>(), 3);
  EXPECT_FALSE(nlohmann::json::parse(slurp(tmp_.path() / "s0" / "summary.json"))["complete"].get<bool>());
}

// Rank 0 hands candidates to both ranks (itself included); the table is that of one thread.
TEST_F(SearchCli, MpiRanksGiveTheSameTableAsThreads) {
  if (!VISCERA_HAS_MPI) GTEST_SKIP() << "built without MPI";
  const std::vector<std::string> args = {"search", blockScene(), "--data", data(), "--param",
                                         "block/fem.youngModulus=log:1kPa:10kPa:4", "--no-plot", "--quiet", "--out"};
  auto with = [&](const std::string& out, const std::string& prefix) {
    auto a = args;
    a.push_back(out);
    return runViscera(a, prefix);
  };
  ASSERT_EQ(with(tmp_ / "threads", "").rc, 0);
  // Open MPI refuses root without these (containers, CI). It never frees what its components
  // allocate (some in plugins it unloads, out of reach of suppressions), so under the sanitizer
  // build (`make test-asan`) the ranks run without the leak check; ASan's other checks stay on.
  const std::string leaks = kUnderAddressSanitizer ? "-x ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 " : "";
  const RunResult r = with(tmp_ / "mpi", "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun -n 2 --oversubscribe " + leaks);
  ASSERT_EQ(r.rc, 0) << r;
  const auto a = resultsTable(tmp_ / "threads"), b = resultsTable(tmp_ / "mpi");
  EXPECT_EQ(a.size(), 6u);
  EXPECT_EQ(a, b);
}

// The dataset's block is softer (3.2 kPa) than the scene's (5 kPa): the audit names the modulus,
// writes its reports, and the augmented scene runs.
TEST_F(SearchCli, AuditNamesTheModulusAndWritesARunnableScene) {
  const RunResult r = runViscera({"audit", blockScene(), "--data", data(), "--out", tmp_ / "audit", "--jobs", "2"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.out.find("effects found: youngModulus"), std::string::npos) << r;
  const auto j = nlohmann::json::parse(slurp(tmp_.path() / "audit" / "report.json"));
  for (const char* key : {"noise_floor_mm", "verdict", "found", "rounds", "candidates", "remaining_gap_mm",
                          "at_noise_level", "augmented_scene"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["verdict"].get<std::string>(), "effects found");
  const auto& round = j["rounds"][0];
  EXPECT_EQ(round["effect"].get<std::string>(), "youngModulus");
  EXPECT_NEAR(round["params"]["scale"].get<double>(), 0.64, 0.064);
  for (const char* key : {"params", "heldout_before_mm", "heldout_after_mm", "runner_up", "margin", "p_value"})
    EXPECT_TRUE(round.contains(key)) << key;
  EXPECT_NE(slurp(tmp_.path() / "audit" / "report.md").find("Verdict: effects found"), std::string::npos);
  const std::string html = slurp(tmp_.path() / "audit" / "report.html");
  EXPECT_NE(html.find("<strong>Verdict: effects found</strong>"), std::string::npos);
  EXPECT_NE(html.find("<img src=\"audit.png\""), std::string::npos);
  EXPECT_GT(fs::file_size(tmp_.path() / "audit" / "audit.png"), 1000u);
  for (const char* series : {"before", "after"})
    for (const char* pvd : {"cloud.pvd", "surface.pvd"})
      EXPECT_TRUE(fs::exists(tmp_.path() / "audit" / "residuals" / series / pvd)) << series << "/" << pvd;
  const std::string scene = j["augmented_scene"].get<std::string>();
  const RunResult check = runViscera({"run", scene, "--steps", "5", "--out", tmp_ / "run", "--quiet"});
  EXPECT_EQ(check.rc, 0) << check;
  EXPECT_NE(slurp(scene).find("audit effect 'youngModulus'"), std::string::npos);
  // Its exporter writes under --out, not beside the original scene.
  EXPECT_TRUE(fs::exists(tmp_.path() / "run" / "block.pvd"));
  EXPECT_FALSE(fs::exists(sourcePath("tests/data/study/block.pvd")));
}

// The bench plants each effect asked for (and a control), audits every case and counts: a
// stiffer tissue and a larger instrument are named, the control names none.
TEST_F(SearchCli, AuditBenchCountsWhatIsNamed) {
  const RunResult r = runViscera({"audit", "bench", blockScene(), "--time", "3", "--effects", "youngModulus,instrumentRadius",
                                  "--strengths", "1", "--seeds", "1", "--jobs", "2", "--force-noise", "1 mN", "--out",
                                  tmp_ / "bench"});
  ASSERT_EQ(r.rc, 0) << r;
  const auto j = nlohmann::json::parse(slurp(tmp_.path() / "bench" / "bench.json"));
  ASSERT_EQ(j["cases"].size(), 3u);
  for (const auto& c : j["cases"]) EXPECT_EQ(c["named"], c["planted"]) << c.dump();
  EXPECT_DOUBLE_EQ(j["detection_rate"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(j["false_discovery_rate"].get<double>(), 0.0);
  const std::string md = slurp(tmp_.path() / "bench" / "bench.md");
  EXPECT_NE(md.find("| planted \\ named |"), std::string::npos) << md;
  EXPECT_NE(r.out.find("Detection rate"), std::string::npos);
  // An existing --out is refused and left as it was.
  const RunResult again = runViscera({"audit", "bench", blockScene(), "--time", "3", "--effects", "gravity", "--out", tmp_ / "bench"});
  EXPECT_EQ(again.rc, 2) << again;
  EXPECT_NE(again.err.find("already exists"), std::string::npos) << again;
  // The audit itself still wants its scene and data.
  EXPECT_NE(runViscera({"audit", blockScene()}).rc, 0);
}

// kill -9 in the middle of a batch leaves a results table that the rerun reads and completes,
// equal to an uninterrupted run's.
TEST_F(SearchCli, AKilledSearchResumesToTheSameTable) {
  const std::string grid = "block/fem.youngModulus=log:1kPa:10kPa:8";
  auto args = [&](const std::string& out) {
    return std::vector<std::string>{"search", blockScene(), "--data", data(), "--param", grid, "--out", out, "--no-plot", "--quiet"};
  };
  ASSERT_EQ(runViscera(args(tmp_ / "whole")).rc, 0);
  std::string cmd = shellQuote(VISCERA_BINARY);
  for (const auto& a : args(tmp_ / "killed")) cmd += " " + shellQuote(a);
  std::system(("(" + cmd + " >/dev/null 2>&1 & p=$!; sleep 0.3; kill -9 $p; wait $p) 2>/dev/null").c_str());
  const RunResult again = runViscera(args(tmp_ / "killed"));
  ASSERT_EQ(again.rc, 0) << again;
  EXPECT_EQ(resultsTable(tmp_ / "whole"), resultsTable(tmp_ / "killed"));
}

TEST_F(SearchCli, BadInputExitsTwoAndWritesNothing) {
  struct Case {
    std::vector<std::string> args;
    const char* message;
  };
  const std::vector<Case> cases = {
      {{"--param", "block/fem.nothing=1,2"}, "has no attribute 'nothing'"},
      {{"--param", "nowhere.youngModulus=1,2"}, "nowhere"},
      {{"--param", "block/fem.youngModulus=log:1:2"}, "log:LO:HI:N"},
      {{"--param", "block/fem.youngModulus=lin:1kPa:2kPa:3", "--shard", "2/2"}, "--shard"},
      {{"--param", "block/fem.youngModulus=refine:1kPa:2kPa", "--shard", "0/2"}, "cannot be split"},
      {{"--param", "block/fem.youngModulus=1,2", "--param", "fem.poissonRatio=refine-lin:0.3:0.4"}, "cannot be mixed"},
  };
  for (const auto& c : cases) {
    std::vector<std::string> args = {"search", blockScene(), "--data", data(), "--out", tmp_ / "out"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const RunResult r = runViscera(args);
    EXPECT_EQ(r.rc, 2) << r;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.message << "\n" << r;
    EXPECT_FALSE(fs::exists(tmp_ / "out")) << c.message;
  }
  fs::create_directories(tmp_.path() / "nodata");
  const RunResult r = runViscera({"search", blockScene(), "--data", tmp_ / "nodata", "--param",
                                  "block/fem.youngModulus=1,2", "--out", tmp_ / "out2"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("trajectory.csv: missing"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(tmp_ / "out2"));
}

}  // namespace
}  // namespace viscera_test
