// Surfaces through OpenMesh: every format written and read back, STL vertex welding, and the
// checks (closed, manifold, oriented, degenerate) on surfaces whose answers are known by
// construction: a 20 x 10 x 5 box (volume 1000, area 700) and an icosphere of radius 10.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <string>

#include "tests/support/ErrorOf.h"
#include "core/Error.h"
#include "io/surface/SurfaceMesh.h"
#include "tests/io/meshing/shapes.h"
#include "tests/support/TempDir.h"

using namespace viscera_test;
using viscera::Error;
using viscera::io::checkSurface;
using viscera::io::readSurface;
using viscera::io::requireClosedSurface;
using viscera::io::writeSurface;
using viscera::test_support::TempDir;

namespace {

constexpr double kPi = 3.14159265358979323846;

// The box of the tests: 20 x 10 x 5 in 8 x 4 x 2 cells of 2.5 (coordinates exact in float).
SurfaceMesh box(bool skipTop = false) { return gridBox(Eigen::Vector3d(20, 10, 5), {8, 4, 2}, skipTop); }

using viscera::test_support::errorOf;

void writeText(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

TEST(SurfaceCheck, BoxIsClosedWithExactVolumeAndArea) {
  const SurfaceMesh s = box();
  // 9 x 5 x 3 lattice points minus the 7 x 3 x 1 inside; two triangles per boundary square.
  EXPECT_EQ(s.points.cols(), 9 * 5 * 3 - 7 * 3 * 1);
  EXPECT_EQ(s.triangles.cols(), 2 * 2 * (8 * 4 + 4 * 2 + 8 * 2));
  const auto c = checkSurface(s);
  EXPECT_TRUE(c.ok());
  // Sums of a few hundred terms of size ~100: rounding stays below 1e-12 relative.
  EXPECT_NEAR(c.volume, 1000.0, 1e-12 * 1000.0);
  EXPECT_NEAR(c.area, 2 * (20 * 10 + 20 * 5 + 10 * 5), 1e-12 * 700.0);
  EXPECT_NO_THROW(requireClosedSurface(s, "box.off"));
}

TEST(SurfaceCheck, IcosphereIsInscribedInTheSphere) {
  const SurfaceMesh s = icosphere(3, 10.0);
  EXPECT_EQ(s.points.cols(), 10 * 64 + 2);
  EXPECT_EQ(s.triangles.cols(), 20 * 64);
  const auto c = checkSurface(s);
  EXPECT_TRUE(c.ok());
  // The polyhedron is the union of pyramids from the centre over its faces: volume = sum of
  // area * (distance of the face's plane from the centre) / 3, evaluated here independently of
  // checkSurface's divergence-theorem sum. Its faces lie between the spheres of radius
  // min(distance) and r, which bound the volume; the deficit of 1280 triangles is 0.86 %.
  double pyramids = 0, nearest = 10.0;
  for (Eigen::Index t = 0; t < s.triangles.cols(); ++t) {
    const Eigen::Vector3d a = s.points.col(s.triangles(0, t)), b = s.points.col(s.triangles(1, t)), c2 = s.points.col(s.triangles(2, t));
    const Eigen::Vector3d n = (b - a).cross(c2 - a);
    const double distance = n.normalized().dot(a);
    nearest = std::min(nearest, distance);
    pyramids += 0.5 * n.norm() * distance / 3.0;
  }
  EXPECT_NEAR(c.volume, pyramids, 1e-12 * pyramids);
  const double sphere = 4.0 / 3.0 * kPi * 1000.0;
  EXPECT_LT(c.volume, sphere);
  EXPECT_GT(c.volume, 4.0 / 3.0 * kPi * nearest * nearest * nearest);
  EXPECT_NEAR((sphere - c.volume) / sphere, 0.0086, 0.0001);
  EXPECT_LT(c.area, 4 * kPi * 100.0);
}

TEST(SurfaceCheck, FlippedSurfaceHasNegativeVolumeButPasses) {
  SurfaceMesh s = box();
  viscera::io::flipSurface(s);
  const auto c = checkSurface(s);
  EXPECT_TRUE(c.ok());
  EXPECT_NEAR(c.volume, -1000.0, 1e-9);
  EXPECT_NO_THROW(requireClosedSurface(s, "inward.off"));
}

TEST(SurfaceCheck, OpenBoxReportsItsRim) {
  const SurfaceMesh s = box(true);
  const auto c = checkSurface(s);
  // The missing top face (8 x 4 squares) leaves its rim: 2 * (8 + 4) edges with one triangle.
  EXPECT_EQ(c.boundaryEdges, 24);
  EXPECT_EQ(c.nonManifoldEdges, 0);
  EXPECT_EQ(c.misorientedEdges, 0);
  EXPECT_FALSE(c.closed());
  const std::string e = errorOf([&] { requireClosedSurface(s, "open.off"); });
  EXPECT_NE(e.find("open.off: "), std::string::npos) << e;
  EXPECT_NE(e.find("not closed: 24 edges belong to only one triangle"), std::string::npos) << e;
  // The example edge lies on the rim, z = 5.
  EXPECT_NE(e.find(", 5) and vertex "), std::string::npos) << e;
}

TEST(SurfaceCheck, CubesSharingAnEdgeAreNotManifold) {
  SurfaceMesh s = gridBox(Eigen::Vector3d(1, 1, 1), {1, 1, 1});
  appendCube(s, Eigen::Vector3d(1, 1, 0));  // touches the first along x = y = 1
  EXPECT_EQ(s.points.cols(), 14);
  const auto c = checkSurface(s);
  EXPECT_EQ(c.nonManifoldEdges, 1);
  EXPECT_EQ(c.nonManifoldEdgeExampleTriangles, 4);
  EXPECT_EQ(c.boundaryEdges, 0);
  const std::string e = errorOf([&] { requireClosedSurface(s, "two.off"); });
  EXPECT_NE(e.find("1 edge is shared by more than two triangles"), std::string::npos) << e;
  EXPECT_NE(e.find("(1, 1, 0)"), std::string::npos) << e;
  EXPECT_NE(e.find("(4 triangles)"), std::string::npos) << e;
}

TEST(SurfaceCheck, CubesSharingACornerHaveANonManifoldVertex) {
  SurfaceMesh s = gridBox(Eigen::Vector3d(1, 1, 1), {1, 1, 1});
  appendCube(s, Eigen::Vector3d(1, 1, 1));
  const auto c = checkSurface(s);
  EXPECT_EQ(c.nonManifoldVertices, 1);
  EXPECT_EQ(c.nonManifoldEdges, 0);
  EXPECT_EQ(c.boundaryEdges, 0);
  EXPECT_TRUE(s.points.col(c.nonManifoldVertexExample).isApprox(Eigen::Vector3d(1, 1, 1)));
  const std::string e = errorOf([&] { requireClosedSurface(s, "corner.off"); });
  EXPECT_NE(e.find("separate fans of triangles meet, e.g. vertex"), std::string::npos) << e;
}

TEST(SurfaceCheck, OneFlippedTriangleIsInconsistent) {
  SurfaceMesh s = box();
  std::swap(s.triangles(1, 5), s.triangles(2, 5));
  const auto c = checkSurface(s);
  EXPECT_EQ(c.misorientedEdges, 3);  // its three edges
  EXPECT_EQ(c.boundaryEdges, 0);
  const std::string e = errorOf([&] { requireClosedSurface(s, "flip.off"); });
  EXPECT_NE(e.find("not consistently oriented: 3 edges are traversed in the same direction"), std::string::npos) << e;
}

TEST(SurfaceCheck, ZeroAreaTriangleIsDegenerate) {
  SurfaceMesh s = box();
  s.triangles.conservativeResize(3, s.triangles.cols() + 1);
  s.triangles.col(s.triangles.cols() - 1) << 0, 0, 1;
  const auto c = checkSurface(s);
  EXPECT_EQ(c.degenerateTriangles, 1);
  EXPECT_EQ(c.degenerateTriangleExample, s.triangles.cols() - 1);
  EXPECT_EQ(c.boundaryEdges, 0);  // left out of the edge analysis
  const std::string e = errorOf([&] { requireClosedSurface(s, "zero.off"); });
  EXPECT_NE(e.find("1 triangle has zero area, e.g. triangle 224 (vertices 0, 0, 1)"), std::string::npos) << e;
}

TEST(SurfaceCheck, EmptySurfaceIsRejected) {
  EXPECT_NE(errorOf([] { requireClosedSurface(SurfaceMesh{}, "none.off"); }).find("none.off: the surface has no triangles"),
            std::string::npos);
}

struct FormatCase {
  const char* name;
  const char* extension;
  bool binary;
  bool keepsIndices;  // STL has no shared vertices: they are welded, in a different order
};

class SurfaceFormats : public testing::TestWithParam<FormatCase> {};

TEST_P(SurfaceFormats, BoxRoundTrips) {
  TempDir dir;
  const SurfaceMesh s = box();
  const std::string path = dir / (std::string("box") + GetParam().extension);
  writeSurface(path, s, GetParam().binary);
  const SurfaceMesh r = readSurface(path);
  ASSERT_EQ(r.points.cols(), s.points.cols());
  ASSERT_EQ(r.triangles.cols(), s.triangles.cols());
  // Multiples of 2.5 survive every format (and single precision) exactly.
  EXPECT_EQ(triangleSet(r.points, r.triangles), triangleSet(s.points, s.triangles));
  if (GetParam().keepsIndices) {
    EXPECT_EQ(r.points, s.points);
    EXPECT_EQ(r.triangles, s.triangles);
  }
  const auto c = checkSurface(r);
  EXPECT_TRUE(c.ok());
  EXPECT_NEAR(c.volume, 1000.0, 1e-9);
}

TEST_P(SurfaceFormats, SphereKeepsSinglePrecision) {
  TempDir dir;
  const SurfaceMesh s = icosphere(3, 10.0);
  const std::string path = dir / (std::string("sphere") + GetParam().extension);
  writeSurface(path, s, GetParam().binary);
  const SurfaceMesh r = readSurface(path);
  ASSERT_EQ(r.points.cols(), s.points.cols());
  ASSERT_EQ(r.triangles.cols(), s.triangles.cols());
  const auto c = checkSurface(r);
  EXPECT_TRUE(c.ok());
  // OpenMesh's readers parse single precision: coordinates of size 10 move by up to
  // 10 * 2^-24 = 6e-7 (ASCII STL keeps 10 digits, below that); the volume by ~1e-7 relative.
  EXPECT_NEAR(c.volume, checkSurface(s).volume, 1e-6 * 4000.0);
  if (GetParam().keepsIndices) {
    EXPECT_LT((r.points - s.points).cwiseAbs().maxCoeff(), 1e-6);
  }
}

INSTANTIATE_TEST_SUITE_P(All, SurfaceFormats,
                         testing::Values(FormatCase{"off", ".off", false, true}, FormatCase{"obj", ".obj", false, true},
                                         FormatCase{"ply", ".ply", false, true}, FormatCase{"ply_binary", ".ply", true, true},
                                         FormatCase{"stl", ".stl", false, false}, FormatCase{"stl_binary", ".stl", true, false}),
                         [](const testing::TestParamInfo<FormatCase>& i) { return std::string(i.param.name); });

// A tetrahedron as ASCII STL whose corner (1, 0, 0) is written as `x` in the first facet.
std::string tetraStl(const std::string& x) {
  auto facet = [](const std::string& a, const std::string& b, const std::string& c) {
    return "facet normal 0 0 0\n outer loop\n  vertex " + a + "\n  vertex " + b + "\n  vertex " + c + "\n endloop\nendfacet\n";
  };
  return "solid t\n" + facet("0 0 0", "0 1 0", x + " 0 0") + facet("0 0 0", "1 0 0", "0 0 1") + facet("0 0 0", "0 0 1", "0 1 0") +
         facet("1 0 0", "0 1 0", "0 0 1") + "endsolid t\n";
}

TEST(SurfaceRead, StlCornersWithinToleranceAreWelded) {
  TempDir dir;
  // 1.0000001 is a float other than 1 (1 + 2^-23), so only the tolerance (1e-6 of the diagonal
  // sqrt(3)) merges it with the other facets' corner.
  writeText(dir / "close.stl", tetraStl("1.0000001"));
  const SurfaceMesh s = readSurface(dir / "close.stl");
  EXPECT_EQ(s.points.cols(), 4);
  EXPECT_TRUE(checkSurface(s).ok());
  EXPECT_NEAR(checkSurface(s).volume, 1.0 / 6.0, 1e-6);
  // 1e-3 apart stays apart: each of the two corners has two edges with one triangle.
  writeText(dir / "far.stl", tetraStl("1.001"));
  const SurfaceMesh f = readSurface(dir / "far.stl");
  EXPECT_EQ(f.points.cols(), 5);
  EXPECT_EQ(checkSurface(f).boundaryEdges, 4);
}

TEST(SurfaceRead, NonManifoldTopologyIsKeptAsInTheFile) {
  // OpenMesh's half-edge mesh would give the offending triangles vertices of their own; the
  // surface read keeps the file's vertices so the check can see the shared edge.
  TempDir dir;
  SurfaceMesh s = gridBox(Eigen::Vector3d(1, 1, 1), {1, 1, 1});
  appendCube(s, Eigen::Vector3d(1, 1, 0));
  writeOff(dir / "two.off", s);
  const SurfaceMesh r = readSurface(dir / "two.off");
  EXPECT_EQ(r.points, s.points);
  EXPECT_EQ(r.triangles, s.triangles);
  EXPECT_EQ(checkSurface(r).nonManifoldEdges, 1);
  // OpenMesh cannot hold it, so it cannot be written through OpenMesh.
  const std::string e = errorOf([&] { writeSurface(dir / "copy.obj", s); });
  EXPECT_NE(e.find("copy.obj: cannot write surface: triangle"), std::string::npos) << e;
  EXPECT_FALSE(std::filesystem::exists(dir / "copy.obj"));
}

TEST(SurfaceRead, PolygonsAreTriangulated) {
  TempDir dir;
  // A unit cube of six quads.
  writeText(dir / "quads.obj",
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
            "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
  const SurfaceMesh s = readSurface(dir / "quads.obj");
  EXPECT_EQ(s.triangles.cols(), 12);
  const auto c = checkSurface(s);
  EXPECT_TRUE(c.ok());
  EXPECT_NEAR(c.volume, 1.0, 1e-12);
}

TEST(SurfaceRead, BadFilesNameTheFile) {
  TempDir dir;
  writeText(dir / "empty.off", "");
  EXPECT_NE(errorOf([&] { readSurface(dir / "empty.off"); }).find("empty.off: the surface file is empty"), std::string::npos);
  writeText(dir / "surface.xyz", "0 0 0\n");
  EXPECT_NE(errorOf([&] { readSurface(dir / "surface.xyz"); }).find("surface.xyz: cannot read surface: unsupported format '.xyz'"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { readSurface(dir / "missing.stl"); }).find("missing.stl: cannot open surface file"), std::string::npos);
  std::filesystem::create_directory(dir / "folder.off");
  EXPECT_NE(errorOf([&] { readSurface(dir / "folder.off"); }).find("folder.off: cannot read surface: it is a directory"),
            std::string::npos);
  writeText(dir / "garbage.off", "this is not a mesh\n");
  EXPECT_NE(errorOf([&] { readSurface(dir / "garbage.off"); }).find("garbage.off: OpenMesh cannot read it as off"), std::string::npos);
  writeText(dir / "points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  EXPECT_NE(errorOf([&] { readSurface(dir / "points.obj"); }).find("points.obj: no triangles in the file (3 vertices, no faces)"),
            std::string::npos);
  writeText(dir / "index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 7\n");
  EXPECT_NE(
      errorOf([&] { readSurface(dir / "index.obj"); }).find("index.obj: face 1 refers to vertex 6 (0-based), but the file has 4 vertices"),
      std::string::npos);
  EXPECT_NE(errorOf([&] { writeSurface(dir / "out.vtk", box()); }).find("out.vtk: cannot write surface: unsupported format '.vtk'"),
            std::string::npos);
}

}  // namespace
