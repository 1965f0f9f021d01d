// `viscera kinematics fk|ik`: inverse kinematics of a Cartesian trajectory, then forward kinematics
// of the joint log, gives the trajectory back; bad options and unreachable poses exit 2.
#include <gtest/gtest.h>

#include "motion/Trajectory.h"
#include "robot/kinematics/JointTrajectory.h"
#include "tests/apps/cli_helpers.h"

using namespace viscera_test;

namespace {

TEST(KinematicsCli, InverseThenForwardGivesThePosesBack) {
  TempDir dir("viscera_kin");
  ASSERT_EQ(runViscera({"trajectory", "--box", "0 0 0 68.7 35.8 39.3", "--faces", "top", "--duration", "8", "--rate", "20",
                        "--out", dir / "poke.csv"}).rc, 0);
  const std::string T = sourcePath("scenes/psm_to_phantom.txt");
  const RunResult ik = runViscera({"kinematics", "ik", "--poses", dir / "poke.csv", "--transform", T, "--unit", "mm",
                                   "--orientation", "fixed", "--out", dir / "joints.csv"});
  ASSERT_EQ(ik.rc, 0) << ik;
  const RunResult fk = runViscera({"kinematics", "fk", "--joints", dir / "joints.csv", "--transform", T, "--unit", "mm",
                                   "--out", dir / "back.csv"});
  ASSERT_EQ(fk.rc, 0) << fk;
  const auto poke = viscera::motion::readTrajectoryCsv(dir / "poke.csv");
  const auto back = viscera::motion::readTrajectoryCsv(dir / "back.csv");
  ASSERT_EQ(back.size(), poke.size());
  const auto joints = viscera::robot::readJointCsv(dir / "joints.csv", 6);
  double worst = 0, orientationSpread = 0;
  for (int i = 0; i < poke.size(); ++i) {
    EXPECT_EQ(back.t[i], poke.t[i]);
    worst = std::max(worst, (back.p[i] - poke.p[i]).norm());
    orientationSpread = std::max(orientationSpread, back.q[i].angularDistance(back.q[0]));
    EXPECT_GE(joints.joints(i)[2], 0.0);  // within the insertion range
  }
  // The IK stops at 1e-10 m = 1e-7 mm.
  EXPECT_LT(worst, 2e-7);
  // --orientation fixed: the tool keeps one orientation (to the IK's 1e-10 rad).
  EXPECT_LT(orientationSpread, 1e-9);
}

TEST(KinematicsCli, BadInputExitsTwoNamingTheProblem) {
  TempDir dir("viscera_kin");
  std::ofstream(dir / "far.csv") << "t,x,y,z,qx,qy,qz,qw\n0,0,0,-0.1,0,0,0,1\n1,2,0,-0.1,0,0,0,1\n";
  RunResult r = runViscera({"kinematics", "ik", "--poses", dir / "far.csv", "--orientation", "fixed", "--out", dir / "j.csv"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("pose 2 (t = 1) is not reached"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(dir / "j.csv"));

  r = runViscera({"kinematics", "ik", "--poses", dir / "far.csv", "--unit", "inch", "--out", dir / "j.csv"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("--unit: 'inch' is not a length unit"), std::string::npos) << r;

  std::ofstream(dir / "j.csv") << "t,q1,q2,q3,q4,q5,q6\n0,0,0,0.12,0,0,0\n1,0,2,0.12,0,0,0\n";
  r = runViscera({"kinematics", "fk", "--joints", dir / "j.csv", "--out", dir / "p.csv"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("j.csv:3: joint 2 'outer_pitch' = 2 rad is outside [-0.925, 0.925] rad"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(dir / "p.csv"));
}

}  // namespace
