// Closed triangle surfaces (OBJ, STL, OFF, PLY) read and written through OpenMesh, with the checks
// meshing needs: closed, manifold, consistently oriented.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>

namespace viscera::io {

struct SurfaceMesh {
  Eigen::Matrix3Xd points;                          // 3 x #vertices
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangles;  // 3 x #triangles, 0-based
};

// Reads .obj, .stl (ASCII or binary), .off or .ply by extension; polygons are triangulated.
// Throws viscera::Error naming the file for unreadable files, unsupported extensions, empty
// surfaces and non-finite coordinates.
//
// The triangles are kept as the file indexes them, before OpenMesh builds its half-edge structure
// (which would split non-manifold or inconsistently oriented faces off), so checkSurface sees the
// file's own topology and vertex numbers. OpenMesh's readers parse coordinates in single
// precision (relative rounding ~6e-8). STL stores every triangle with its own corners: corners
// closer than 1e-6 of the bounding-box diagonal are merged into one vertex.
SurfaceMesh readSurface(const std::string& path);
// Writes by extension (.obj, .stl, .off, .ply), atomically. `binary` selects binary STL or PLY
// (OBJ and OFF are always text). OpenMesh stores a surface as a half-edge mesh, so only manifold,
// consistently oriented surfaces can be written; any other is an Error naming the first triangle
// that does not fit.
void writeSurface(const std::string& path, const SurfaceMesh& surface, bool binary = false);

// What is wrong with a surface, if anything.
struct SurfaceCheck {
  int boundaryEdges = 0;        // edges with one triangle (the surface is open)
  int nonManifoldEdges = 0;     // edges with more than two triangles
  int nonManifoldVertices = 0;  // vertices whose triangles do not form one fan
  int misorientedEdges = 0;     // interior edges traversed the same way by both triangles
  int degenerateTriangles = 0;  // zero area
  double volume = 0.0;          // enclosed volume (divergence theorem); < 0 if oriented inwards
  double area = 0.0;            // total triangle area
  // One example of each problem, for messages: 0-based vertex indices of an edge, a vertex or a
  // triangle index; -1 where there is none.
  std::array<int, 2> boundaryEdgeExample{-1, -1};
  std::array<int, 2> nonManifoldEdgeExample{-1, -1};
  int nonManifoldEdgeExampleTriangles = 0;  // how many triangles share that edge
  int nonManifoldVertexExample = -1;
  std::array<int, 2> misorientedEdgeExample{-1, -1};
  int degenerateTriangleExample = -1;
  bool closed() const { return boundaryEdges == 0; }
  bool manifold() const { return nonManifoldEdges == 0 && nonManifoldVertices == 0; }
  bool oriented() const { return misorientedEdges == 0; }
  bool ok() const { return closed() && manifold() && oriented() && degenerateTriangles == 0; }
};
// Triangles that repeat a vertex are counted as degenerate and left out of the edge analysis.
// A triangle is degenerate when twice its area is at most 1e-12 times its longest edge squared.
SurfaceCheck checkSurface(const SurfaceMesh& surface);
// Throws viscera::Error naming `source` and what is wrong (with counts and a first example edge or
// vertex) unless the surface is closed, manifold, consistently oriented and without degenerate
// triangles, or if it has no triangles. A surface oriented inwards throughout passes (see
// flipSurface).
void requireClosedSurface(const SurfaceMesh& surface, const std::string& source);

// Reverses the orientation of every triangle (turns an inward-oriented surface outwards).
void flipSurface(SurfaceMesh& surface);

}  // namespace viscera::io
