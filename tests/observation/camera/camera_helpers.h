// Shared pieces of the depth-camera tests: the gel phantom's surface, a rectangle surface, and
// analytic ray intersections with boxes and spheres to check the renderer against.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "observation/DepthCamera.h"
#include "observation/SurfaceIndex.h"
#include "engine/topology/GridSplit.h"

namespace camera_test {

using viscera::obs::TriangleList;

// A block of the gel phantom's size (68.7 x 35.8 x 39.3 mm, its two shorter sides in the other order
// than scenes/gel_phantom.xml) at the origin on a grid of n nodes, split into tetrahedra; its
// boundary triangles, outward.
struct Phantom {
  Eigen::Vector3d lo{0, 0, 0}, hi{68.7, 35.8, 39.3};
  Eigen::Matrix3Xd points;  // 3 x #nodes
  TriangleList triangles;   // 3 x #boundary triangles
  explicit Phantom(std::array<int, 3> n = {25, 9, 9}) {
    points = viscera::gridPoints(n, lo, hi);
    const viscera::TetList tets = viscera::splitHexahedra(viscera::gridHexahedra(n), n[0] - 1, n[1] - 1, true);
    triangles = viscera::obs::boundaryTriangles(tets, points);
  }
  Eigen::Vector3d centre() const { return 0.5 * (lo + hi); }
};

// A rectangle in the plane z = height: [x0, x1] x [y0, y1] as two triangles, counter-clockwise seen
// from +z (or clockwise when `flip`).
struct Rectangle {
  Eigen::Matrix3Xd points;
  TriangleList triangles;
  Rectangle(double x0, double x1, double y0, double y1, double height, bool flip = false) {
    points.resize(3, 4);
    points << x0, x1, x1, x0,  //
        y0, y0, y1, y1,        //
        height, height, height, height;
    triangles.resize(3, 2);
    triangles << 0, 0,  //
        1, 2,           //
        2, 3;
    if (flip) triangles.row(1).swap(triangles.row(2));
  }
};

// The entry and exit parameters of the line o + t d through the box [lo, hi] (slab method);
// nothing when the line misses it.
inline std::optional<std::pair<double, double>> boxInterval(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                                            const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  double t0 = -std::numeric_limits<double>::infinity(), t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return std::nullopt;
      continue;
    }
    double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (t0 > t1) return std::nullopt;
  return std::make_pair(t0, t1);
}

// Distance from the centre c to the line o + t d, and the parameter of the line's nearer crossing
// of the sphere |x - c| = r (when it crosses): geometry of the right triangle formed by the centre,
// its foot on the line and the crossing.
struct SphereCrossing {
  double distance = 0;                    // centre to line
  std::optional<double> t;                // the first crossing with t > 0
};
inline SphereCrossing sphereCrossing(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& c,
                                     double r) {
  const Eigen::Vector3d u = d.normalized();
  const double along = (c - o).dot(u);                  // foot of the perpendicular, as a length along u
  const Eigen::Vector3d foot = o + along * u;
  SphereCrossing s;
  s.distance = (c - foot).norm();
  if (s.distance <= r) {
    const double half = std::sqrt(r * r - s.distance * s.distance);  // half chord
    const double first = along - half > 0 ? along - half : along + half;
    if (first > 0) s.t = first / d.norm();
  }
  return s;
}

}  // namespace camera_test
