// Datasets read as data from outside, and replays scored against answers known without the code
// under test: clouds at a known distance from a block at rest, a known force error.
#include <gtest/gtest.h>

#include <cmath>

#include "core/Error.h"
#include "study/Dataset.h"
#include "study/Replay.h"
#include "tests/study/study_helpers.h"

namespace viscera_test {
namespace {

using viscera::test_support::TempDir;
namespace study = viscera::study;

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const viscera::Error& e) {
    return e.what();
  }
  return "";
}

TEST(Dataset, ReadsFramesTrajectoryTransformAndWrench) {
  TempDir dir;
  const viscera::RigidTransform T(Eigen::Translation3d(5, -3, 200) * Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  writeParkedDataset(dir.path(), {0.013, 0.5, 0.987}, liftedTopFace(0.3), &T, "t,fx,fy,fz\n0.1,1,2,3\n0.2,1,2,3\n");
  const study::Dataset d = study::readDataset(dir.str());
  ASSERT_EQ(d.frames.size(), 3u);
  EXPECT_DOUBLE_EQ(d.frames[1].time, 0.5);
  ASSERT_TRUE(d.cameraToScene.has_value());
  ASSERT_TRUE(d.wrench.has_value());
  EXPECT_FALSE(d.wrench->hasTorque);
  EXPECT_EQ(d.wrench->size(), 2);
  // The clouds come back in the scene frame (float precision of the PCD file).
  const auto clouds = study::readFrames(d);
  EXPECT_LT((clouds[0] - liftedTopFace(0.3)).cwiseAbs().maxCoeff(), 1e-4);
}

TEST(Dataset, MissingOrMalformedPartsAreErrorsNamingTheFile) {
  TempDir dir;
  EXPECT_NE(errorOf([&] { study::readDataset(dir / "nothing"); }).find("no such dataset folder"), std::string::npos);
  EXPECT_NE(errorOf([&] { study::readDataset(dir.str()); }).find("trajectory.csv: missing"), std::string::npos);

  writeParkedDataset(dir.path(), {0.1, 0.2}, liftedTopFace(0), nullptr, "t,fx,fy,fz,tx\n0.1,1,2,3,4\n");
  const std::string w = errorOf([&] { study::readDataset(dir.str()); });
  EXPECT_NE(w.find("wrench.csv:1"), std::string::npos) << w;
  EXPECT_NE(w.find("4 columns"), std::string::npos) << w;

  writeText(dir.path() / "wrench.csv", "t,fx,fy,fz\n0.1,1,2,3\n0.1,1,2,3\n");
  const std::string t = errorOf([&] { study::readDataset(dir.str()); });
  EXPECT_NE(t.find("wrench.csv:3"), std::string::npos) << t;
  EXPECT_NE(t.find("does not increase"), std::string::npos) << t;

  fs::remove(dir.path() / "wrench.csv");
  writeText(dir.path() / "camera" / "index.csv", "time,file\n0.2,f0.pcd\n0.1,f1.pcd\n");
  const std::string o = errorOf([&] { study::readDataset(dir.str()); });
  EXPECT_NE(o.find("index.csv:3"), std::string::npos) << o;
  EXPECT_NE(o.find("must increase"), std::string::npos) << o;

  writeText(dir.path() / "camera" / "index.csv", "time,file\n0.1,f0.pcd\n0.2,gone.pcd\n");
  const std::string m = errorOf([&] { study::readDataset(dir.str()); });
  EXPECT_NE(m.find("gone.pcd"), std::string::npos) << m;
}

TEST(Dataset, CheckReportsEmptyFramesGapsAndProblems) {
  TempDir dir;
  writeParkedDataset(dir.path(), {0.1, 0.2}, liftedTopFace(0));
  // An empty frame and a trajectory with a 2 s gap.
  writeText(dir.path() / "camera" / "f1.pcd",
            "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 0\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 0\nDATA ascii\n");
  writeText(dir.path() / "trajectory.csv", "0,20,10,75,0,0,0,1\n2,20,10,75,0,0,0,1\n");
  const study::DatasetReport r = study::checkDataset(dir.str());
  EXPECT_TRUE(r.ok());
  std::string warnings;
  for (const auto& w : r.warnings) warnings += w + "\n";
  EXPECT_NE(warnings.find("f1.pcd: the frame has no points"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("gap of 2 s"), std::string::npos) << warnings;

  writeText(dir.path() / "camera" / "f0.pcd", "not a point cloud");
  EXPECT_FALSE(study::checkDataset(dir.str()).ok());
}

// The block at rest, the clouds 0.3 mm above its top face: every frame's RMS distance is 0.3 mm,
// whatever the frame times, the camera frame or the Young's modulus.
TEST(Replay, CloudsAtAKnownDistanceScoreThatDistance) {
  TempDir dir;
  const viscera::RigidTransform T(Eigen::Translation3d(20, -150, 200) * Eigen::AngleAxisd(2.2, Eigen::Vector3d(1, 0, 0)));
  const std::vector<double> times = {0, 0.0137, 0.25, 0.5003, 0.999};
  writeParkedDataset(dir.path(), times, liftedTopFace(0.3), &T, "t,fx,fy,fz\n0.005,1000,0,0\n0.5,0,-1000,0\n");
  const study::PreparedDataset data = study::prepareDataset(dir.str());
  const viscera::SceneDesc desc = study::replayDescription(blockScene(), data.data);
  const study::ReplayScore s = study::replay(desc, data);
  ASSERT_TRUE(s.ok()) << s.reason;
  ASSERT_EQ(s.frames.size(), times.size());
  // Float coordinates in the PCD file: 1e-5 mm.
  for (const auto& f : s.frames) EXPECT_NEAR(f.value, 0.3, 1e-5) << "frame at " << f.time;
  EXPECT_NEAR(s.cloudRms, 0.3, 1e-5);
  EXPECT_NEAR(s.cloudTerm, 0.3, 1e-5);  // L = 1 mm
  EXPECT_TRUE(std::isnan(s.cloudRmsContact));
  // The instrument never touches: the simulated force is 0, so each error is the measured 1000.
  ASSERT_EQ(s.samples.size(), 2u);
  EXPECT_NEAR(s.forceRms, 1000, 1e-9);
  EXPECT_NEAR(s.forceTerm, 1.0, 1e-12);  // F = RMS measured force = 1000
  EXPECT_NEAR(s.metric, 1.3, 1e-5);
  EXPECT_NEAR(s.metricSe, 0.0, 1e-5);
  EXPECT_EQ(s.steps, 100);  // to the last frame at 0.999 s: 100 steps of 10 ms
}

// A capture stamped with absolute times (seconds since 1970) replays from the scene's start.
TEST(Replay, AbsoluteTimeStampsReplayFromTheScenesStart) {
  TempDir dir;
  writeParkedDataset(dir.path(), {0.0137, 0.5003}, liftedTopFace(0.2), nullptr, "", 1.7e9);
  const study::PreparedDataset data = study::prepareDataset(dir.str());
  const study::ReplayScore s = study::replay(study::replayDescription(blockScene(), data.data), data);
  ASSERT_TRUE(s.ok()) << s.reason;
  EXPECT_EQ(s.steps, 51);
  ASSERT_EQ(s.frames.size(), 2u);
  EXPECT_NEAR(s.cloudRms, 0.2, 1e-5);
}

TEST(Replay, TheSceneMustHaveOneTrajectoryDriver) {
  TempDir dir;
  writeParkedDataset(dir.path(), {0.1}, liftedTopFace(0));
  const study::Dataset d = study::readDataset(dir.str());
  viscera::SceneDesc desc = blockScene();
  auto& instrument = desc.element("instrument").children;
  instrument.erase(instrument.begin() + 2);
  const std::string e = errorOf([&] { study::replayDescription(desc, d); });
  EXPECT_NE(e.find("no TrajectoryDriver"), std::string::npos) << e;
}

TEST(Replay, ATimeBudgetStopsTheReplayAsATimeout) {
  TempDir dir;
  writeParkedDataset(dir.path(), {0.1, 0.9}, liftedTopFace(0));
  const study::PreparedDataset data = study::prepareDataset(dir.str());
  study::ReplayOptions o;
  o.timeBudget = 1e-9;
  const study::ReplayScore s = study::replay(study::replayDescription(blockScene(), data.data), data, o);
  EXPECT_EQ(s.status, study::ReplayScore::Status::Timeout);
  EXPECT_NE(s.reason.find("time budget"), std::string::npos) << s.reason;
  EXPECT_TRUE(std::isnan(s.metric));
}

}  // namespace
}  // namespace viscera_test
