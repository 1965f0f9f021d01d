// The parameter search on datasets made from the block with a known Young's modulus (3.2 kPa, off
// every grid) and Poisson's ratio 0.4: recovery with a force sensor, honesty without one, the
// same results whatever the jobs or shards, resuming, and candidates that fail.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "core/Error.h"
#include "study/Search.h"
#include "tests/apps/cli_helpers.h"
#include "tests/study/study_helpers.h"

namespace viscera_test {
namespace {

namespace study = viscera::study;

const char* const kE = "block/fem.youngModulus";
const char* const kNu = "block/fem.poissonRatio";

class Search : public ::testing::Test {
 protected:
  // One ground-truth dataset for the suite: 3 s of indentation seen at 10 Hz, with a force sensor
  // of 1 mN noise (the peak contact force is about 0.3 N).
  static void SetUpTestSuite() {
    dir_ = new TempDir("viscera_search");
    const RunResult r = runViscera({"dataset", "make", studyData("block.xml"), "--out", *dir_ / "data", "--time", "3",
                                    "--set", std::string(kE) + "=3.2 kPa", "--position", "20 -200 250", "--look-at",
                                    "20 10 10", "--force-noise", "0.001 N", "--quiet"});
    ASSERT_EQ(r.rc, 0) << r;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string data() { return *dir_ / "data"; }

  study::SearchReport search(const std::vector<std::string>& args, const std::string& results, bool wrench = true,
                             int jobs = 1, int shard = 0, int shards = 1, study::SearchProgress* progress = nullptr) {
    const viscera::SceneDesc scene = blockScene();
    std::vector<study::ParamSpec> params;
    for (const auto& a : args) params.push_back(study::parseParam(a, scene));
    study::ScoreOptions so;
    so.useWrench = wrench;
    const study::PreparedDataset d = study::prepareDataset(data(), so);
    study::SearchOptions o;
    o.jobs = jobs;
    o.shard = shard;
    o.shards = shards;
    o.replay.score = so;
    return study::runSearch(scene, d, params, o, results, "test", progress);
  }

  TempDir out_;
  static TempDir* dir_;
};
TempDir* Search::dir_ = nullptr;

std::map<std::string, double> metrics(const study::SearchReport& r) {
  std::map<std::string, double> m;
  for (const auto& c : r.results) {
    std::string k;
    for (double v : c.values) k += std::to_string(v) + ";";
    m[k] = c.metric;
  }
  return m;
}

TEST(SearchParams, GridsListsAndRefinementsInTheScenesUnits) {
  const viscera::SceneDesc scene = blockScene();
  study::ParamSpec p = study::parseParam("block/fem.youngModulus=log:1kPa:100kPa:3", scene);
  ASSERT_EQ(p.grid.size(), 3u);
  // mm g s: 1 kPa = 1000 g mm^-1 s^-2.
  EXPECT_DOUBLE_EQ(p.grid[0], 1000);
  EXPECT_NEAR(p.grid[1], 10000, 1e-9);
  EXPECT_DOUBLE_EQ(p.grid[2], 100000);
  EXPECT_EQ(p.scale, study::Scale::Log);
  EXPECT_EQ(p.unit, "g mm^-1 s^-2");
  p = study::parseParam("fem.poissonRatio=lin:0.3:0.45:4", scene);
  EXPECT_NEAR(p.grid[1], 0.35, 1e-12);
  EXPECT_EQ(p.scale, study::Scale::Linear);
  p = study::parseParam("fem.youngModulus=2 kPa, 500Pa,1kPa", scene);
  EXPECT_EQ(p.grid, (std::vector<double>{500, 1000, 2000}));
  p = study::parseParam("fem.youngModulus=refine:10Pa:1MPa", scene);
  EXPECT_TRUE(p.refine);
  EXPECT_DOUBLE_EQ(p.hi, 1e6);
}

TEST(SearchParams, BadSpecsAreErrorsNamingTheOption) {
  const viscera::SceneDesc scene = blockScene();
  auto err = [&](const std::string& a) {
    try {
      study::parseParam(a, scene);
    } catch (const viscera::Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(err("block/fem.stiffness=1,2").find("has no attribute 'stiffness'"), std::string::npos);
  EXPECT_NE(err("nowhere/fem.youngModulus=1,2").find("nowhere/fem"), std::string::npos);
  EXPECT_NE(err("block/linear.iterations=1,2").find("not a real number"), std::string::npos);
  EXPECT_NE(err("fem.youngModulus=log:1kPa:10kPa").find("log:LO:HI:N"), std::string::npos);
  EXPECT_NE(err("fem.youngModulus=log:1kPa:10kPa:0").find("from 1 to 100000"), std::string::npos);
  EXPECT_NE(err("fem.youngModulus=lin:1kPa:10 m:3").find("incompatible"), std::string::npos);
  EXPECT_NE(err("fem.poissonRatio=0.3,0.6").find("out of range"), std::string::npos);
  EXPECT_NE(err("fem.youngModulus=refine:0:1kPa").find("out of range"), std::string::npos);
  EXPECT_NE(err("fem.poissonRatio=refine:0:0.4").find("LO > 0"), std::string::npos);
  EXPECT_NE(err("fem.youngModulus").find("ADDRESS=SPEC"), std::string::npos);
}

// With the force sensor the modulus is found; the dissertation's procedure in one call.
TEST_F(Search, RecoversYoungsModulusWithTheWrench) {
  const study::SearchReport r = search({std::string(kE) + "=refine:100Pa:100kPa"}, out_ / "results.csv");
  ASSERT_TRUE(r.best);
  EXPECT_NEAR(r.best->values[0], 3200, 320);  // within 10 %
  ASSERT_EQ(r.params.size(), 1u);
  EXPECT_TRUE(r.params[0].identifiable) << r.params[0].statement;
  EXPECT_LE(r.params[0].lo, 3200);
  EXPECT_GE(r.params[0].hi, 3200);
  EXPECT_GT(r.params[0].curvature, 0);
  ASSERT_EQ(r.stages.size(), 3u);
  EXPECT_EQ(r.stages[0].name, "decades");
  EXPECT_EQ(r.stages[2].name, "minimise");
}

// Clouds alone: the modulus is not identifiable, and the search says so rather than guessing.
TEST_F(Search, WithoutTheWrenchTheModulusIsNotIdentifiable) {
  const study::SearchReport r = search({std::string(kE) + "=refine:100Pa:100kPa"}, out_ / "results.csv", false);
  ASSERT_TRUE(r.best);
  ASSERT_EQ(r.params.size(), 1u);
  const study::ParamReport& p = r.params[0];
  EXPECT_FALSE(p.identifiable) << p.statement;
  EXPECT_LE(p.lo, 3200);
  EXPECT_GE(p.hi, 3200);
  EXPECT_NE(p.statement.find("not identifiable"), std::string::npos) << p.statement;
  EXPECT_NE(p.statement.find("force"), std::string::npos) << p.statement;
}

TEST_F(Search, RecoversYoungsModulusAndPoissonsRatioTogether) {
  const study::SearchReport r =
      search({std::string(kE) + "=refine:1kPa:10kPa", std::string(kNu) + "=refine-lin:0.3:0.49"}, out_ / "results.csv", true, 2);
  ASSERT_TRUE(r.best);
  EXPECT_NEAR(r.best->values[0], 3200, 320);
  EXPECT_NEAR(r.best->values[1], 0.4, 0.03);
}

TEST_F(Search, OneJobTwoJobsAndMergedShardsGiveTheSameTable) {
  const std::vector<std::string> grid = {std::string(kE) + "=log:1kPa:10kPa:4"};
  const auto one = metrics(search(grid, out_ / "one.csv", true, 1));
  const auto two = metrics(search(grid, out_ / "two.csv", true, 2));
  EXPECT_EQ(one, two);
  auto a = search(grid, out_ / "a.csv", true, 1, 0, 2).results;
  const auto b = search(grid, out_ / "b.csv", true, 1, 1, 2).results;
  EXPECT_EQ(a.size(), 2u);
  a.insert(a.end(), b.begin(), b.end());
  const viscera::SceneDesc scene = blockScene();
  const auto merged = study::analyse({study::parseParam(grid[0], scene)}, a, true);
  EXPECT_EQ(metrics(merged), one);
}

struct Counter : study::SearchProgress {
  void finished(const study::CandidateResult&, int, int) override { ++count; }
  int count = 0;
};

TEST_F(Search, RerunningResumesWithoutRedoingFinishedCandidates) {
  const std::vector<std::string> grid = {std::string(kE) + "=log:1kPa:10kPa:4"};
  const std::string path = out_ / "results.csv";
  const auto full = metrics(search(grid, path));
  // A batch killed after three candidates: its table has three rows.
  std::string text = slurp(path);
  text.erase(text.rfind('\n', text.size() - 2) + 1);
  writeText(path, text);
  Counter c;
  const auto resumed = search(grid, path, true, 1, 0, 1, &c);
  EXPECT_EQ(c.count, 1);
  EXPECT_EQ(metrics(resumed), full);
  // A results table of another search is refused.
  const viscera::SceneDesc scene = blockScene();
  const std::vector<study::ParamSpec> other = {study::parseParam(std::string(kNu) + "=0.3,0.4", scene)};
  EXPECT_THROW(study::readResults(path, other, "test"), viscera::Error);
  EXPECT_THROW(study::readResults(path, {study::parseParam(grid[0], scene)}, "another"), viscera::Error);
}

TEST_F(Search, DivergingAndTimedOutCandidatesAreRecordedAndTheBatchGoesOn) {
  const study::SearchReport r = search({std::string(kE) + "=1e-6,3200"}, out_ / "results.csv");
  ASSERT_EQ(r.results.size(), 2u);
  EXPECT_EQ(r.diverged, 1);
  EXPECT_EQ(r.ok, 1);
  const auto& bad = r.results[0].values[0] < 1 ? r.results[0] : r.results[1];
  EXPECT_EQ(bad.status, study::ReplayScore::Status::Diverged);
  EXPECT_NE(bad.reason.find("diverged"), std::string::npos) << bad.reason;
  ASSERT_TRUE(r.best);
  EXPECT_EQ(r.best->values[0], 3200);
}

}  // namespace
}  // namespace viscera_test
