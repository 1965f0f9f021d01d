// Bad trajectories behind a scene's TrajectoryDriver, through the command line: `viscera run` and
// `viscera check` must reject them with exit code 2, a message that points at the trajectory
// file and its offending line (and names the driver's element in the scene), and nothing written
// to the output folder. The fixtures tests/data/bad/traj_*.xml are traj_ok.xml (scene_ok.xml's
// beam plus an instrument driven by traj_ok.csv) with the trajectory file swapped; the bad
// traj_*.csv are one-edit variants of traj_ok.csv.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cli_helpers.h"

using namespace viscera_test;

namespace {

struct TrajCase {
  std::string scene;                     // fixture in tests/data/bad/
  std::string trajectory;                // the trajectory file the scene names
  std::string lineNeedle;                // text on the offending line of the trajectory ("" for a missing file)
  std::vector<std::string> mustContain;  // the problem
};

// The "<scene>:<line>:" of the TrajectoryDriver's filename attribute.
std::string driverWhere(const std::string& scene) {
  const int line = lineOf(scene, "<TrajectoryDriver ");
  EXPECT_GT(line, 0) << "fixture problem: no TrajectoryDriver in " << scene;
  return scene + ":" + std::to_string(line) + ":";
}

// The common contract for one command's result.
void expectMessage(const RunResult& r, const TrajCase& c, const std::string& what) {
  const std::string scene = badPath(c.scene), traj = badPath(c.trajectory);
  EXPECT_EQ(r.rc, 2) << what << "\n" << r;
  // The trajectory's own file and line first ...
  std::string where = traj + ":";
  if (!c.lineNeedle.empty()) {
    const int line = lineOf(traj, c.lineNeedle);
    EXPECT_GT(line, 0) << "fixture problem: '" << c.lineNeedle << "' not found in " << traj;
    where += std::to_string(line) + ":";
  }
  EXPECT_NE(r.err.find(where), std::string::npos) << what << ": expected '" << where << "' in the message\n" << r;
  // ... then the scene element that asked for it.
  EXPECT_NE(r.err.find(driverWhere(scene)), std::string::npos) << what << "\n" << r;
  EXPECT_NE(r.err.find("TrajectoryDriver.filename"), std::string::npos) << what << "\n" << r;
  for (const auto& s : c.mustContain) EXPECT_NE(r.err.find(s), std::string::npos) << what << ": expected '" << s << "'\n" << r;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << what << "\n" << r;
  // One error line, no stack of follow-up messages.
  EXPECT_EQ(lines(r.err).size(), 1u) << what << "\n" << r;
}

void expectRejected(const TrajCase& c) {
  const std::string scene = badPath(c.scene);
  ASSERT_TRUE(fs::exists(scene)) << scene;
  {
    TempDir tmp;
    const fs::path out = tmp.path() / "out";
    RunResult r = runViscera({"run", scene, "--out", out.string(), "--steps", "2"});
    expectMessage(r, c, "run");
    EXPECT_TRUE(absentOrEmpty(out)) << "the output folder " << out << " was written to";
  }
  {
    // Also with the other outputs asked for: none of them may appear.
    TempDir tmp;
    const fs::path out = tmp.path() / "out";
    RunResult r = runViscera({"run", scene, "--out", out.string(), "--steps", "2", "--summary", tmp / "summary.json",
                              "--wrench", tmp / "wrench.csv", "--state-out", tmp / "state.csv"});
    expectMessage(r, c, "run with --summary --wrench --state-out");
    EXPECT_TRUE(absentOrEmpty(out)) << "the output folder " << out << " was written to";
    for (const char* f : {"summary.json", "wrench.csv", "state.csv"})
      EXPECT_FALSE(fs::exists(tmp.path() / f)) << f << " was written";
  }
  expectMessage(runViscera({"check", scene}), c, "check");
}

// The control: the scene the bad ones are edits of runs and checks fine, and the instrument
// follows traj_ok.csv, so each rejection below is caused by its one edit.
TEST(TrajectorySceneErrors, ControlSceneRuns) {
  TempDir tmp;
  RunResult r =
      runViscera({"run", badPath("traj_ok.xml"), "--out", tmp / "out", "--steps", "2", "--summary", tmp / "summary.json"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_TRUE(fs::exists(tmp.path() / "out" / "beam.pvd")) << r;
  // After 2 steps of 0.01 the instrument is at the sample t = 0.02 of traj_ok.csv.
  const std::string summary = slurp(tmp.path() / "summary.json");
  EXPECT_NE(summary.find("\"position\": [0.5, 0.5, 5.8]"), std::string::npos) << summary;
  RunResult c = runViscera({"check", badPath("traj_ok.xml")});
  EXPECT_EQ(c.rc, 0) << c;
}

TEST(TrajectorySceneErrors, TimeNotIncreasing) {
  expectRejected({"traj_time_not_increasing.xml", "traj_time_not_increasing.csv", "0.02,0.5,0.5,5.7,", {"does not increase"}});
}

TEST(TrajectorySceneErrors, NaNCoordinate) {
  expectRejected({"traj_nan.xml", "traj_nan.csv", ",nan,", {"'z'", "not finite"}});
}

TEST(TrajectorySceneErrors, WrongColumnCount) {
  expectRejected({"traj_column_count.xml", "traj_column_count.csv", "0.01,0.5,0.5,5.9,0,0,0", {"8 columns", "got 7"}});
}

TEST(TrajectorySceneErrors, MissingFile) {
  // No line to point at in a file that does not exist: the message names the missing file and
  // the scene line that asked for it.
  ASSERT_FALSE(fs::exists(badPath("traj_no_such_file.csv")));
  expectRejected({"traj_missing_file.xml", "traj_no_such_file.csv", "", {"cannot open trajectory"}});
}

}  // namespace
