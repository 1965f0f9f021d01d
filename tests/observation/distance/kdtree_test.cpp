// The k-d tree against brute force: random sets, duplicates, far queries, hints and search radii.
#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "observation/KdTree.h"

namespace {

using viscera::obs::KdTree;

// The nearest point by scanning all of them: smallest squared distance, smallest index on ties,
// only points strictly closer than sqrt(maxDistance2).
KdTree::Nearest bruteForce(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& p,
                           double maxDistance2 = std::numeric_limits<double>::infinity()) {
  KdTree::Nearest best;
  best.distance2 = maxDistance2;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const double dx = points(0, i) - p.x(), dy = points(1, i) - p.y(), dz = points(2, i) - p.z();
    const double d2 = dx * dx + dy * dy + dz * dz;
    if (d2 < best.distance2) best = {static_cast<int>(i), d2};
  }
  if (best.index < 0) return {};
  return best;
}

Eigen::Matrix3Xd randomPoints(int n, std::mt19937& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  Eigen::Matrix3Xd m(3, n);
  for (int i = 0; i < n; ++i) m.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return m;
}

// Exact agreement: the tree computes each squared distance with the same arithmetic as the brute
// force above, and its pruning never drops a point at the best distance, so index and distance
// must match bit for bit.
void expectSame(const KdTree::Nearest& got, const KdTree::Nearest& want, const std::string& what) {
  EXPECT_EQ(got.index, want.index) << what;
  EXPECT_EQ(got.distance2, want.distance2) << what;
}

TEST(KdTree, MatchesBruteForceOnRandomSets) {
  std::mt19937 rng(7);
  for (int n : {1, 2, 5, 31, 32, 33, 100, 1000, 5000}) {
    const Eigen::Matrix3Xd points = randomPoints(n, rng, -10, 10);
    const KdTree tree(points);
    ASSERT_EQ(tree.size(), n);
    // Queries inside the cloud, around it and far away.
    const Eigen::Matrix3Xd queries = randomPoints(300, rng, -15, 15);
    int hint = -1;
    for (Eigen::Index q = 0; q < queries.cols(); ++q) {
      const auto want = bruteForce(points, queries.col(q));
      expectSame(tree.nearest(queries.col(q)), want, "n = " + std::to_string(n) + ", query " + std::to_string(q));
      // The previous answer as a hint, and an arbitrary point as a (bad) hint: same answer.
      expectSame(tree.nearest(queries.col(q), std::numeric_limits<double>::infinity(), hint), want, "previous hint");
      expectSame(tree.nearest(queries.col(q), std::numeric_limits<double>::infinity(), static_cast<int>(q % n)), want,
                 "arbitrary hint");
      hint = want.index;
    }
    for (const Eigen::Vector3d& far : {Eigen::Vector3d(1e6, -2e6, 3e5), Eigen::Vector3d(-1e9, 0, 0)})
      expectSame(tree.nearest(far), bruteForce(points, far), "far query");
  }
}

TEST(KdTree, DuplicatesGiveTheSmallestIndex) {
  // Three copies of a random set, plus 100 copies of one point: every query ties between copies and
  // must get the smallest index (the one of the first copy).
  std::mt19937 rng(11);
  const Eigen::Matrix3Xd base = randomPoints(400, rng, 0, 1);
  Eigen::Matrix3Xd points(3, 3 * 400 + 100);
  points << base, base, base, base.col(17).replicate(1, 100);
  const KdTree tree(points);
  const Eigen::Matrix3Xd queries = randomPoints(500, rng, -0.2, 1.2);
  for (Eigen::Index q = 0; q < queries.cols(); ++q) {
    const auto want = bruteForce(points, queries.col(q));
    ASSERT_LT(want.index, 400);
    expectSame(tree.nearest(queries.col(q)), want, "query " + std::to_string(q));
    expectSame(tree.nearest(queries.col(q), std::numeric_limits<double>::infinity(), 1200 + static_cast<int>(q % 100)), want,
               "hint on a duplicate");
  }
  // A query exactly on the repeated point: distance 0, the first copy (17).
  const auto hit = tree.nearest(base.col(17), std::numeric_limits<double>::infinity(), 1250);
  EXPECT_EQ(hit.index, 17);
  EXPECT_EQ(hit.distance2, 0.0);
}

TEST(KdTree, AllPointsEqual) {
  const Eigen::Matrix3Xd points = Eigen::Vector3d(1, 2, 3).replicate(1, 200);
  const KdTree tree(points);
  const auto hit = tree.nearest(Eigen::Vector3d(1, 2, 5), std::numeric_limits<double>::infinity(), 150);
  EXPECT_EQ(hit.index, 0);
  EXPECT_EQ(hit.distance2, 4.0);
}

TEST(KdTree, SearchRadiusIsStrict) {
  // Points on the x axis at 0, 1, 2, ..., 9; the query at x = -1 is 1 from point 0.
  Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Zero(3, 10);
  for (int i = 0; i < 10; ++i) points(0, i) = i;
  const KdTree tree(points);
  const Eigen::Vector3d p(-1, 0, 0);
  EXPECT_EQ(tree.nearest(p, 1.0).index, -1);  // exactly at the radius: not strictly closer
  EXPECT_EQ(tree.nearest(p, 1.0).distance2, std::numeric_limits<double>::infinity());
  EXPECT_EQ(tree.nearest(p, 1.0 + 1e-12).index, 0);
  EXPECT_EQ(tree.nearest(p, 0.5, 3).index, -1);  // a hint outside the radius changes nothing
  // Random sets: with a radius, the brute force's answer or none.
  std::mt19937 rng(3);
  const Eigen::Matrix3Xd cloud = randomPoints(2000, rng, 0, 1);
  const KdTree big(cloud);
  const Eigen::Matrix3Xd queries = randomPoints(200, rng, -0.5, 1.5);
  for (Eigen::Index q = 0; q < queries.cols(); ++q)
    expectSame(big.nearest(queries.col(q), 0.01), bruteForce(cloud, queries.col(q), 0.01), "radius 0.1");
}

TEST(KdTree, EmptyTree) {
  const KdTree tree(Eigen::Matrix3Xd(3, 0));
  EXPECT_TRUE(tree.empty());
  const auto hit = tree.nearest(Eigen::Vector3d::Zero(), std::numeric_limits<double>::infinity(), 0);
  EXPECT_EQ(hit.index, -1);
  EXPECT_EQ(hit.distance2, std::numeric_limits<double>::infinity());
}

TEST(KdTree, RebuildReplacesThePoints) {
  std::mt19937 rng(5);
  KdTree tree(randomPoints(100, rng, 0, 1));
  const Eigen::Matrix3Xd second = randomPoints(37, rng, 5, 6);
  tree.build(second);
  EXPECT_EQ(tree.size(), 37);
  const Eigen::Vector3d p(5.5, 5.5, 5.5);
  expectSame(tree.nearest(p), bruteForce(second, p), "after rebuild");
}

}  // namespace
