// Joint logs (t,q1..q6 CSV) and the PsmJointDriver that replays them through the PSM's forward
// kinematics: the instrument is where the kinematics put the tool tip, placed by the transform, in
// the scene's length unit, and it moves along the kinematic path between samples.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "io/scene/Transform.h"
#include "robot/kinematics/JointTrajectory.h"
#include "robot/kinematics/PsmKinematics.h"
#include "tests/support/ErrorOf.h"
#include "tests/support/TempDir.h"

using viscera::RigidObject;
using viscera::robot::JointTrajectory;
using viscera::test_support::errorOf;
using viscera::test_support::TempDir;

namespace {

void write(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

std::string scene(const std::string& driverAttrs, const std::string& units = "mm g s", const std::string& dt = "0.01") {
  return R"(<Node name="root" gravity="0 0 0" dt=")" + dt + R"(" units=")" + units + R"(">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d"/>
    <PsmJointDriver name="psm" filename="joints.csv" )" +
         driverAttrs + R"(/>
  </Node>
</Node>
)";
}

RigidObject& tool(viscera::Scene& s) { return *s.all<RigidObject>().front(); }

TEST(JointTrajectory, ParsesInterpolatesAndHolds) {
  const JointTrajectory tr = viscera::robot::parseJointCsv(
      "# a joint log\nt,q1,q2\n0, 0, 1\n\n2, 1, -1\n", "log.csv", 2);
  ASSERT_EQ(tr.size(), 2);
  EXPECT_EQ(tr.line(0), 3);
  EXPECT_EQ(tr.line(1), 5);
  // Linear interpolation: exact for these binary fractions.
  EXPECT_EQ(tr.sample(0.5), Eigen::Vector2d(0.25, 0.5));
  EXPECT_EQ(tr.sample(-1), Eigen::Vector2d(0, 1));
  EXPECT_EQ(tr.sample(5), Eigen::Vector2d(1, -1));
}

TEST(JointTrajectory, WritesAndReadsBackExactly) {
  JointTrajectory tr(3);
  tr.add(0.1, Eigen::Vector3d(M_PI / 7, -1e-17, 0.123456789012345678));
  tr.add(0.30000000000000004, Eigen::Vector3d(1.0 / 3, 2e300, -0.0));
  const JointTrajectory back = viscera::robot::parseJointCsv(viscera::robot::formatJointCsv(tr), "x.csv", 3);
  ASSERT_EQ(back.size(), 2);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(back.time(i), tr.time(i));
    EXPECT_EQ(Eigen::VectorXd(back.joints(i)), Eigen::VectorXd(tr.joints(i)));
  }
}

TEST(JointTrajectory, BadRowsNameTheLineAndColumn) {
  using viscera::robot::parseJointCsv;
  EXPECT_EQ(errorOf([] { parseJointCsv("t,q1\n0,1\n0,2\n", "a.csv", 1); }),
            "a.csv:3: time 0 does not increase (previous 0 at line 2)");
  EXPECT_EQ(errorOf([] { parseJointCsv("0,1,2\n", "a.csv", 1); }), "a.csv:1: expected 2 columns (t,q1), got 3");
  EXPECT_EQ(errorOf([] { parseJointCsv("0, nan\n", "a.csv", 1); }), "a.csv:1:4: column 'q1' is not finite ('nan')");
  EXPECT_EQ(errorOf([] { parseJointCsv("0,x\n", "a.csv", 1); }), "a.csv:1:3: column 'q1': 'x' is not a number");
  EXPECT_EQ(errorOf([] { parseJointCsv("t,q1\n", "a.csv", 1); }), "a.csv: no rows (expected t,q1)");
}

// A constant log at the MISSION's check pose puts the tip at (0, 0, -0.1135) m in the robot
// frame: in a mm scene, through a transform, the instrument is at T * (0, 0, -113.5).
TEST(PsmJointDriver, CheckPoseThroughTheTransformInSceneUnits) {
  TempDir dir("viscera_psm");
  write(dir / "joints.csv", "t,q1,q2,q3,q4,q5,q6\n0,0,0,0.12,0,0,0\n1,0,0,0.12,0,0,0\n");
  viscera::RigidTransform T = viscera::RigidTransform::Identity();
  T.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(30, 20, 160);
  viscera::writeTransform(dir / "psm.txt", T, "robot -> scene (mm)");
  write(dir / "scene.xml", scene(R"(transform="psm.txt" translation="1 2 3")"));
  auto s = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
  viscera::Simulation sim(*s);
  const Eigen::Vector3d expected = T * Eigen::Vector3d(0, 0, -113.5) + Eigen::Vector3d(1, 2, 3);
  // Tolerance: a few ulps of the ~200 mm coordinates through the 6-joint chain and the transform.
  EXPECT_LT((tool(*s).live(sim.state()).p - expected).norm(), 1e-11);
  ASSERT_FALSE(sim.step().has_value());
  EXPECT_LT((tool(*s).live(sim.state()).p - expected).norm(), 1e-11);
  EXPECT_LT(tool(*s).live(sim.state()).v.norm(), 1e-9);
}

// Between two samples that differ in yaw and pitch only, the joints are interpolated, so the tip
// stays on the sphere about the remote centre of motion (the base origin) whose radius the
// insertion and wrist fix; a straight line between the sampled tip positions would cut inside it
// by r (1 - cos(theta/2)), about 3.4 mm here.
TEST(PsmJointDriver, FollowsTheKinematicPathBetweenSamples) {
  TempDir dir("viscera_psm");
  write(dir / "joints.csv", "0,-0.6,-0.4,0.15,0.3,0.2,-0.1\n1,0.6,0.4,0.15,0.3,0.2,-0.1\n");
  write(dir / "scene.xml", scene("", "m kg s", "0.05"));
  auto s = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
  viscera::Simulation sim(*s);
  const viscera::robot::SerialChain psm = viscera::robot::psmLargeNeedleDriver();
  Eigen::VectorXd q0(6), q1(6);
  q0 << -0.6, -0.4, 0.15, 0.3, 0.2, -0.1;
  q1 << 0.6, 0.4, 0.15, 0.3, 0.2, -0.1;
  const double radius = psm.tipPose(q0).translation().norm();
  const Eigen::Vector3d chordStart = psm.tipPose(q0).translation(), chordEnd = psm.tipPose(q1).translation();
  Eigen::Vector3d previous = tool(*s).live(sim.state()).p;
  double worstRadius = 0, chordGap = 0;
  for (int k = 1; k <= 20; ++k) {
    ASSERT_FALSE(sim.step().has_value());
    const double t = 0.05 * k;
    const RigidObject::Live& b = tool(*s).live(sim.state());
    worstRadius = std::max(worstRadius, std::abs(b.p.norm() - radius));
    chordGap = std::max(chordGap, radius - (chordStart + t * (chordEnd - chordStart)).norm());
    // The pose is the forward kinematics of the linearly interpolated joints.
    const Eigen::Isometry3d fk = psm.tipPose(q0 + t * (q1 - q0));
    EXPECT_LT((b.p - fk.translation()).norm(), 1e-14);
    EXPECT_LT(Eigen::AngleAxisd(b.q.toRotationMatrix() * fk.linear().transpose()).angle(), 1e-12);
    // The velocity is the step's displacement over dt.
    EXPECT_LT((b.v * 0.05 - (b.p - previous)).norm(), 1e-14);
    previous = b.p;
  }
  EXPECT_LT(worstRadius, 1e-14);  // on the sphere to round-off
  EXPECT_GT(chordGap, 3e-3);      // while the chord is millimetres inside it
}

TEST(PsmJointDriver, JointOutsideTheLimitsNamesTheLogLineAndTheScene) {
  TempDir dir("viscera_psm");
  write(dir / "joints.csv", "t,q1,q2,q3,q4,q5,q6\n0,0,0,0.12,0,0,0\n1,0,0,0.3,0,0,0\n");
  write(dir / "scene.xml", scene(""));
  const std::string msg = errorOf([&] { viscera::buildScene(viscera::io::readScene(dir / "scene.xml"))->init(); });
  EXPECT_NE(msg.find(dir / "joints.csv:3: joint 3 'outer_insertion' = 0.3 m is outside [0, 0.24] m"), std::string::npos) << msg;
  EXPECT_NE(msg.find("scene.xml:4:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("PsmJointDriver.filename"), std::string::npos) << msg;
  // checkLimits="false" replays it as recorded.
  write(dir / "scene.xml", scene(R"(checkLimits="false")"));
  EXPECT_NO_THROW(viscera::buildScene(viscera::io::readScene(dir / "scene.xml"))->init());
}

TEST(PsmJointDriver, BadLogNamesTheFileLine) {
  TempDir dir("viscera_psm");
  write(dir / "joints.csv", "t,q1,q2,q3,q4,q5,q6\n0,0,0,0.12,0,0\n");
  write(dir / "scene.xml", scene(""));
  const std::string msg = errorOf([&] { viscera::buildScene(viscera::io::readScene(dir / "scene.xml"))->init(); });
  EXPECT_NE(msg.find(dir / "joints.csv:2: expected 7 columns (t,q1,q2,q3,q4,q5,q6), got 6 (read for"), std::string::npos) << msg;
}

}  // namespace
