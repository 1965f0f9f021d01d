#include "engine/observation/SurfaceIndex.h"

#include <algorithm>
#include <map>
#include <numeric>

#include "engine/collision/Geometry.h"

namespace viscera::obs {

TriangleList boundaryTriangles(const TetList& tets, const Eigen::Matrix3Xd& x) {
  static const int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  std::map<std::array<int, 3>, std::pair<int, std::array<int, 3>>> faces;
  for (Eigen::Index e = 0; e < tets.cols(); ++e)
    for (int f = 0; f < 4; ++f) {
      std::array<int, 3> tri = {tets(kFace[f][0], e), tets(kFace[f][1], e), tets(kFace[f][2], e)};
      const int opp = tets(f, e);
      const Eigen::Vector3d n = (x.col(tri[1]) - x.col(tri[0])).cross(x.col(tri[2]) - x.col(tri[0]));
      if (n.dot(x.col(opp) - x.col(tri[0])) > 0) std::swap(tri[1], tri[2]);
      std::array<int, 3> key = tri;
      std::sort(key.begin(), key.end());
      auto [it, fresh] = faces.try_emplace(key, 1, tri);
      if (!fresh) ++it->second.first;
    }
  std::vector<std::array<int, 3>> kept;
  for (const auto& [key, v] : faces)
    if (v.first == 1) kept.push_back(v.second);
  TriangleList out(3, static_cast<Eigen::Index>(kept.size()));
  for (size_t t = 0; t < kept.size(); ++t)
    for (int k = 0; k < 3; ++k) out(k, static_cast<Eigen::Index>(t)) = kept[t][k];
  return out;
}

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
