// Closed triangle surfaces (OBJ, STL, OFF, PLY) read and written through OpenMesh, with the checks
// meshing needs: closed, manifold, consistently oriented.
#pragma once

#include <Eigen/Core>
#include <string>

namespace viscera::io {

struct SurfaceMesh {
  Eigen::Matrix3Xd points;                          // 3 x #vertices
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangles;  // 3 x #triangles, 0-based
};

// Reads .obj, .stl (ASCII or binary), .off or .ply by extension; polygons are triangulated.
// Throws viscera::Error naming the file for unreadable files, unsupported extensions, empty
// surfaces and non-finite coordinates.
SurfaceMesh readSurface(const std::string& path);
// Writes by extension (.obj, .stl, .off, .ply), atomically.
void writeSurface(const std::string& path, const SurfaceMesh& surface);

// What is wrong with a surface, if anything.
struct SurfaceCheck {
  int boundaryEdges = 0;       // edges with one triangle (the surface is open)
  int nonManifoldEdges = 0;    // edges with more than two triangles
  int nonManifoldVertices = 0; // vertices whose triangles do not form one fan
  int misorientedEdges = 0;    // interior edges traversed the same way by both triangles
  int degenerateTriangles = 0; // zero area
  double volume = 0.0;         // enclosed volume (divergence theorem); < 0 if oriented inwards
  bool closed() const { return boundaryEdges == 0; }
  bool manifold() const { return nonManifoldEdges == 0 && nonManifoldVertices == 0; }
  bool oriented() const { return misorientedEdges == 0; }
  bool ok() const { return closed() && manifold() && oriented() && degenerateTriangles == 0; }
};
SurfaceCheck checkSurface(const SurfaceMesh& surface);
// Throws viscera::Error naming `source` and what is wrong (with counts and a first example edge or
// vertex) unless the surface is closed, manifold, consistently oriented and without degenerate
// triangles.
void requireClosedSurface(const SurfaceMesh& surface, const std::string& source);

}  // namespace viscera::io
