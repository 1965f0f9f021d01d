// Points embedded in tetrahedra: barycentric coordinates against hand-computed values, exact
// reproduction of affine deformations (points inside and outside the mesh), points out of reach,
// and the boundary surface of a split grid.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "engine/mapping/Embedding.h"
#include "engine/topology/GridSplit.h"

using namespace viscera;

namespace {

// The unit corner tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1).
struct UnitTet {
  Eigen::Matrix3Xd nodes;
  TetList tets;
  UnitTet() : nodes(3, 4), tets(4, 1) {
    nodes << 0, 1, 0, 0,  //
        0, 0, 1, 0,       //
        0, 0, 0, 1;
    tets << 0, 1, 2, 3;
  }
};

// A 4 x 3 x 3 node grid over [0,3] x [0,2] x [0,2] split into 72 tetrahedra (SOFA's split).
struct GridMesh {
  Eigen::Matrix3Xd nodes;
  TetList tets;
  GridMesh() {
    const std::array<int, 3> n{4, 3, 3};
    nodes = gridPoints(n, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(3, 2, 2));
    tets = splitHexahedra(gridHexahedra(n), 3, 2, true);
  }
};

// An affine map x -> A x + b with shear, stretch and rotation (det A > 0).
struct Affine {
  Eigen::Matrix3d A;
  Eigen::Vector3d b{0.7, -1.3, 2.1};
  Affine() {
    Eigen::Matrix3d S;
    S << 1.2, 0.3, -0.1,  //
        0.0, 0.8, 0.25,   //
        0.1, 0.0, 1.1;
    A = Eigen::AngleAxisd(0.6, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix() * S;
  }
  Eigen::Matrix3Xd operator()(const Eigen::Matrix3Xd& x) const { return (A * x).colwise() + b; }
};

TEST(Embedding, UnitTetrahedronWeightsAreTheCoordinates) {
  UnitTet m;
  Eigen::Matrix3Xd p(3, 1);
  p << 0.1, 0.2, 0.3;
  const TetEmbedding e = embedInTetrahedra(m.nodes, m.tets, p, 1.0);
  ASSERT_EQ(e.element[0], 0);
  EXPECT_EQ(e.distance[0], 0.0);
  // In the corner tetrahedron the coordinates of (x, y, z) are (1 - x - y - z, x, y, z); 1e-15
  // allows the round-off of the 3 x 3 inverse.
  const Eigen::Vector4d expected(0.4, 0.1, 0.2, 0.3);
  EXPECT_LT((e.weights.col(0) - expected).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(Embedding, OutsidePointIsExtrapolatedFromTheNearestTetrahedron) {
  UnitTet m;
  Eigen::Matrix3Xd p(3, 1);
  p << 1, 1, 1;
  const TetEmbedding e = embedInTetrahedra(m.nodes, m.tets, p, 2.0);
  ASSERT_EQ(e.element[0], 0);
  EXPECT_EQ(e.extrapolatedCount(), 1);
  // Unclamped coordinates of (1, 1, 1): (1 - 3, 1, 1, 1). Its nearest feature is the face
  // x + y + z = 1, at distance (3 - 1) / sqrt(3).
  EXPECT_LT((e.weights.col(0) - Eigen::Vector4d(-2, 1, 1, 1)).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_NEAR(e.distance[0], 2.0 / std::sqrt(3.0), 1e-14);
}

TEST(Embedding, PointOutOfReachIsUnplaced) {
  UnitTet m;
  Eigen::Matrix3Xd p(3, 2);
  p << 0.25, 0, 0.25, 0, 0.25, 10;  // (0.25, 0.25, 0.25) inside; (0, 0, 10) 9 above the apex
  const TetEmbedding e = embedInTetrahedra(m.nodes, m.tets, p, 0.5);
  EXPECT_EQ(e.element[0], 0);
  EXPECT_EQ(e.element[1], -1);
  EXPECT_TRUE(std::isinf(e.distance[1]));
  EXPECT_EQ(e.unplacedCount(), 1);
  EXPECT_EQ(e.extrapolatedCount(), 0);
  // The apex (0, 0, 1) is the nearest point of the tetrahedron.
  const auto [tet, d] = nearestTetrahedron(m.nodes, m.tets, p.col(1));
  EXPECT_EQ(tet, 0);
  EXPECT_NEAR(d, 9.0, 1e-14);
}

TEST(Embedding, InsideWeightsAreConvexAndReproduceThePoint) {
  GridMesh m;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(0.0, 3.0), uyz(0.0, 2.0);
  Eigen::Matrix3Xd p(3, 500);
  for (int i = 0; i < p.cols(); ++i) p.col(i) = Eigen::Vector3d(ux(rng), uyz(rng), uyz(rng));
  // The grid nodes themselves lie on faces and edges shared by several tetrahedra.
  Eigen::Matrix3Xd all(3, p.cols() + m.nodes.cols());
  all << p, m.nodes;
  const TetEmbedding e = embedInTetrahedra(m.nodes, m.tets, all, 0.5);
  ASSERT_EQ(e.unplacedCount(), 0);
  EXPECT_EQ(e.extrapolatedCount(), 0);
  Eigen::Matrix3Xd back;
  applyEmbedding(e, m.nodes, back);
  for (int i = 0; i < all.cols(); ++i) {
    // The coordinates come from a 3 x 3 inverse of edges of length <= 1.5: round-off stays below
    // 1e-14, far inside the 1e-12 allowed here for points on shared faces.
    EXPECT_NEAR(e.weights.col(i).sum(), 1.0, 1e-12) << i;
    EXPECT_GE(e.weights.col(i).minCoeff(), -1e-12) << i;
    EXPECT_LE(e.weights.col(i).maxCoeff(), 1.0 + 1e-12) << i;
    EXPECT_EQ(e.distance[i], 0.0) << i;
    EXPECT_LT((back.col(i) - all.col(i)).norm(), 1e-12) << i;
  }
}

TEST(Embedding, AffineDeformationIsReproducedInsideAndOutside) {
  GridMesh m;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ux(0.0, 3.0), uyz(0.0, 2.0), gap(0.01, 0.3);
  Eigen::Matrix3Xd p(3, 600);
  for (int i = 0; i < p.cols(); ++i) {
    Eigen::Vector3d q(ux(rng), uyz(rng), uyz(rng));
    // Half of the points pushed out through one of the six faces by up to 0.3 (a visual surface
    // slightly outside the mesh).
    if (i % 2) {
      const int face = (i / 2) % 6, axis = face / 2;
      const double hi[3] = {3, 2, 2};
      q[axis] = face % 2 ? hi[axis] + gap(rng) : -gap(rng);
    }
    p.col(i) = q;
  }
  const TetEmbedding e = embedInTetrahedra(m.nodes, m.tets, p, 0.5);
  ASSERT_EQ(e.unplacedCount(), 0);
  EXPECT_EQ(e.extrapolatedCount(), 300);
  EXPECT_GT(e.distance.maxCoeff(), 0.2);
  EXPECT_LE(e.distance.maxCoeff(), 0.3);

  const Affine f;
  Eigen::Matrix3Xd mapped;
  applyEmbedding(e, f(m.nodes), mapped);
  // Barycentric coordinates (unclamped outside) reproduce affine functions exactly; what is left
  // is round-off on coordinates of size ~5: below 1e-13 in practice, checked at 1e-12.
  const double err = (mapped - f(p)).colwise().norm().maxCoeff();
  EXPECT_LT(err, 1e-12);
}

TEST(Embedding, BoundaryOfASplitGridIsClosedAndOutward) {
  GridMesh m;
  const TriangleList t = boundaryTriangles(m.tets, m.nodes);
  // 3 x 2 x 2 cells: 2 (3*2 + 3*2 + 2*2) = 32 boundary squares, two triangles each.
  ASSERT_EQ(t.cols(), 64);
  // Divergence theorem: the sum over outward triangles of (area normal . centroid) is 3 x volume
  // (3 * 12); inward or missing triangles would change it. Exact up to round-off.
  double flux = 0;
  for (int k = 0; k < t.cols(); ++k) {
    const Eigen::Vector3d a = m.nodes.col(t(0, k)), b = m.nodes.col(t(1, k)), c = m.nodes.col(t(2, k));
    flux += 0.5 * (b - a).cross(c - a).dot((a + b + c) / 3.0);
  }
  EXPECT_NEAR(flux, 36.0, 1e-12);
}

TEST(Embedding, MeanEdgeLengthOfTheUnitTetrahedron) {
  UnitTet m;
  // Three unit edges and three face diagonals of length sqrt(2).
  EXPECT_NEAR(meanEdgeLength(m.nodes, m.tets), (3.0 + 3.0 * std::sqrt(2.0)) / 6.0, 1e-15);
}

}  // namespace
