// Cloud -> surface distances on cases with known answers: a plane, an icosphere, a single triangle
// worked by hand; the statistics' definitions; the cut-off; thread independence; the VTK export.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "observation/CloudDistance.h"
#include "tests/apps/cli_helpers.h"

namespace {

using namespace viscera::obs;

const double kNaN = std::numeric_limits<double>::quiet_NaN();

// A square [0, n] x [0, n] in the plane z = 0 on (n + 1) x (n + 1) vertices at unit spacing, two
// triangles per unit square, counter-clockwise seen from +z (normal +z).
struct Surface {
  Eigen::Matrix3Xd x;
  TriangleList triangles;
};

Surface planarSquare(int n) {
  Surface s;
  s.x.resize(3, (n + 1) * (n + 1));
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) s.x.col(i + (n + 1) * j) = Eigen::Vector3d(i, j, 0);
  s.triangles.resize(3, 2 * n * n);
  int t = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = i + (n + 1) * j, b = a + 1, c = a + n + 1, d = c + 1;
      s.triangles.col(t++) << a, b, d;
      s.triangles.col(t++) << a, d, c;
    }
  return s;
}

// The unit icosphere: an icosahedron whose faces are split in four `levels` times, new vertices
// pushed onto the sphere; faces oriented outwards.
Surface icosphere(int levels) {
  const double g = (1 + std::sqrt(5.0)) / 2;
  std::vector<Eigen::Vector3d> v = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                                    {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                       {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                       {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[static_cast<size_t>(a)] + v[static_cast<size_t>(b)]).normalized());
      return mid[key] = static_cast<int>(v.size() - 1);
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& t : f) {
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({t[1], bc, ab});
      next.push_back({t[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    f = next;
  }
  Surface s;
  s.x.resize(3, static_cast<Eigen::Index>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) s.x.col(static_cast<Eigen::Index>(i)) = v[i];
  s.triangles.resize(3, static_cast<Eigen::Index>(f.size()));
  for (size_t t = 0; t < f.size(); ++t) {
    auto tri = f[t];
    const Eigen::Vector3d a = v[static_cast<size_t>(tri[0])], b = v[static_cast<size_t>(tri[1])], c = v[static_cast<size_t>(tri[2])];
    if ((b - a).cross(c - a).dot(a + b + c) < 0) std::swap(tri[1], tri[2]);
    s.triangles.col(static_cast<Eigen::Index>(t)) << tri[0], tri[1], tri[2];
  }
  return s;
}

DistanceResult measure(const Surface& s, const Eigen::Matrix3Xd& cloud, DistanceOptions options) {
  CloudDistance d(s.triangles, static_cast<int>(s.x.cols()), options);
  d.setSurface(s.x);
  return d.measure(cloud);
}

DistanceOptions method(DistanceMethod m, int factor = 3) {
  DistanceOptions o;
  o.method = m;
  o.factor = factor;
  return o;
}

TEST(CloudDistance, PointsAboveAPlane) {
  // Points over the square at heights above and below: the distance is |height|, the residual
  // -height * (0, 0, 1), the sign that of the height. The points sit above points of the factor-3
  // lattice (multiples of 1/3), so the nearest sample is straight below and the vertex method is
  // exact too. Coordinates are below 5, so rounding stays under 1e-14; 1e-12 is the tolerance.
  const Surface sq = planarSquare(4);
  Eigen::Matrix3Xd cloud(3, 6);
  cloud << 1.0 / 3, 2, 3 + 2.0 / 3, 0.5 + 1.0 / 6, 4.0 / 3, 3,  //
      1.0 / 3, 2, 1 + 1.0 / 3, 2.0 / 3, 4, 0.0,                  //
      0.5, -0.25, 2, 1e-3, -1.5, 0.75;
  for (DistanceMethod m : {DistanceMethod::Vertices, DistanceMethod::Triangles}) {
    const DistanceResult r = measure(sq, cloud, method(m));
    ASSERT_EQ(r.distance.size(), 6u);
    for (int i = 0; i < 6; ++i) {
      const double h = cloud(2, i);
      EXPECT_NEAR(r.distance[static_cast<size_t>(i)], std::abs(h), 1e-12) << methodName(m) << " point " << i;
      EXPECT_NEAR((r.residual.col(i) - Eigen::Vector3d(0, 0, -h)).norm(), 0.0, 1e-12) << methodName(m) << " point " << i;
      if (m == DistanceMethod::Triangles) {
        EXPECT_NEAR(r.signedDistance[static_cast<size_t>(i)], h, 1e-12) << "point " << i;
      }
    }
    EXPECT_EQ(r.signedDistance.empty(), m == DistanceMethod::Vertices);
    EXPECT_EQ(r.stats.count, 6);
    EXPECT_NEAR(r.stats.max, 2.0, 1e-12);
  }
  // Points over the plane but off the lattice: exact for triangles, at most half a sample diagonal
  // more for vertices.
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0.2, 3.8), h(-1, 1);
  Eigen::Matrix3Xd random(3, 500);
  for (int i = 0; i < 500; ++i) random.col(i) = Eigen::Vector3d(u(rng), u(rng), h(rng));
  const DistanceResult exact = measure(sq, random, method(DistanceMethod::Triangles));
  const DistanceResult sampled = measure(sq, random, method(DistanceMethod::Vertices));
  for (int i = 0; i < 500; ++i) {
    const double z = random(2, i);
    EXPECT_NEAR(exact.distance[static_cast<size_t>(i)], std::abs(z), 1e-12);
    EXPECT_NEAR(exact.signedDistance[static_cast<size_t>(i)], z, 1e-12);
    const double halfDiagonal = std::sqrt(2.0) / 6;  // samples 1/3 apart
    EXPECT_GE(sampled.distance[static_cast<size_t>(i)], std::abs(z) - 1e-12);
    EXPECT_LE(sampled.distance[static_cast<size_t>(i)], std::hypot(z, halfDiagonal) + 1e-12);
  }
}

TEST(CloudDistance, IcosphereExactDistancesAboveFaceCentres) {
  // Points on the line through each face's centroid along its normal, at heights h outside and
  // inside. The sphere is convex, so outside the closest surface point is the centroid and the
  // distance is h (the rest of the surface lies behind the face's plane). Inside at depth 0.02 the
  // neighbouring face planes are farther than the face itself (their tilt of ~0.2 rad over the
  // centroid's ~0.04 distance to the edges adds ~0.008), so the answer is again the centroid.
  // Tolerance 1e-12: everything is O(1).
  const Surface sphere = icosphere(2);
  ASSERT_EQ(sphere.triangles.cols(), 320);
  const std::vector<double> heights = {0.3, 0.1, 1e-4, -0.02};
  const int m = static_cast<int>(sphere.triangles.cols());
  Eigen::Matrix3Xd cloud(3, m * static_cast<int>(heights.size()));
  std::vector<Eigen::Vector3d> normals, centroids;
  for (int t = 0; t < m; ++t) {
    const Eigen::Vector3d a = sphere.x.col(sphere.triangles(0, t)), b = sphere.x.col(sphere.triangles(1, t)),
                          c = sphere.x.col(sphere.triangles(2, t));
    normals.push_back((b - a).cross(c - a).normalized());
    centroids.push_back((a + b + c) / 3);
    for (size_t k = 0; k < heights.size(); ++k)
      cloud.col(t * static_cast<int>(heights.size()) + static_cast<int>(k)) = centroids.back() + heights[k] * normals.back();
  }
  const DistanceResult r = measure(sphere, cloud, method(DistanceMethod::Triangles));
  for (int t = 0; t < m; ++t)
    for (size_t k = 0; k < heights.size(); ++k) {
      const size_t i = static_cast<size_t>(t) * heights.size() + k;
      const double h = heights[k];
      EXPECT_NEAR(r.distance[i], std::abs(h), 1e-12) << "face " << t << " height " << h;
      EXPECT_NEAR(r.signedDistance[i], h, 1e-12) << "face " << t << " height " << h;
      EXPECT_NEAR((r.residual.col(static_cast<Eigen::Index>(i)) + h * normals[static_cast<size_t>(t)]).norm(), 0.0, 1e-12);
      EXPECT_EQ(r.nearest[i], t);
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(r.barycentric(j, static_cast<Eigen::Index>(i)), 1.0 / 3, 1e-9);
    }
}

TEST(CloudDistance, IcosphereSignIsOutsideOrInside) {
  // Random points at radius 0.5 .. 1.5: the sign says whether they are outside the polyhedron.
  // The polyhedron lies between its inradius and the unit sphere, so points beyond radius 1 are
  // outside and points within 0.95 (below the inradius of ~0.98 for this tessellation) inside;
  // the pseudo-normals make this right at edges and vertices too.
  const Surface sphere = icosphere(2);
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> radius(0.5, 1.5);
  std::vector<Eigen::Vector3d> kept;
  while (kept.size() < 2000) {
    const double r = radius(rng);
    if (r > 0.95 && r < 1.0) continue;
    kept.push_back(Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized() * r);
  }
  // Also points straight out of and into the vertices, where the closest feature is a vertex.
  for (Eigen::Index v = 0; v < sphere.x.cols(); ++v) {
    kept.push_back(1.2 * sphere.x.col(v));
    kept.push_back(0.9 * sphere.x.col(v));
  }
  Eigen::Matrix3Xd cloud(3, static_cast<Eigen::Index>(kept.size()));
  for (size_t i = 0; i < kept.size(); ++i) cloud.col(static_cast<Eigen::Index>(i)) = kept[i];
  const DistanceResult r = measure(sphere, cloud, method(DistanceMethod::Triangles));
  for (size_t i = 0; i < kept.size(); ++i) {
    const bool outside = kept[i].norm() > 1.0;
    EXPECT_EQ(r.signedDistance[i] > 0, outside) << "point " << i << " at radius " << kept[i].norm();
    EXPECT_EQ(std::abs(r.signedDistance[i]), r.distance[i]);
  }
  // Points out of the vertices are at distance 0.2 and 0.1 from them (the vertices are the
  // closest points: radial lines through a convex polyhedron's vertex leave every face behind).
  const size_t first = kept.size() - 2 * static_cast<size_t>(sphere.x.cols());
  for (size_t i = first; i < kept.size(); i += 2) {
    EXPECT_NEAR(r.signedDistance[i], 0.2, 1e-12);
    EXPECT_NEAR(r.signedDistance[i + 1], -0.1, 0.1 * 0.05);  // inside, a face may be a little closer
  }
}

TEST(CloudDistance, IcosphereVerticesMatchBruteForce) {
  // The vertex method against the nearest of all super-sampled points, found by scanning them.
  const Surface sphere = icosphere(2);
  DistanceOptions o = method(DistanceMethod::Vertices, 3);
  CloudDistance d(sphere.triangles, static_cast<int>(sphere.x.cols()), o);
  d.setSurface(sphere.x);
  const Eigen::Matrix3Xd samples = d.samples();
  // 162 vertices, 480 edges with 2 inner points, 320 faces with 1: 1442 samples.
  ASSERT_EQ(samples.cols(), 162 + 480 * 2 + 320);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.6, 1.6);
  Eigen::Matrix3Xd cloud(3, 3000);
  for (int i = 0; i < 3000; ++i) cloud.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
  const DistanceResult r = d.measure(cloud);
  for (int i = 0; i < 3000; ++i) {
    double best = std::numeric_limits<double>::infinity();
    int arg = -1;
    for (Eigen::Index s = 0; s < samples.cols(); ++s) {
      const double d2 = (samples.col(s) - cloud.col(i)).squaredNorm();
      if (d2 < best) best = d2, arg = static_cast<int>(s);
    }
    // Same value up to the order of summation (1e-15 relative); the index must match unless two
    // samples are that close to a tie.
    EXPECT_NEAR(r.distance[static_cast<size_t>(i)], std::sqrt(best), 1e-12) << "point " << i;
    if (r.nearest[static_cast<size_t>(i)] != arg) {
      EXPECT_NEAR((samples.col(r.nearest[static_cast<size_t>(i)]) - cloud.col(i)).squaredNorm(), best, 1e-12);
    }
    const Eigen::Vector3d residual = samples.col(r.nearest[static_cast<size_t>(i)]) - cloud.col(i);
    EXPECT_EQ(Eigen::Vector3d(r.residual.col(i)), residual);
  }
}

TEST(DistanceStats, DefinitionsOnKnownData) {
  // 1, 2, ..., 20: mean 10.5, mean square 20 * 21 * 41 / 6 / 20 = 143.5, median (10 + 11) / 2,
  // 95th percentile at h = 0.95 * 19 = 18.05: 19 + 0.05 * (20 - 19) = 19.05 (numpy's default).
  std::vector<double> d;
  for (int i = 20; i >= 1; --i) d.push_back(i);  // order must not matter
  DistanceStats s = summarize(d);
  EXPECT_EQ(s.count, 20);
  EXPECT_EQ(s.beyond, 0);
  EXPECT_DOUBLE_EQ(s.mean, 10.5);
  EXPECT_DOUBLE_EQ(s.meanSquared, 143.5);
  EXPECT_DOUBLE_EQ(s.rms, std::sqrt(143.5));
  EXPECT_DOUBLE_EQ(s.median, 10.5);
  EXPECT_DOUBLE_EQ(s.p95, 19.05);
  EXPECT_EQ(s.max, 20);
  EXPECT_TRUE(std::isnan(s.signedMean));

  // Odd count: the middle value; signed mean of the signed values; points flagged out are beyond.
  s = summarize({3, 1, 2, 100, 5}, {-3, 1, 2, 100, -5}, {1, 1, 1, 0, 1});
  EXPECT_EQ(s.count, 4);
  EXPECT_EQ(s.beyond, 1);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.mean, 2.75);
  EXPECT_DOUBLE_EQ(s.signedMean, -1.25);
  EXPECT_DOUBLE_EQ(s.max, 5);
  EXPECT_DOUBLE_EQ(s.p95, 3 + 0.85 * 2);  // h = 0.95 * 3 = 2.85 between 3 and 5

  std::vector<double> one = {7};
  EXPECT_EQ(percentile(one, 0.95), 7);
  std::vector<double> none;
  EXPECT_TRUE(std::isnan(percentile(none, 0.5)));
  s = summarize({}, {}, {});
  EXPECT_EQ(s.count, 0);
  EXPECT_TRUE(std::isnan(s.mean) && std::isnan(s.median) && std::isnan(s.max));
}

// One triangle (0,0,0), (3,0,0), (0,3,0) (normal +z) and three points worked by hand:
//   P1 = (1, 1, 0.5): above the centroid (1, 1, 0), a sample; residual (0, 0, -0.5).
//   P2 = (2.1, 0, 0.2): nearest sample (2, 0, 0) on edge ab (weights a 1/3, b 2/3), residual
//        (-0.1, 0, -0.2); nearest surface point (2.1, 0, 0) (weights a 0.3, b 0.7), residual (0, 0, -0.2).
//   P3 = (0, 0, -1): below vertex a; residual (0, 0, 1), signed -1.
struct HandCase {
  Surface s;
  Eigen::Matrix3Xd cloud;
  HandCase() : cloud(3, 3) {
    s.x.resize(3, 3);
    s.x << 0, 3, 0, 0, 0, 3, 0, 0, 0;
    s.triangles.resize(3, 1);
    s.triangles << 0, 1, 2;
    cloud << 1, 2.1, 0, 1, 0, 0, 0.5, 0.2, -1;
  }
};

TEST(CloudDistance, PerVertexMeansByHandVertices) {
  const HandCase c;
  const DistanceResult r = measure(c.s, c.cloud, method(DistanceMethod::Vertices, 3));
  const double d2 = std::sqrt(0.01 + 0.04);
  EXPECT_NEAR(r.distance[0], 0.5, 1e-15);
  EXPECT_NEAR(r.distance[1], d2, 1e-15);
  EXPECT_NEAR(r.distance[2], 1.0, 1e-15);
  // Vertex a: weights 1/3 (P1), 1/3 (P2), 1 (P3), sum 5/3.
  //   mean residual = (1/3 (0,0,-0.5) + 1/3 (-0.1,0,-0.2) + (0,0,1)) / (5/3) = (-0.02, 0, 0.46)
  //   mean distance = (0.5/3 + d2/3 + 1) / (5/3) = (3.5 + d2) / 5
  // Vertex b: weights 1/3 (P1), 2/3 (P2), sum 1: (0,0,-0.5)/3 + 2/3 (-0.1,0,-0.2) = (-0.2/3, 0, -0.3)
  //   mean distance 0.5/3 + 2 d2 / 3
  // Vertex c: P1 only: (0, 0, -0.5), distance 0.5.
  // Tolerance 1e-14: sums of a few O(1) terms.
  EXPECT_NEAR((r.meanResidual.col(0) - Eigen::Vector3d(-0.02, 0, 0.46)).norm(), 0, 1e-14);
  EXPECT_NEAR((r.meanResidual.col(1) - Eigen::Vector3d(-0.2 / 3, 0, -0.3)).norm(), 0, 1e-14);
  EXPECT_NEAR((r.meanResidual.col(2) - Eigen::Vector3d(0, 0, -0.5)).norm(), 0, 1e-14);
  EXPECT_NEAR(r.meanDistance[0], (3.5 + d2) / 5, 1e-14);
  EXPECT_NEAR(r.meanDistance[1], 0.5 / 3 + 2 * d2 / 3, 1e-14);
  EXPECT_NEAR(r.meanDistance[2], 0.5, 1e-14);
  EXPECT_EQ(r.pointCount, (std::vector<int>{3, 2, 1}));
  // Frame statistics of 0.5, d2 = 0.2236, 1.
  EXPECT_NEAR(r.stats.mean, (1.5 + d2) / 3, 1e-15);
  EXPECT_NEAR(r.stats.median, 0.5, 1e-15);
  EXPECT_NEAR(r.stats.meanSquared, (0.25 + 0.05 + 1) / 3, 1e-15);
}

TEST(CloudDistance, PerVertexMeansByHandTriangles) {
  const HandCase c;
  const DistanceResult r = measure(c.s, c.cloud, method(DistanceMethod::Triangles));
  EXPECT_NEAR(r.distance[1], 0.2, 1e-15);
  ASSERT_EQ(r.signedDistance.size(), 3u);
  EXPECT_NEAR(r.signedDistance[0], 0.5, 1e-15);
  EXPECT_NEAR(r.signedDistance[1], 0.2, 1e-15);
  EXPECT_NEAR(r.signedDistance[2], -1.0, 1e-15);
  // Vertex a: weights 1/3, 0.3, 1 (sum 49/30); z residuals -0.5, -0.2, 1:
  //   mean z = (-0.5/3 - 0.06 + 1) / (49/30) = (23.2/30) / (49/30) = 23.2 / 49
  //   mean distance = (0.5/3 + 0.06 + 1) / (49/30) = 36.8 / 49
  // Vertex b: weights 1/3, 0.7 (sum 31/30): z = (-0.5/3 - 0.14) / (31/30) = -9.2 / 31,
  //   distance (0.5/3 + 0.14) / (31/30) = 9.2 / 31
  // Vertex c: P1 only.
  EXPECT_NEAR((r.meanResidual.col(0) - Eigen::Vector3d(0, 0, 23.2 / 49)).norm(), 0, 1e-14);
  EXPECT_NEAR((r.meanResidual.col(1) - Eigen::Vector3d(0, 0, -9.2 / 31)).norm(), 0, 1e-14);
  EXPECT_NEAR((r.meanResidual.col(2) - Eigen::Vector3d(0, 0, -0.5)).norm(), 0, 1e-14);
  EXPECT_NEAR(r.meanDistance[0], 36.8 / 49, 1e-14);
  EXPECT_NEAR(r.meanDistance[1], 9.2 / 31, 1e-14);
  EXPECT_EQ(r.pointCount, (std::vector<int>{3, 2, 1}));
  EXPECT_NEAR(r.stats.signedMean, (0.5 + 0.2 - 1) / 3, 1e-15);
}

TEST(CloudDistance, CutOffLeavesFarPointsOut) {
  // With a cut-off of 0.6, P3 (distance 1) is beyond: the statistics and the vertex means are those
  // of P1 and P2 only, and vertex a keeps weights 1/3, 1/3.
  const HandCase c;
  DistanceOptions o = method(DistanceMethod::Vertices, 3);
  o.maxDistance = 0.6;
  const DistanceResult r = measure(c.s, c.cloud, o);
  EXPECT_EQ(r.stats.count, 2);
  EXPECT_EQ(r.stats.beyond, 1);
  EXPECT_EQ(r.within, (std::vector<char>{1, 1, 0}));
  EXPECT_NEAR(r.stats.max, 0.5, 1e-15);
  EXPECT_EQ(r.pointCount, (std::vector<int>{2, 2, 1}));
  EXPECT_NEAR((r.meanResidual.col(0) - Eigen::Vector3d(-0.05, 0, -0.35)).norm(), 0, 1e-14);
  EXPECT_NEAR(r.distance[2], 1.0, 1e-15);  // still measured, only left out
  // A vertex no point is attributed to has NaN means and count 0.
  o.maxDistance = 0.1;
  const DistanceResult none = measure(c.s, c.cloud, o);
  EXPECT_EQ(none.stats.count, 0);
  EXPECT_EQ(none.pointCount, (std::vector<int>{0, 0, 0}));
  EXPECT_TRUE(std::isnan(none.meanDistance[0]) && std::isnan(none.meanResidual(2, 1)));
  EXPECT_TRUE(std::isnan(none.stats.mean));
}

TEST(CloudDistance, ThreadsDoNotChangeTheResult) {
  const Surface sphere = icosphere(3);
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1.3, 1.3);
  Eigen::Matrix3Xd cloud(3, 20000);
  for (int i = 0; i < 20000; ++i) cloud.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
  for (DistanceMethod m : {DistanceMethod::Vertices, DistanceMethod::Triangles}) {
    DistanceOptions serial = method(m), parallel = method(m);
    serial.parallel = false;
    parallel.parallel = true;
    const DistanceResult a = measure(sphere, cloud, serial), b = measure(sphere, cloud, parallel);
    EXPECT_EQ(a.distance, b.distance) << methodName(m);
    EXPECT_EQ(a.nearest, b.nearest) << methodName(m);
    EXPECT_EQ(a.signedDistance, b.signedDistance) << methodName(m);
    EXPECT_EQ(a.residual, b.residual) << methodName(m);
    EXPECT_EQ(a.stats.mean, b.stats.mean) << methodName(m);
    EXPECT_EQ(a.stats.p95, b.stats.p95) << methodName(m);
    // Bit-equal per-vertex sums (NaN where empty: compare the counts and the non-NaN values).
    EXPECT_EQ(a.pointCount, b.pointCount) << methodName(m);
    for (size_t v = 0; v < a.meanDistance.size(); ++v)
      if (a.pointCount[v] > 0) {
        EXPECT_EQ(a.meanDistance[v], b.meanDistance[v]);
      }
  }
}

TEST(CloudDistance, RejectsBadInput) {
  const Surface sq = planarSquare(1);
  EXPECT_THROW(CloudDistance(TriangleList(3, 0), 4), std::invalid_argument);
  DistanceOptions o;
  o.factor = 0;
  EXPECT_THROW(CloudDistance(sq.triangles, 4, o), std::invalid_argument);
  EXPECT_THROW(CloudDistance(sq.triangles, 3), std::invalid_argument);  // index 3 of 3 vertices
  CloudDistance d(sq.triangles, 4);
  EXPECT_THROW(d.measure(Eigen::Matrix3Xd::Zero(3, 1)), std::logic_error);  // no surface yet
  EXPECT_THROW(d.setSurface(Eigen::Matrix3Xd::Zero(3, 5)), std::invalid_argument);
  d.setSurface(sq.x);
  Eigen::Matrix3Xd bad = Eigen::Matrix3Xd::Zero(3, 2);
  bad(1, 1) = kNaN;
  EXPECT_THROW(d.measure(bad), std::invalid_argument);
  // An empty cloud is fine: no statistics.
  EXPECT_EQ(d.measure(Eigen::Matrix3Xd(3, 0)).stats.count, 0);
}

// --- The VTK export, read back as text: the arrays exist with the right sizes and values. ---

std::vector<uint8_t> base64Decode(const std::string& text) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::vector<uint8_t> out;
  uint32_t buffer = 0;
  int bits = 0;
  for (char c : text) {
    const int v = value(c);
    if (v < 0) continue;  // padding, blanks
    buffer = (buffer << 6) | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<uint8_t>(buffer >> bits));
    }
  }
  return out;
}

// The values of the Float64 array `name` in a VTK XML file written uncompressed (a UInt64 byte
// count, then little-endian doubles, base64); `components` receives its NumberOfComponents. Fails
// the test and returns nothing if the array is missing.
std::vector<double> readArray(const std::string& xml, const std::string& name, int& components) {
  const size_t at = xml.find("Name=\"" + name + "\"");
  if (at == std::string::npos) {
    ADD_FAILURE() << "no array " << name;
    return {};
  }
  const size_t tagStart = xml.rfind('<', at), tagEnd = xml.find('>', at);
  const std::string tag = xml.substr(tagStart, tagEnd - tagStart);
  components = 1;
  const size_t nc = tag.find("NumberOfComponents=\"");
  if (nc != std::string::npos) components = std::stoi(tag.substr(nc + 20));
  const std::vector<uint8_t> bytes = base64Decode(xml.substr(tagEnd + 1, xml.find('<', tagEnd) - tagEnd - 1));
  uint64_t count = 0;
  std::memcpy(&count, bytes.data(), 8);
  EXPECT_EQ(count + 8, bytes.size()) << name;
  std::vector<double> values(count / 8);
  std::memcpy(values.data(), bytes.data() + 8, count);
  return values;
}

TEST(ResidualExport, VtpFilesHoldTheFields) {
  const HandCase c;
  DistanceOptions o = method(DistanceMethod::Triangles);
  o.maxDistance = 0.6;
  const DistanceResult r = measure(c.s, c.cloud, o);
  viscera::test_support::TempDir tmp;
  writeCloudResiduals(tmp / "cloud.vtp", c.cloud, r);
  writeSurfaceResiduals(tmp / "surface.vtp", c.s.x, c.s.triangles, r);

  const std::string cloud = viscera_test::slurp(tmp / "cloud.vtp");
  EXPECT_NE(cloud.find("NumberOfPoints=\"3\" NumberOfVerts=\"3\""), std::string::npos) << cloud;
  int comps = 0;
  EXPECT_EQ(readArray(cloud, "distance", comps), r.distance);
  EXPECT_EQ(comps, 1);
  const std::vector<double> residual = readArray(cloud, "residual", comps);
  EXPECT_EQ(comps, 3);
  EXPECT_EQ(residual, std::vector<double>(r.residual.data(), r.residual.data() + 9));
  EXPECT_EQ(readArray(cloud, "signedDistance", comps), r.signedDistance);
  EXPECT_EQ(readArray(cloud, "within", comps), (std::vector<double>{1, 1, 0}));

  const std::string surface = viscera_test::slurp(tmp / "surface.vtp");
  EXPECT_NE(surface.find("NumberOfPoints=\"3\""), std::string::npos);
  EXPECT_NE(surface.find("NumberOfPolys=\"1\""), std::string::npos);
  EXPECT_EQ(readArray(surface, "meanResidual", comps).size(), 9u);
  EXPECT_EQ(comps, 3);
  EXPECT_EQ(readArray(surface, "meanDistance", comps).size(), 3u);
  EXPECT_EQ(readArray(surface, "pointCount", comps), (std::vector<double>{2, 2, 1}));

  // The vertex method has no signed distance, and without a cut-off no `within`.
  const DistanceResult v = measure(c.s, c.cloud, method(DistanceMethod::Vertices));
  writeCloudResiduals(tmp / "vertices.vtp", c.cloud, v);
  const std::string plain = viscera_test::slurp(tmp / "vertices.vtp");
  EXPECT_EQ(plain.find("signedDistance"), std::string::npos);
  EXPECT_EQ(plain.find("within"), std::string::npos);
}

}  // namespace
