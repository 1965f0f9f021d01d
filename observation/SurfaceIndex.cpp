#include "observation/SurfaceIndex.h"

#include <algorithm>
#include <numeric>

#include "engine/collision/Geometry.h"

namespace viscera::obs {

void SurfaceIndex::build(const Eigen::Matrix3Xd& points, const TriangleList& triangles) {
  points_ = points;
  tris_ = triangles;
  nodes_.clear();
  order_.resize(static_cast<size_t>(tris_.cols()));
  std::iota(order_.begin(), order_.end(), 0);
  std::vector<Eigen::Vector3d> centres(order_.size());
  for (Eigen::Index t = 0; t < tris_.cols(); ++t)
    centres[static_cast<size_t>(t)] = (points_.col(tris_(0, t)) + points_.col(tris_(1, t)) + points_.col(tris_(2, t))) / 3.0;
  if (!order_.empty()) {
    nodes_.reserve(2 * order_.size());
    buildRange(centres, 0, static_cast<int>(order_.size()));
    refitNode(0);
  }
}

int SurfaceIndex::buildRange(std::vector<Eigen::Vector3d>& centres, int first, int count) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  if (count <= 4) {
    nodes_[id].first = first;
    nodes_[id].count = count;
    return id;
  }
  Eigen::Vector3d lo = centres[order_[first]], hi = lo;
  for (int i = first; i < first + count; ++i) {
    lo = lo.cwiseMin(centres[order_[i]]);
    hi = hi.cwiseMax(centres[order_[i]]);
  }
  int axis;
  (hi - lo).maxCoeff(&axis);
  const int half = count / 2;
  std::nth_element(order_.begin() + first, order_.begin() + first + half, order_.begin() + first + count,
                   [&](int a, int b) { return centres[a][axis] < centres[b][axis]; });
  const int l = buildRange(centres, first, half);
  const int r = buildRange(centres, first + half, count - half);
  nodes_[id].left = l;
  nodes_[id].right = r;
  return id;
}

void SurfaceIndex::refitNode(int n) {
  NodeData& node = nodes_[n];
  if (node.left < 0) {
    node.lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    node.hi = -node.lo;
    for (int i = node.first; i < node.first + node.count; ++i)
      for (int k = 0; k < 3; ++k) {
        node.lo = node.lo.cwiseMin(points_.col(tris_(k, order_[i])));
        node.hi = node.hi.cwiseMax(points_.col(tris_(k, order_[i])));
      }
    return;
  }
  refitNode(node.left);
  refitNode(node.right);
  node.lo = nodes_[node.left].lo.cwiseMin(nodes_[node.right].lo);
  node.hi = nodes_[node.left].hi.cwiseMax(nodes_[node.right].hi);
}

void SurfaceIndex::update(const Eigen::Matrix3Xd& points) {
  points_ = points;
  if (!nodes_.empty()) refitNode(0);
}

Eigen::Vector3d SurfaceIndex::normal(int t) const {
  const Eigen::Vector3d a = points_.col(tris_(0, t));
  const Eigen::Vector3d n = (points_.col(tris_(1, t)) - a).cross(points_.col(tris_(2, t)) - a);
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

namespace {
double boxDistance2(const Eigen::Vector3d& p, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).squaredNorm();
}
}  // namespace

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
  if (nodes_.empty()) return best;
  if (hint >= 0 && hint < tris_.cols()) test(hint);
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const NodeData& node = nodes_[stack[--top]];
    if (boxDistance2(p, node.lo, node.hi) > best.distance2) continue;
    if (node.left < 0) {
      for (int i = node.first; i < node.first + node.count; ++i) test(order_[i]);
      continue;
    }
    const double dl = boxDistance2(p, nodes_[node.left].lo, nodes_[node.left].hi);
    const double dr = boxDistance2(p, nodes_[node.right].lo, nodes_[node.right].hi);
    // Nearer child last, so it is popped first.
    if (dl < dr) {
      if (dr <= best.distance2) stack[top++] = node.right;
      if (dl <= best.distance2) stack[top++] = node.left;
    } else {
      if (dl <= best.distance2) stack[top++] = node.left;
      if (dr <= best.distance2) stack[top++] = node.right;
    }
  }
  if (best.triangle < 0) best.distance2 = std::numeric_limits<double>::infinity();
  return best;
}

}  // namespace viscera::obs
