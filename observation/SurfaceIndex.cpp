#include "observation/SurfaceIndex.h"

#include <algorithm>

#include "engine/collision/Geometry.h"

namespace viscera::obs {

void SurfaceIndex::build(const Eigen::Matrix3Xd& points, const TriangleList& triangles) {
  points_ = points;
  tris_ = triangles;
  tree_.build(boxes());
}

std::vector<geom::AabbTree::Box> SurfaceIndex::boxes() const {
  std::vector<geom::AabbTree::Box> b(static_cast<size_t>(tris_.cols()));
  for (Eigen::Index t = 0; t < tris_.cols(); ++t)
    for (int k = 0; k < 3; ++k) b[static_cast<size_t>(t)].extend(points_.col(tris_(k, t)));
  return b;
}

void SurfaceIndex::update(const Eigen::Matrix3Xd& points) {
  points_ = points;
  tree_.refit(boxes());
}

Eigen::Vector3d SurfaceIndex::normal(int t) const {
  const Eigen::Vector3d a = points_.col(tris_(0, t));
  const Eigen::Vector3d n = (points_.col(tris_(1, t)) - a).cross(points_.col(tris_(2, t)) - a);
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}


SurfaceIndex::Hit SurfaceIndex::closest(const Eigen::Vector3d& p, double maxDistance2, int hint) const {
  Hit best;
  best.distance2 = maxDistance2;
  auto test = [&](int t) {
    const geom::TriangleClosest c =
        geom::closestOnTriangle(p, points_.col(tris_(0, t)), points_.col(tris_(1, t)), points_.col(tris_(2, t)));
    const double d2 = (c.point - p).squaredNorm();
    if (d2 < best.distance2 || (d2 == best.distance2 && best.triangle >= 0 && t < best.triangle)) {
      best.distance2 = d2;
      best.point = c.point;
      best.triangle = t;
      best.w = c.w;
      best.region = c.region;
    }
  };
  if (tris_.cols() == 0) return best;
  if (hint >= 0 && hint < tris_.cols()) test(hint);
  tree_.nearest(p, best.distance2, test);
  if (best.triangle < 0) best.distance2 = std::numeric_limits<double>::infinity();
  return best;
}

}  // namespace viscera::obs
