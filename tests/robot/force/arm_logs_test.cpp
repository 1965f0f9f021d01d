// Joint-state, wrench and Jacobian logs: the dVRK layouts, column maps, errors that name file:line,
// and resampling and alignment checked against values known in closed form.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

#include "core/Error.h"
#include "robot/force/ArmLogs.h"
#include "tests/support/ErrorOf.h"

namespace viscera::robot {
namespace {

using test_support::errorOf;

// A 6-joint log row at time t: q_j = j t, qd_j = j, tau_j = -j t.
std::string row(double t, int joints = 6) {
  std::string s = std::to_string(t);
  for (int j = 1; j <= joints; ++j) s += "," + std::to_string(j * t);
  for (int j = 1; j <= joints; ++j) s += "," + std::to_string(j);
  for (int j = 1; j <= joints; ++j) s += "," + std::to_string(-j * t);
  return s + "\n";
}

TEST(JointStateLog, ReadsTheDvrkLayoutWithAndWithoutHeader) {
  const std::string body = row(0) + row(0.001) + row(0.002);
  for (const std::string& text : {body, "t,q1,q2,q3,q4,q5,q6,qd1,qd2,qd3,qd4,qd5,qd6,tau1,tau2,tau3,tau4,tau5,tau6\n" + body}) {
    const JointStateLog log = parseJointStateLog(text, "log.csv");
    ASSERT_EQ(log.samples(), 3);
    EXPECT_DOUBLE_EQ(log.q()(2, 3), 4 * 0.002);
    EXPECT_DOUBLE_EQ(log.qd()(1, 5), 6);
    EXPECT_DOUBLE_EQ(log.effort()(2, 0), -0.002);
  }
}

TEST(JointStateLog, DropsTheJawOfASevenJointLog) {
  const JointStateLog log = parseJointStateLog(row(0, 7) + row(0.5, 7), "jaw.csv");
  ASSERT_EQ(log.dof, 6);
  EXPECT_DOUBLE_EQ(log.qd()(0, 5), 6);       // qd6, not q7
  EXPECT_DOUBLE_EQ(log.effort()(1, 0), -0.5);  // tau1 after the jaw's velocity
}

TEST(JointStateLog, FollowsAColumnMapOrAHeaderInAnotherOrder) {
  // effort first, then time, then velocity, then a column to skip, then position.
  std::string text;
  for (double t : {0.0, 0.1}) {
    std::string line;
    for (int j = 1; j <= 6; ++j) line += std::to_string(-j * t) + ",";
    line += std::to_string(t);
    for (int j = 1; j <= 6; ++j) line += "," + std::to_string(j);
    line += ",99";
    for (int j = 1; j <= 6; ++j) line += "," + std::to_string(j * t);
    text += line + "\n";
  }
  const std::string map = "tau1,tau2,tau3,tau4,tau5,tau6,t,qd1,qd2,qd3,qd4,qd5,qd6,-,q1,q2,q3,q4,q5,q6";
  const JointStateLog a = parseJointStateLog(text, "odd.csv", 6, map);
  EXPECT_DOUBLE_EQ(a.q()(1, 2), 0.3);
  EXPECT_DOUBLE_EQ(a.effort()(1, 2), -0.3);
  EXPECT_DOUBLE_EQ(a.series.t[1], 0.1);
  const std::string header = "Effort_1,effort_2,effort_3,effort_4,effort_5,effort_6,time,velocity1,velocity2,velocity3,velocity4,"
                             "velocity5,velocity6,jaw,position_1,position_2,position_3,position_4,position_5,position_6\n";
  EXPECT_EQ(parseJointStateLog(header + text, "named.csv").series.values, a.series.values);
}

TEST(JointStateLog, BadLogsNameFileAndLine) {
  const std::string good = row(0) + row(0.001);
  EXPECT_NE(errorOf([&] { parseJointStateLog(good + row(0.0005), "back.csv"); }).find("back.csv:3"), std::string::npos);
  std::string nan = row(0.002);
  nan.replace(nan.find(',') + 1, 8, "nan");
  EXPECT_NE(errorOf([&] { parseJointStateLog(good + nan, "nan.csv"); }).find("nan.csv:3"), std::string::npos);
  EXPECT_NE(errorOf([&] { parseJointStateLog(good + "0.003,1,2\n", "short.csv"); }).find("short.csv:3"), std::string::npos);
  EXPECT_NE(errorOf([&] { parseJointStateLog("0,1,2,3\n", "four.csv"); }).find("four.csv:1: 4 columns"), std::string::npos);
  EXPECT_NE(errorOf([&] { parseJointStateLog(good, "x.csv", 6, "t,q1"); }).find("--columns: no column for"), std::string::npos);
}

TEST(Series, InterpolatesAndResamplesLinearSignalsExactly) {
  // A 1 kHz ramp: resampling to 200 Hz by interpolation, or by averaging over each period (symmetric
  // windows), gives the ramp's values at the new times.
  Series s{"ramp", {"x"}, {}, Eigen::MatrixXd(1001, 1), {}};
  for (int i = 0; i <= 1000; ++i) {
    s.t.push_back(i * 1e-3);
    s.values(i, 0) = 2 + 3 * s.t.back();
  }
  for (bool average : {false, true}) {
    const Series r = resample(s, 200, average);
    ASSERT_EQ(r.samples(), 201);
    for (int i = 1; i + 1 < r.samples(); ++i) EXPECT_NEAR(r.values(i, 0), 2 + 3 * r.t[i], 1e-12) << i;
  }
  EXPECT_NEAR(interpolate(s, {0.1234}).values(0, 0), 2 + 3 * 0.1234, 1e-12);
  EXPECT_NE(errorOf([&] { interpolate(s, {1.5}); }).find("ramp: covers"), std::string::npos);
}

TEST(Series, AveragesAtTimesCentredOnThem) {
  // A 1 kHz ramp ending at 2.997 s, averaged at 200 Hz times up to its very end: each value is the
  // ramp's at the time (a symmetric window), and the last one is the mean of the samples in reach.
  Series s{"ramp", {"x"}, {}, Eigen::MatrixXd(2998, 1), {}};
  for (int i = 0; i <= 2997; ++i) {
    s.t.push_back(i * 1e-3);
    s.values(i, 0) = 3 * s.t.back();
  }
  const std::vector<double> times = {0.0012, 1.0012, 2.9962};
  const Series a = averageAt(s, times, 0.005);
  EXPECT_NEAR(a.values(1, 0), 3 * 1.0012, 3e-3);  // samples 0.999..1.003: mean 1.001
  EXPECT_NEAR(a.values(2, 0), 3 * (2.994 + 2.995 + 2.996 + 2.997) / 4, 1e-12);
  const std::vector<double> grid = uniformTimes(0, 2.997, 200);
  EXPECT_LE(grid.back(), 2.997);
}

TEST(Series, WritesAndReadsBackWrenchesAndJacobians) {
  Eigen::MatrixXd w(2, 6);
  w << 1, 2, 3, 4, 5, 6, -1, -2, -3, -4, -5, 1.0 / 3;
  const std::string text = formatSeries(wrenchSeries({0, 0.005}, w));
  EXPECT_EQ(text.substr(0, text.find('\n')), "t,Fx,Fy,Fz,Tx,Ty,Tz");
  const std::string path = testing::TempDir() + "/wrench.csv";
  writeSeries(path, wrenchSeries({0, 0.005}, w));
  EXPECT_EQ(readWrenchCsv(path).values, w);
  std::ofstream(path) << "t,Fx,Fy,Fz\n0,1,2,3\n0.1,4,5,6\n";
  const Series forces = readWrenchCsv(path);
  EXPECT_EQ(forces.values.cols(), 6);
  EXPECT_EQ(forces.values(1, 2), 6);
  EXPECT_EQ(forces.values(1, 3), 0);
  Eigen::MatrixXd J = Eigen::MatrixXd::Random(3, 36);
  writeSeries(path, jacobianSeries({0, 1, 2}, J, 6));
  EXPECT_EQ(readJacobianCsv(path, 6).values, J);
}

}  // namespace
}  // namespace viscera::robot
