// Point-based rigid registration (robot -> scene from touched corners): exact recovery, the
// residual statistics under noise, rejection of degenerate sets, and the point CSV files.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <random>
#include <string>

#include "tests/support/ErrorOf.h"
#include "core/Error.h"
#include "observation/Registration.h"
#include "tests/observation/registration/phantom.h"

using namespace registration_test;
using viscera::RigidTransform;
using viscera::obs::PointList;
using viscera::obs::registerPoints;

namespace {

RigidTransform randomTransform(std::mt19937& rng) {
  std::normal_distribution<double> g(0, 1);
  Eigen::Quaterniond q(g(rng), g(rng), g(rng), g(rng));  // a uniformly random rotation
  q.normalize();
  std::uniform_real_distribution<double> u(-500, 500);
  RigidTransform T = RigidTransform::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return T;
}

using viscera::test_support::errorOf;

TEST(PointRegistration, ExactForTheFourTopCornersWithoutNoise) {
  std::mt19937 rng(3);
  const Eigen::Matrix3Xd scene = phantomCorners().leftCols(4);
  for (int trial = 0; trial < 20; ++trial) {
    const RigidTransform truth = randomTransform(rng);  // robot -> scene
    const Eigen::Matrix3Xd robot = truth.inverse() * scene;
    const auto r = registerPoints(robot, scene);
    // Rounding only: coordinates up to ~600 mm carry ~1e-13 of absolute rounding.
    EXPECT_LT((r.transform.matrix() - truth.matrix()).cwiseAbs().maxCoeff(), 1e-12) << "trial " << trial;
    EXPECT_LT(r.max, 1e-12);
    EXPECT_LE(r.rms, r.max);
    ASSERT_EQ(r.residuals.cols(), 4);
    ASSERT_EQ(r.norms.size(), 4);
    EXPECT_NEAR(r.transform.linear().determinant(), 1.0, 1e-14);
  }
}

// With isotropic Gaussian noise of sigma per coordinate on the target points, a least-squares fit
// of the 6 rigid parameters leaves E[sum |r_i|^2] = (3n - 6) sigma^2 (to first order in
// sigma / size): E[RMS^2] = (3n - 6) / n sigma^2, 1.5 sigma^2 for the 4 top corners and
// 2.25 sigma^2 for all 8 corners.
void checkNoiseLevel(const Eigen::Matrix3Xd& scene, unsigned seed) {
  const int n = static_cast<int>(scene.cols()), trials = 4000;
  const double sigma = 0.5;  // mm, a touch with the end-effector
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0, sigma);
  double sumRms2 = 0;
  for (int k = 0; k < trials; ++k) {
    const RigidTransform truth = randomTransform(rng);
    const Eigen::Matrix3Xd robot = truth.inverse() * scene;
    Eigen::Matrix3Xd noisy = scene;
    for (Eigen::Index i = 0; i < noisy.size(); ++i) noisy(i) += g(rng);
    const auto r = registerPoints(robot, noisy);
    sumRms2 += r.rms * r.rms;
  }
  const double expected = (3.0 * n - 6) / n * sigma * sigma, mean = sumRms2 / trials;
  // sum |r|^2 / sigma^2 is chi-square with 3n - 6 degrees of freedom (variance 2 (3n - 6)); the
  // mean of 4000 trials has a relative standard error of sqrt(2 / (4000 (3n - 6))) = 0.9 % (n = 4)
  // and 0.5 % (n = 8). 4 % is 4 standard errors for n = 4; second-order effects
  // ((0.5 / 40)^2 ~ 2e-4) are far below.
  EXPECT_NEAR(mean / expected, 1.0, 0.04) << "n = " << n;
  std::printf("[ measured ] n = %d: mean RMS^2 %.5f mm^2, expected %.5f (ratio %.4f)\n", n, mean, expected, mean / expected);
}

TEST(PointRegistration, ResidualRmsMatchesTheNoiseLevel) {
  checkNoiseLevel(phantomCorners().leftCols(4), 5);
  checkNoiseLevel(phantomCorners(), 6);
}

TEST(PointRegistration, ResidualsAreTransformedSourceMinusTarget) {
  // Target = source shifted by (1, 2, 3), one point moved 0.3 further along z: the fit is not
  // exact, and the residuals must be T s_i - d_i for the returned T.
  Eigen::Matrix3Xd s = phantomCorners().leftCols(4);
  Eigen::Matrix3Xd d = s.colwise() + Eigen::Vector3d(1, 2, 3);
  d(2, 1) += 0.3;
  const auto r = registerPoints(s, d);
  const Eigen::Matrix3Xd expected = (r.transform * s) - d;
  EXPECT_LT((r.residuals - expected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(r.max, r.norms.maxCoeff(), 0);
  EXPECT_NEAR(r.rms, std::sqrt(r.norms.squaredNorm() / 4), 1e-15);
  // The residuals of a least-squares rigid fit sum to zero (the centroids coincide).
  EXPECT_LT(r.residuals.rowwise().sum().norm(), 1e-12);
  EXPECT_GT(r.max, 0.05);
}

TEST(PointRegistration, RejectsDegenerateSets) {
  const Eigen::Matrix3Xd corners = phantomCorners();
  // Fewer than 3 points.
  EXPECT_NE(errorOf([&] { registerPoints(corners.leftCols(2), corners.leftCols(2), "robot.csv", "scene.csv"); }).find("at least 3"),
            std::string::npos);
  // Different counts.
  EXPECT_NE(errorOf([&] { registerPoints(corners.leftCols(4), corners.leftCols(3), "robot.csv", "scene.csv"); })
                .find("robot.csv has 4 points but scene.csv has 3"),
            std::string::npos);
  // Collinear: points along one edge of the block, in either set.
  Eigen::Matrix3Xd line(3, 4);
  line << 0, 10, 20, 68.7,
          0, 0, 0, 0,
          39.3, 39.3, 39.3, 39.3;
  const std::string e1 = errorOf([&] { registerPoints(line, corners.leftCols(4), "robot.csv", "scene.csv"); });
  EXPECT_NE(e1.find("robot.csv: "), std::string::npos) << e1;
  EXPECT_NE(e1.find("collinear"), std::string::npos) << e1;
  const std::string e2 = errorOf([&] { registerPoints(corners.leftCols(4), line, "robot.csv", "scene.csv"); });
  EXPECT_NE(e2.find("scene.csv: "), std::string::npos) << e2;
  // Nearly collinear: 1 um off a 70 mm line is still rejected.
  Eigen::Matrix3Xd almost = line;
  almost(1, 2) = 1e-3;
  EXPECT_NE(errorOf([&] { registerPoints(almost, corners.leftCols(4)); }).find("collinear"), std::string::npos);
  // Coincident.
  const Eigen::Matrix3Xd same = Eigen::Vector3d(1, 2, 3).replicate(1, 4);
  EXPECT_NE(errorOf([&] { registerPoints(same, corners.leftCols(4)); }).find("coincide"), std::string::npos);
  // Non-finite.
  Eigen::Matrix3Xd nan = corners.leftCols(4);
  nan(0, 2) = std::nan("");
  EXPECT_NE(errorOf([&] { registerPoints(nan, corners.leftCols(4), "robot.csv"); }).find("robot.csv: point 3 is not finite"),
            std::string::npos);
  // Three non-collinear points are enough.
  EXPECT_NO_THROW(registerPoints(corners.leftCols(3), corners.leftCols(3)));
}

// ---------------------------------------------------------------------------------------------
// Point files

TEST(PointFiles, ParsesHeaderNamesCommentsAndBlanks) {
  const PointList p = viscera::obs::parsePointList("# touched corners\nname,x,y,z\n\nA, 1, 2, 3\nB,4,5,6\r\n  C ,+7,-8,9e1\n", "robot.csv");
  ASSERT_EQ(p.points.cols(), 3);
  EXPECT_EQ(p.names, (std::vector<std::string>{"A", "B", "C"}));
  EXPECT_EQ(p.lines, (std::vector<int>{4, 5, 6}));
  EXPECT_EQ(p.points.col(2), Eigen::Vector3d(7, -8, 90));
  const PointList q = viscera::obs::parsePointList("1,2,3\n4,5,6\n7,8,9\n", "scene.csv");
  EXPECT_TRUE(q.names.empty());
  EXPECT_EQ(q.points.col(0), Eigen::Vector3d(1, 2, 3));
  // A numeric name in the 4-column form is a name.
  const PointList r = viscera::obs::parsePointList("1,0,0,0\n2,1,0,0\n3,0,1,0\n", "n.csv");
  EXPECT_EQ(r.names, (std::vector<std::string>{"1", "2", "3"}));
}

TEST(PointFiles, ErrorsNameFileAndLine) {
  auto err = [](const std::string& text) { return errorOf([&] { viscera::obs::parsePointList(text, "pts.csv"); }); };
  EXPECT_NE(err("").find("pts.csv: no points"), std::string::npos);
  EXPECT_NE(err("x,y,z\n# nothing\n").find("no points"), std::string::npos);
  EXPECT_NE(err("1,2\n").find("pts.csv:1: expected 3 columns (x,y,z) or 4 (name,x,y,z), found 2"), std::string::npos);
  EXPECT_NE(err("1,2,3\n4,5,6,7\n").find("pts.csv:2: expected 3 columns"), std::string::npos);
  EXPECT_NE(err("1,2,3\n4,abc,6\n").find("pts.csv:2: y: 'abc' is not a number"), std::string::npos);
  EXPECT_NE(err("1,2,3\n4,5,nan\n").find("pts.csv:2: z: 'nan' is not finite"), std::string::npos);
  EXPECT_NE(err("1,2,3\n4,5,1e999\n").find("pts.csv:2: z: '1e999' is not finite"), std::string::npos);
  EXPECT_NE(err("A,1,2,3\nB,4,5,6\nA,7,8,9\n").find("pts.csv:3: point name 'A' repeated (first on line 1)"), std::string::npos);
  EXPECT_NE(err(",1,2,3\n").find("pts.csv:1: empty point name"), std::string::npos);
  // Only the first line may be a header.
  EXPECT_NE(err("1,2,3\nx,y,z\n").find("pts.csv:2: x: 'x' is not a number"), std::string::npos);
  EXPECT_NE(errorOf([] { viscera::obs::readPointList("/nonexistent/robot.csv"); }).find("/nonexistent/robot.csv: cannot open"),
            std::string::npos);
}

TEST(PointFiles, PairsByNameOrByOrder) {
  const PointList robot = viscera::obs::parsePointList("A,1,0,0\nB,0,1,0\nC,0,0,1\n", "robot.csv");
  const PointList scene = viscera::obs::parsePointList("name,x,y,z\nC,30,0,0\nA,10,0,0\nB,20,0,0\n", "scene.csv");
  Eigen::Matrix3Xd S, D;
  std::vector<std::string> labels;
  viscera::obs::pairPoints(robot, scene, S, D, labels);
  EXPECT_EQ(labels, (std::vector<std::string>{"A", "B", "C"}));
  EXPECT_EQ(D.row(0), Eigen::RowVector3d(10, 20, 30));
  EXPECT_EQ(S, robot.points);

  const PointList unnamed = viscera::obs::parsePointList("1,0,0\n0,1,0\n0,0,1\n", "u.csv");
  viscera::obs::pairPoints(unnamed, unnamed, S, D, labels);
  EXPECT_EQ(labels, (std::vector<std::string>{"1", "2", "3"}));

  auto pairErr = [&](const PointList& a, const PointList& b) {
    return errorOf([&] { viscera::obs::pairPoints(a, b, S, D, labels); });
  };
  const PointList other = viscera::obs::parsePointList("A,1,0,0\nB,0,1,0\nD,0,0,1\n", "other.csv");
  EXPECT_NE(pairErr(robot, other).find("robot.csv:3: point 'C' has no point of the same name in other.csv"), std::string::npos);
  const PointList fewer = viscera::obs::parsePointList("A,1,0,0\nB,0,1,0\n", "fewer.csv");
  EXPECT_NE(pairErr(fewer, robot).find("robot.csv:3: point 'C' has no point of the same name in fewer.csv"), std::string::npos);
  EXPECT_NE(pairErr(robot, unnamed).find("robot.csv names its points but u.csv does not"), std::string::npos);
  const PointList four = viscera::obs::parsePointList("1,0,0\n0,1,0\n0,0,1\n1,1,1\n", "four.csv");
  EXPECT_NE(pairErr(unnamed, four).find("u.csv has 3 points but four.csv has 4"), std::string::npos);
}

}  // namespace
