// `viscera learn record`, `train` and `eval` through the command line: the shipped stepper rolled
// out over the scene's own 80 s palpation, with the report's per-segment figures checked against
// each other; a missing model refused with exit code 2 naming it; training's choice words, in any
// case, reach the model and its record.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "tests/apps/cli_helpers.h"

using namespace viscera_test;

namespace {

TEST(LearnCli, EvalReportsSegmentsAndMarksThoseAtRest) {
  TempDir dir("viscera_learn");
  RunResult r = runViscera({"learn", "record", sourcePath("scenes/gel_phantom_coarse.xml"), "--out", dir / "held", "--rollouts", "1",
                            "--time", "80", "--scene-trajectory"});
  ASSERT_EQ(r.rc, 0) << r;
  r = runViscera({"learn", "eval", sourcePath("scenes/models/stepper_coarse"), dir / "held", "--out", dir / "ev", "--no-plot"});
  if (r.rc != 0 && r.err.find("not available") != std::string::npos) GTEST_SKIP() << "built without LibTorch";
  ASSERT_EQ(r.rc, 0) << r;
  const auto report = nlohmann::json::parse(slurp(fs::path(dir / "ev") / "eval.json"));
  const auto& segments = report["rollouts"][0]["segments"];
  ASSERT_EQ(segments.size(), 8u);
  // The palpation's last poke ends before 70 s: the FEM is at rest from there on, and that segment
  // has no ratio; every other one has, and the smallest of theirs is the one reported.
  double smallest = 1e300;
  for (size_t k = 0; k < segments.size(); ++k) {
    const bool still = segments[k]["femAtRest"];
    EXPECT_EQ(still, k == 7) << "segment " << k;
    if (!still) smallest = std::min(smallest, segments[k]["noMotionMean"].get<double>() / segments[k]["mean"].get<double>());
  }
  EXPECT_DOUBLE_EQ(report["smallestSegmentRatio"].get<double>(), smallest);
  EXPECT_NE(r.out.find("at rest"), std::string::npos) << r;
  EXPECT_TRUE(fs::exists(fs::path(dir / "ev") / "errors.csv"));

  r = runViscera({"learn", "eval", dir / "no_such_model", dir / "held", "--out", dir / "ev2"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("no_such_model"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(fs::path(dir / "ev2")));
}

TEST(LearnCli, TrainRecordsTheOutputAndScheduleItWasGiven) {
  TempDir dir("viscera_learn");
  RunResult r = runViscera({"learn", "record", sourcePath("scenes/gel_phantom_coarse.xml"), "--out", dir / "rec", "--rollouts", "2",
                            "--time", "5", "--speed", "15:20", "--quiet"});
  ASSERT_EQ(r.rc, 0) << r;
  r = runViscera({"learn", "train", dir / "rec", "--out", dir / "m", "--width", "8", "--epochs", "1", "--validation-time", "0.5",
                  "--schedule", "Cosine", "--output", "OFFSET", "--threads", "1", "--quiet"});
  if (r.rc != 0 && r.err.find("not available") != std::string::npos) GTEST_SKIP() << "built without LibTorch";
  ASSERT_EQ(r.rc, 0) << r;
  const auto config = nlohmann::json::parse(slurp(fs::path(dir / "m") / "config.json"));
  EXPECT_EQ(config["architecture"]["output"], "next offset");
  EXPECT_EQ(config["training"]["rateSchedule"], "cosine");
  const std::string command = config["training"]["command"];
  EXPECT_NE(command.find("--schedule cosine"), std::string::npos) << command;
  EXPECT_NE(command.find("--output offset"), std::string::npos) << command;
  r = runViscera({"learn", "train", dir / "rec", "--out", dir / "m2", "--output", "sideways"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("--output"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(fs::path(dir / "m2")));
}

}  // namespace
