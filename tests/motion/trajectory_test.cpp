// Trajectories: the CSV format (exact round trip, optional header, comments, line-numbered
// errors), interpolation (lerp + shortest-arc slerp) and the piecewise-constant twist.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "core/Error.h"
#include "motion/Trajectory.h"
#include "tests/support/TempDir.h"

using viscera::motion::Trajectory;
using viscera::test_support::TempDir;

namespace {

constexpr double kPi = 3.14159265358979323846;

#define EXPECT_CONTAINS(text, part) EXPECT_NE(std::string(text).find(part), std::string::npos) << "message: " << (text)

Eigen::Quaterniond aboutAxis(double angle, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
}

// Rotation angle between two orientations (shortest arc).
double angleBetween(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) { return a.angularDistance(b); }

// The message of the viscera::Error that parsing `text` as "traj.csv" throws.
std::string parseError(const std::string& text) {
  try {
    viscera::motion::parseTrajectoryCsv(text, "traj.csv");
  } catch (const viscera::Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected viscera::Error, got: " << e.what();
    return {};
  }
  ADD_FAILURE() << "parsing did not throw:\n" << text;
  return {};
}

const std::string kHeader = "t,x,y,z,qx,qy,qz,qw\n";

TEST(TrajectoryCsv, RoundTripIsExact) {
  Trajectory tr;
  tr.add(0.0, {0.1, 1.0 / 3.0, -2.5e17});
  tr.add(1e-300, {std::nextafter(1.0, 2.0), -0.0, 123456.789}, aboutAxis(0.7, {1, 2, 3}));
  tr.add(0.3, {1e-310, 2.0 / 7.0, 6.02214076e23}, aboutAxis(3.1, {-1, 0.5, 0.25}));
  tr.add(1.0 / 3.0, {-1, -2, -3}, Eigen::Quaterniond(0.5, -0.5, 0.5, -0.5));
  const std::string text = viscera::motion::formatTrajectoryCsv(tr);
  EXPECT_EQ(text.substr(0, kHeader.size()), kHeader);

  const Trajectory back = viscera::motion::parseTrajectoryCsv(text, "rt.csv");
  ASSERT_EQ(back.size(), tr.size());
  for (int i = 0; i < tr.size(); ++i) {
    EXPECT_EQ(back.t[i], tr.t[i]) << i;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(back.p[i][k], tr.p[i][k]) << i << " " << k;
    for (int k = 0; k < 4; ++k) EXPECT_EQ(back.q[i].coeffs()[k], tr.q[i].coeffs()[k]) << i << " " << k;
  }
  EXPECT_EQ(viscera::motion::formatTrajectoryCsv(back), text);
}

TEST(TrajectoryCsv, WriteAndReadAFile) {
  TempDir dir("viscera_traj");
  Trajectory tr;
  tr.add(0, {1, 2, 3});
  tr.add(0.5, {4, 5, 6}, aboutAxis(1.0, {0, 0, 1}));
  viscera::motion::writeTrajectoryCsv(dir / "out.csv", tr);
  const Trajectory back = viscera::motion::readTrajectoryCsv(dir / "out.csv");
  EXPECT_EQ(viscera::motion::formatTrajectoryCsv(back), viscera::motion::formatTrajectoryCsv(tr));
  const auto entries = std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator());
  EXPECT_EQ(entries, 1);  // no temporary file left behind
}

TEST(TrajectoryCsv, HeaderIsOptional) {
  const std::string rows = "0,1,2,3,0,0,0,1\n1,2,3,4,0,0,1,0\n";
  const Trajectory a = viscera::motion::parseTrajectoryCsv(rows, "a.csv");
  const Trajectory b = viscera::motion::parseTrajectoryCsv(kHeader + rows, "b.csv");
  const Trajectory c = viscera::motion::parseTrajectoryCsv("time, px, py, pz, i, j, k, w\n" + rows, "c.csv");
  ASSERT_EQ(a.size(), 2);
  EXPECT_EQ(viscera::motion::formatTrajectoryCsv(a), viscera::motion::formatTrajectoryCsv(b));
  EXPECT_EQ(viscera::motion::formatTrajectoryCsv(a), viscera::motion::formatTrajectoryCsv(c));
  EXPECT_EQ(a.p[1], Eigen::Vector3d(2, 3, 4));
  EXPECT_EQ(a.q[1].coeffs(), Eigen::Vector4d(0, 0, 1, 0));  // Eigen's coeffs are x, y, z, w
}

TEST(TrajectoryCsv, CommentsBlankLinesWhitespaceAndCrlf) {
  const std::string text =
      "# recorded with the tracker\r\n"
      "\r\n"
      "  t , x , y , z , qx , qy , qz , qw \r\n"
      "   # a comment after the header\r\n"
      " 0 , 1 ,\t2 , 3 , 0 , 0 , 0 , 1\r\n"
      "\r\n"
      "\t\r\n"
      "+0.5,-1e1,2.5E-1,3,0,0,0,1\r\n"
      "# trailing comment";
  const Trajectory tr = viscera::motion::parseTrajectoryCsv(text, "crlf.csv");
  ASSERT_EQ(tr.size(), 2);
  EXPECT_EQ(tr.t[1], 0.5);
  EXPECT_EQ(tr.p[0], Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(tr.p[1], Eigen::Vector3d(-10, 0.25, 3));
}

TEST(TrajectoryCsv, QuaternionsAreNormalised) {
  const Trajectory tr = viscera::motion::parseTrajectoryCsv("0,0,0,0, 0,0,0,2\n1,0,0,0, 0,0,3,4\n", "n.csv");
  EXPECT_EQ(tr.q[0].coeffs(), Eigen::Vector4d(0, 0, 0, 1));
  EXPECT_NEAR(tr.q[1].norm(), 1.0, 1e-15);
  EXPECT_NEAR(tr.q[1].z(), 0.6, 1e-15);
  EXPECT_NEAR(tr.q[1].w(), 0.8, 1e-15);
}

TEST(TrajectoryCsv, MissingFile) {
  TempDir dir("viscera_traj");
  const std::string path = dir / "nope.csv";
  try {
    viscera::motion::readTrajectoryCsv(path);
    FAIL() << "no error";
  } catch (const viscera::Error& e) {
    EXPECT_CONTAINS(e.what(), path + ": cannot open trajectory");
  }
  try {
    viscera::motion::readTrajectoryCsv(dir.str());
    FAIL() << "no error for a folder";
  } catch (const viscera::Error& e) {
    EXPECT_CONTAINS(e.what(), dir.str() + ": cannot open trajectory");
  }
}

TEST(TrajectoryCsv, EmptyFileHasNoSamples) {
  EXPECT_CONTAINS(parseError(""), "traj.csv: no samples");
  EXPECT_CONTAINS(parseError("\n\n# only a comment\n"), "traj.csv: no samples");
  EXPECT_CONTAINS(parseError(kHeader), "traj.csv: no samples");
  TempDir dir("viscera_traj");
  std::ofstream(dir / "empty.csv").close();
  try {
    viscera::motion::readTrajectoryCsv(dir / "empty.csv");
    FAIL() << "no error";
  } catch (const viscera::Error& e) {
    EXPECT_CONTAINS(e.what(), dir / "empty.csv" + ": no samples");
  }
}

TEST(TrajectoryCsv, WrongColumnCount) {
  const std::string msg = parseError(kHeader + "0,0,0,0,0,0,0,1\n\n# x\n1,0,0,0,0,0,1\n");
  EXPECT_CONTAINS(msg, "traj.csv:5:");
  EXPECT_CONTAINS(msg, "expected 8 columns (t,x,y,z,qx,qy,qz,qw), got 7");
  EXPECT_CONTAINS(parseError("0,0,0,0,0,0,0,1,\n"), "traj.csv:1:");
  EXPECT_CONTAINS(parseError("0,0,0,0,0,0,0,1,\n"), "got 9");
  // A first row that is numeric is data, not a header: its column count is checked.
  EXPECT_CONTAINS(parseError("# c\n0 0 0 0 0 0 0 1\n"), "traj.csv:2:");
  EXPECT_CONTAINS(parseError("# c\n0 0 0 0 0 0 0 1\n"), "got 1");
}

TEST(TrajectoryCsv, NotANumberNamesTheColumn) {
  std::string msg = parseError(kHeader + "0,0,0,0,0,0,0,1\n1,0,0,0,abc,0,0,1\n");
  EXPECT_CONTAINS(msg, "traj.csv:3:");
  EXPECT_CONTAINS(msg, "column 'qx': 'abc' is not a number");
  msg = parseError("0,0,0,0,0,0,0,1\n\n1,0,0,0,0,0,0,1\n2,0,1.5x,0,0,0,0,1\n");
  EXPECT_CONTAINS(msg, "traj.csv:4:");
  EXPECT_CONTAINS(msg, "column 'y': '1.5x' is not a number");
  msg = parseError("0,0,0,0,0,0,0,1\n1,0,0,,0,0,0,1\n");
  EXPECT_CONTAINS(msg, "traj.csv:2:");
  EXPECT_CONTAINS(msg, "column 'z': '' is not a number");
}

TEST(TrajectoryCsv, NonFiniteValues) {
  std::string msg = parseError(kHeader + "0,0,0,0,0,0,0,1\n1,0,nan,0,0,0,0,1\n");
  EXPECT_CONTAINS(msg, "traj.csv:3:");
  EXPECT_CONTAINS(msg, "column 'y' is not finite");
  msg = parseError("0,0,0,0,0,0,0,1\n# c\n1,0,0,0,0,0,0,inf\n");
  EXPECT_CONTAINS(msg, "traj.csv:3:");
  EXPECT_CONTAINS(msg, "column 'qw' is not finite");
  msg = parseError("1e999,0,0,0,0,0,0,1\n");
  EXPECT_CONTAINS(msg, "traj.csv:1:");
  EXPECT_CONTAINS(msg, "column 't' is not finite");
}

TEST(TrajectoryCsv, ZeroQuaternion) {
  const std::string msg = parseError(kHeader + "0,0,0,0,0,0,0,1\n1,0,0,0,0,0,0,0\n");
  EXPECT_CONTAINS(msg, "traj.csv:3:");
  EXPECT_CONTAINS(msg, "zero length");
}

TEST(TrajectoryCsv, TimeMustIncrease) {
  std::string msg = parseError(kHeader + "0,0,0,0,0,0,0,1\n0.6,0,0,0,0,0,0,1\n# c\n0.5,0,0,0,0,0,0,1\n");
  EXPECT_CONTAINS(msg, "traj.csv:5:");
  EXPECT_CONTAINS(msg, "time 0.5 does not increase (previous 0.6 at line 3)");
  msg = parseError("0,0,0,0,0,0,0,1\n1,0,0,0,0,0,0,1\n1,0,0,0,0,0,0,1\n");
  EXPECT_CONTAINS(msg, "traj.csv:3:");
  EXPECT_CONTAINS(msg, "time 1 does not increase (previous 1 at line 2)");
}

Trajectory twoSamples() {
  Trajectory tr;
  tr.add(0, {0, 0, 0});
  tr.add(2, {2, 4, -6}, aboutAxis(kPi / 2, {0, 0, 1}));
  return tr;
}

TEST(TrajectorySample, MidpointLerpAndSlerp) {
  const Trajectory tr = twoSamples();
  const auto mid = tr.sample(1.0);
  EXPECT_EQ(mid.p, Eigen::Vector3d(1, 2, -3));
  EXPECT_NEAR(angleBetween(mid.q, aboutAxis(kPi / 4, {0, 0, 1})), 0, 1e-12);
  const auto quarter = tr.sample(0.5);
  EXPECT_EQ(quarter.p, Eigen::Vector3d(0.5, 1, -1.5));
  EXPECT_NEAR(angleBetween(quarter.q, aboutAxis(kPi / 8, {0, 0, 1})), 0, 1e-12);
  // At the samples, the samples themselves.
  EXPECT_EQ(tr.sample(0).p, tr.p[0]);
  EXPECT_EQ(tr.sample(2).p, tr.p[1]);
  EXPECT_NEAR(angleBetween(tr.sample(2).q, tr.q[1]), 0, 1e-12);
}

TEST(TrajectorySample, HeldOutsideTheSamples) {
  const Trajectory tr = twoSamples();
  EXPECT_EQ(tr.sample(-5).p, tr.p[0]);
  EXPECT_EQ(tr.sample(-5).q.coeffs(), tr.q[0].coeffs());
  EXPECT_EQ(tr.sample(7).p, tr.p[1]);
  EXPECT_EQ(tr.sample(7).q.coeffs(), tr.q[1].coeffs());
}

TEST(TrajectorySample, SlerpTakesTheShortestArc) {
  // -q is the same rotation as q: interpolation must not swing the long way round.
  Trajectory tr;
  tr.add(0, {0, 0, 0});
  tr.add(1, {0, 0, 0}, Eigen::Quaterniond(-aboutAxis(kPi / 2, {0, 0, 1}).coeffs()));
  EXPECT_NEAR(angleBetween(tr.sample(0.5).q, aboutAxis(kPi / 4, {0, 0, 1})), 0, 1e-12);
  EXPECT_NEAR(tr.sample(0.5).q.norm(), 1, 1e-15);
  // A 300 degree turn is the same as -60 degrees.
  Trajectory far;
  far.add(0, {0, 0, 0});
  far.add(1, {0, 0, 0}, aboutAxis(kPi * 5 / 3, {1, 0, 0}));
  EXPECT_NEAR(angleBetween(far.sample(0.5).q, aboutAxis(-kPi / 6, {1, 0, 0})), 0, 1e-12);
}

TEST(TrajectorySample, FindsTheRightInterval) {
  Trajectory tr;
  for (int i = 0; i < 10; ++i) tr.add(i * i, {double(i), 0, 0});  // t = 0, 1, 4, 9, ...
  EXPECT_DOUBLE_EQ(tr.sample(6.5).p.x(), 2.5);   // between t=4 (x=2) and t=9 (x=3)
  EXPECT_DOUBLE_EQ(tr.sample(81).p.x(), 9);
  EXPECT_DOUBLE_EQ(tr.sample(49).p.x(), 7);
}

TEST(TrajectoryTwist, LinearAndAngularVelocity) {
  const Trajectory tr = twoSamples();
  for (double t : {0.0, 0.3, 1.0, 1.999}) {
    const auto tw = tr.twist(t);
    EXPECT_TRUE(tw.v.isApprox(Eigen::Vector3d(1, 2, -3), 1e-15)) << t << ": " << tw.v.transpose();
    EXPECT_NEAR((tw.w - Eigen::Vector3d(0, 0, kPi / 4)).norm(), 0, 1e-12) << t << ": " << tw.w.transpose();
  }
  // Zero before the start and at/after the end.
  EXPECT_EQ(tr.twist(-0.1).v, Eigen::Vector3d::Zero());
  EXPECT_EQ(tr.twist(2).v, Eigen::Vector3d::Zero());
  EXPECT_EQ(tr.twist(2).w, Eigen::Vector3d::Zero());
  EXPECT_EQ(tr.twist(3).w, Eigen::Vector3d::Zero());
}

TEST(TrajectoryTwist, AngularVelocityIsInTheWorldFrame) {
  // Start turned 90 degrees about x, then turn 0.3 rad about the world z axis in 0.5 s. In the
  // body frame that axis is not z, so a body-frame result would differ.
  const Eigen::Quaterniond q0 = aboutAxis(kPi / 2, {1, 0, 0});
  Trajectory tr;
  tr.add(1, {0, 0, 0}, q0);
  tr.add(1.5, {0, 0, 0}, aboutAxis(0.3, {0, 0, 1}) * q0);
  EXPECT_NEAR((tr.twist(1.2).w - Eigen::Vector3d(0, 0, 0.6)).norm(), 0, 1e-12) << tr.twist(1.2).w.transpose();
  // Shortest arc: written as -q, the same turn.
  Trajectory flipped;
  flipped.add(1, {0, 0, 0}, q0);
  flipped.add(1.5, {0, 0, 0}, Eigen::Quaterniond(-(aboutAxis(0.3, {0, 0, 1}) * q0).coeffs()));
  EXPECT_NEAR((flipped.twist(1.2).w - Eigen::Vector3d(0, 0, 0.6)).norm(), 0, 1e-12);
}

TEST(TrajectoryTwist, AtASampleTimeTheIntervalStartingThere) {
  Trajectory tr;
  tr.add(0, {0, 0, 0});
  tr.add(1, {1, 0, 0});                                  // v = (1,0,0) on [0,1)
  tr.add(3, {1, 4, 0}, aboutAxis(0.2, {0, 1, 0}));       // v = (0,2,0), w = (0,0.1,0) on [1,3)
  tr.add(4, {1, 4, 0}, aboutAxis(0.2, {0, 1, 0}));       // still on [3,4)
  EXPECT_EQ(tr.twist(0).v, Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(tr.twist(1).v, Eigen::Vector3d(0, 2, 0));
  EXPECT_NEAR((tr.twist(1).w - Eigen::Vector3d(0, 0.1, 0)).norm(), 0, 1e-12);
  EXPECT_EQ(tr.twist(3).v, Eigen::Vector3d::Zero());
  EXPECT_NEAR(tr.twist(3).w.norm(), 0, 1e-15);
  EXPECT_EQ(tr.twist(4).v, Eigen::Vector3d::Zero());
}

TEST(TrajectoryTwist, TinyRotationsStayAccurate) {
  Trajectory tr;
  tr.add(0, {0, 0, 0});
  tr.add(1e-3, {0, 0, 0}, aboutAxis(1e-14, {0, 1, 0}));
  EXPECT_NEAR(tr.twist(0).w.y(), 1e-11, 1e-20);
}

TEST(Trajectory, SingleSampleIsAConstantPose) {
  Trajectory tr;
  tr.add(2, {1, 2, 3}, aboutAxis(0.5, {1, 0, 0}));
  for (double t : {0.0, 2.0, 5.0}) {
    EXPECT_EQ(tr.sample(t).p, Eigen::Vector3d(1, 2, 3));
    EXPECT_NEAR(angleBetween(tr.sample(t).q, aboutAxis(0.5, {1, 0, 0})), 0, 1e-15);
    EXPECT_EQ(tr.twist(t).v, Eigen::Vector3d::Zero());
    EXPECT_EQ(tr.twist(t).w, Eigen::Vector3d::Zero());
  }
  const Trajectory one = viscera::motion::parseTrajectoryCsv("2,1,2,3,0,0,0,1\n", "one.csv");
  EXPECT_EQ(one.size(), 1);
  EXPECT_EQ(one.start(), one.end());
}

TEST(Trajectory, AddRejectsTimesThatDoNotIncrease) {
  Trajectory tr;
  tr.add(1, {0, 0, 0});
  EXPECT_THROW(tr.add(1, {0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(tr.add(0.5, {0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(tr.add(2, {0, 0, 0}, Eigen::Quaterniond(0, 0, 0, 0)), std::invalid_argument);
  EXPECT_EQ(tr.size(), 1);
}

}  // namespace
