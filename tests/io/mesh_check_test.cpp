// checkTetMesh: index range, degenerate and inverted tetrahedra, orientation sign.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "core/Error.h"
#include "io/mesh/Mesh.h"

using viscera::io::VolumeMesh;

namespace {

// Two unit-corner tetrahedra sharing the face (1, 2, 3), both with positive volume.
VolumeMesh twoTets() {
  VolumeMesh m;
  m.points.resize(3, 5);
  m.points << 0, 1, 0, 0, 1,  //
      0, 0, 1, 0, 1,          //
      0, 0, 0, 1, 1;
  m.tets.resize(4, 2);
  m.tets << 0, 1,  //
      1, 2,        //
      2, 3,        //
      3, 4;
  return m;
}

std::string errorOf(const VolumeMesh& m, const std::string& source = "liver.msh") {
  try {
    viscera::io::checkTetMesh(m, source);
  } catch (const viscera::Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "checkTetMesh did not throw";
  return {};
}

#define EXPECT_CONTAINS(text, part) EXPECT_NE(std::string(text).find(part), std::string::npos) << "message: " << (text)

TEST(MeshCheck, ConsistentMeshesGiveTheirSign) {
  VolumeMesh m = twoTets();
  EXPECT_EQ(viscera::io::checkTetMesh(m, "liver.msh"), 1);
  m.tets.row(0).swap(m.tets.row(1));  // flips every tetrahedron
  EXPECT_EQ(viscera::io::checkTetMesh(m, "liver.msh"), -1);
}

TEST(MeshCheck, ToleranceIsRelativeToTheTetSize) {
  VolumeMesh m = twoTets();
  m.points *= 1e-5;  // a 10 micrometre mesh in metres is fine
  EXPECT_EQ(viscera::io::checkTetMesh(m, "small.msh"), 1);
  m.points *= 1e10;
  EXPECT_EQ(viscera::io::checkTetMesh(m, "large.msh"), 1);
}

TEST(MeshCheck, DegenerateTetIsNamed) {
  VolumeMesh m = twoTets();
  // Node 4 a hair off the face (1, 2, 3): tetrahedron 1 is flat.
  m.points.col(4) = (m.points.col(1) + m.points.col(2) + m.points.col(3)) / 3.0;
  m.points(0, 4) += 1e-14;
  const std::string msg = errorOf(m);
  EXPECT_CONTAINS(msg, "liver.msh: tetrahedron 1 is degenerate");

  VolumeMesh repeated = twoTets();
  repeated.tets(3, 0) = 1;  // a node used twice
  EXPECT_CONTAINS(errorOf(repeated), "tetrahedron 0 is degenerate");
}

TEST(MeshCheck, InvertedTetIsNamed) {
  VolumeMesh m = twoTets();
  m.tets.conservativeResize(4, 3);
  m.tets.col(2) = m.tets.col(0);
  std::swap(m.tets(0, 1), m.tets(1, 1));  // tet 1 now negative, 0 and 2 positive
  EXPECT_CONTAINS(errorOf(m), "liver.msh: tetrahedron 1 is inverted (negative volume) while others are positive");

  m.tets.row(0).swap(m.tets.row(1));  // now tets 0 and 2 negative, 1 positive
  EXPECT_CONTAINS(errorOf(m), "tetrahedron 1 is inverted (positive volume) while others are negative");
}

TEST(MeshCheck, IndicesEmptinessAndCoordinates) {
  VolumeMesh m = twoTets();
  m.tets(2, 1) = 5;
  EXPECT_CONTAINS(errorOf(m), "liver.msh: tetrahedron 1 refers to node 5, but the mesh has 5 nodes");
  m = twoTets();
  m.tets(0, 0) = -1;
  EXPECT_CONTAINS(errorOf(m), "tetrahedron 0 refers to node -1");
  m = twoTets();
  m.triangles.resize(3, 1);
  m.triangles << 0, 1, 7;
  EXPECT_CONTAINS(errorOf(m), "triangle 0 refers to node 7");
  m = twoTets();
  m.points(1, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_CONTAINS(errorOf(m), "node 3 has a coordinate that is not finite");
  m = twoTets();
  m.tets.resize(4, 0);
  EXPECT_CONTAINS(errorOf(m, "empty.vtk"), "empty.vtk: no tetrahedra");
}

}  // namespace
