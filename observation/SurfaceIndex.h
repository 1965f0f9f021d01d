// Exact closest points on a triangle surface: the bounding-volume hierarchy of contact
// (geom::AabbTree) over the triangles, built once and refitted when the surface deforms. Used by the cloud -> surface distance, ICP
// registration and anything else that asks "where on the tissue surface is this point nearest?".
#pragma once

#include <Eigen/Core>
#include <array>
#include <limits>
#include <vector>

#include "engine/Roles.h"
#include "engine/collision/Geometry.h"
#include "io/mesh/Mesh.h"

namespace viscera::obs {

using TriangleList = Eigen::Matrix<int, 3, Eigen::Dynamic>;  // 3 x #triangles

// The outward boundary faces of tetrahedra (io/mesh/Mesh.h).
using io::boundaryTriangles;

class SurfaceIndex {
 public:
  struct Hit {
    Eigen::Vector3d point = Eigen::Vector3d::Zero();  // closest point on the surface
    int triangle = -1;                                // -1 when nothing lies within the search radius
    std::array<double, 3> w{0, 0, 0};                 // barycentric weights on that triangle
    int region = 0;                                   // as closestOnTriangle: 0 face, 1-3 edge, 4-6 vertex
    double distance2 = std::numeric_limits<double>::infinity();
  };

  SurfaceIndex() = default;
  SurfaceIndex(const Eigen::Matrix3Xd& points, const TriangleList& triangles) { build(points, triangles); }
  // Builds the hierarchy over the triangles' boxes.
  void build(const Eigen::Matrix3Xd& points, const TriangleList& triangles);
  // New positions for the same points and triangles: refits the boxes in O(n).
  void update(const Eigen::Matrix3Xd& points);

  // The closest surface point to p among points closer than sqrt(maxDistance2). `hint`, a
  // triangle likely to be close (the previous query's, for coherent queries), tightens the
  // search from the start; it never changes the answer.
  Hit closest(const Eigen::Vector3d& p, double maxDistance2 = std::numeric_limits<double>::infinity(), int hint = -1) const;

  const Eigen::Matrix3Xd& points() const { return points_; }
  const TriangleList& triangles() const { return tris_; }
  int numTriangles() const { return static_cast<int>(tris_.cols()); }
  // Unit normal of triangle t at the current positions (zero for a degenerate triangle).
  Eigen::Vector3d normal(int t) const;

 private:
  std::vector<geom::AabbTree::Box> boxes() const;  // one per triangle at the current positions
  Eigen::Matrix3Xd points_;
  TriangleList tris_;
  geom::AabbTree tree_;
};

}  // namespace viscera::obs
