// Super-sampling of triangle surfaces: counts, shared points, weights, and the gel phantom's grid.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <vector>

#include "observation/SurfaceSampling.h"
#include "engine/topology/GridSplit.h"

namespace {

using viscera::obs::superSample;
using viscera::obs::TriangleList;

TEST(SurfaceSampling, OneTriangle) {
  TriangleList tri(3, 1);
  tri << 0, 1, 2;
  Eigen::Matrix3Xd x(3, 3);
  x << 0, 3, 0,  //
      0, 0, 3,   //
      0, 0, 0;
  for (int factor : {1, 2, 3, 5}) {
    const auto s = superSample(tri, 3, factor);
    // (f + 1)(f + 2) / 2 lattice points.
    EXPECT_EQ(s.numSamples(), (factor + 1) * (factor + 2) / 2) << "factor " << factor;
    // The samples of a right triangle with legs 3 are the points (3i/f, 3j/f), i + j <= f; the
    // weights are multiples of 1/f, so each coordinate is within rounding of that lattice.
    const Eigen::Matrix3Xd p = s.sample(x);
    std::vector<std::array<int, 2>> lattice;
    for (Eigen::Index k = 0; k < p.cols(); ++k) {
      const double i = p(0, k) * factor / 3, j = p(1, k) * factor / 3;
      EXPECT_NEAR(i, std::round(i), 1e-12);
      EXPECT_NEAR(j, std::round(j), 1e-12);
      EXPECT_EQ(p(2, k), 0.0);
      lattice.push_back({static_cast<int>(std::lround(i)), static_cast<int>(std::lround(j))});
    }
    std::sort(lattice.begin(), lattice.end());
    EXPECT_TRUE(std::adjacent_find(lattice.begin(), lattice.end()) == lattice.end()) << "a lattice point twice";
    for (const auto& [i, j] : lattice) EXPECT_LE(i + j, factor);
  }
}

TEST(SurfaceSampling, SharedEdgesAndVerticesOnce) {
  // Triangles (0, 1, 2) and (2, 1, 3) share the edge 1-2; (2, 4, 5) shares vertex 2 only; vertex 6
  // is unused. Factor 3: one sample per used vertex (6), two inside each distinct edge (8 edges),
  // one inside each triangle (3).
  TriangleList tris(3, 3);
  tris << 0, 2, 2,  //
      1, 1, 4,      //
      2, 3, 5;
  const auto s = superSample(tris, 7, 3);
  EXPECT_EQ(s.numSamples(), 6 + 8 * 2 + 3);
  EXPECT_EQ(s.numVertices(), 7);
  // Every row sums to 1 and has 1 to 3 non-zeros; the first six rows are the used vertices, in order.
  for (int r = 0; r < s.numSamples(); ++r) {
    double sum = 0;
    int nnz = 0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(s.weights, r); it; ++it) sum += it.value(), ++nnz;
    EXPECT_NEAR(sum, 1.0, 1e-15) << "row " << r;
    EXPECT_GE(nnz, 1);
    EXPECT_LE(nnz, 3);
  }
  for (int v = 0; v < 6; ++v) EXPECT_EQ(s.weights.coeff(v, v), 1.0);
  for (int r = 0; r < s.numSamples(); ++r) EXPECT_EQ(s.weights.coeff(r, 6), 0.0) << "row " << r;
  // Edge points run from the lower vertex: the first edge (0, 1) gives 2/3 x0 + 1/3 x1, then
  // 1/3 x0 + 2/3 x1.
  EXPECT_NEAR(s.weights.coeff(6, 0), 2.0 / 3, 1e-15);
  EXPECT_NEAR(s.weights.coeff(6, 1), 1.0 / 3, 1e-15);
  EXPECT_NEAR(s.weights.coeff(7, 0), 1.0 / 3, 1e-15);
  // The last three rows are the triangles' centroids.
  for (int t = 0; t < 3; ++t)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.weights.coeff(22 + t, tris(k, t)), 1.0 / 3, 1e-15);
}

TEST(SurfaceSampling, RejectsBadInput) {
  TriangleList tri(3, 1);
  tri << 0, 1, 3;
  EXPECT_THROW(superSample(tri, 3, 3), std::invalid_argument);  // vertex 3 of 3
  tri << 0, 1, 2;
  EXPECT_THROW(superSample(tri, 3, 0), std::invalid_argument);
  const auto s = superSample(tri, 3, 2);
  EXPECT_THROW(s.sample(Eigen::Matrix3Xd::Zero(3, 4)), std::invalid_argument);
}

TEST(SurfaceSampling, PhantomGridTimesThreeIsTheFinerGridsSurface) {
  // The gel phantom: a 25 x 9 x 9 grid split into tetrahedra. Each boundary quad is two triangles;
  // factor 3 puts points at the thirds of every edge (the quad's sides and its diagonal) and at
  // the two triangles' centroids, which together are the 4 x 4 nodes of the quad refined three
  // times. So the samples must be the surface nodes of the 73 x 25 x 25 grid over the same box,
  // each once.
  const Eigen::Vector3d lo(0, 0, 0), hi(68.7, 35.8, 39.3);
  const Eigen::Matrix3Xd x = viscera::gridPoints({25, 9, 9}, lo, hi);
  const viscera::TetList tets = viscera::splitHexahedra(viscera::gridHexahedra({25, 9, 9}), 24, 8, true);
  const TriangleList surface = viscera::obs::boundaryTriangles(tets, x);
  ASSERT_EQ(surface.cols(), 2 * 2 * (24 * 8 + 24 * 8 + 8 * 8));
  const auto s = superSample(surface, static_cast<int>(x.cols()), 3);
  const Eigen::Matrix3Xd p = s.sample(x);
  const int fineSurface = 73 * 25 * 25 - 71 * 23 * 23;
  ASSERT_EQ(s.numSamples(), fineSurface);

  // Each sample's fine-grid index (i, j, k) = position / fine spacing must be an integer on the box
  // surface; rounding in the interpolation stays far below 1e-9 of a spacing.
  const Eigen::Vector3d spacing = (hi - lo).cwiseQuotient(Eigen::Vector3d(72, 24, 24));
  std::map<std::array<int, 3>, int> seen;
  for (Eigen::Index c = 0; c < p.cols(); ++c) {
    std::array<int, 3> ijk;
    for (int k = 0; k < 3; ++k) {
      const double f = (p(k, c) - lo[k]) / spacing[k];
      ASSERT_NEAR(f, std::round(f), 1e-9) << "sample " << c << " axis " << k;
      ijk[static_cast<size_t>(k)] = static_cast<int>(std::lround(f));
    }
    const bool onSurface = ijk[0] == 0 || ijk[0] == 72 || ijk[1] == 0 || ijk[1] == 24 || ijk[2] == 0 || ijk[2] == 24;
    EXPECT_TRUE(onSurface) << "sample " << c << " is inside the block";
    ++seen[ijk];
  }
  EXPECT_EQ(static_cast<int>(seen.size()), fineSurface);  // all distinct, so every surface node once
}

}  // namespace
