#include "engine/collision/Geometry.h"

#include <algorithm>
#include <numeric>

namespace viscera::geom {

TriangleClosest closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {a, {1, 0, 0}, 4};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {b, {0, 1, 0}, 5};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {a + v * ab, {1 - v, v, 0}, 1};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {c, {0, 0, 1}, 6};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {a + w * ac, {1 - w, 0, w}, 3};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + w * (c - b), {0, 1 - w, w}, 2};
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {a + v * ab + w * ac, {1 - v - w, v, w}, 0};
}

void AabbTree::build(const std::vector<Box>& boxes) {
  nodes_.clear();
  prims_.resize(boxes.size());
  std::iota(prims_.begin(), prims_.end(), 0);
  if (boxes.empty()) return;
  std::vector<Eigen::Vector3d> centres(boxes.size());
  for (size_t i = 0; i < boxes.size(); ++i) centres[i] = boxes[i].center();
  nodes_.reserve(2 * boxes.size());
  buildRange(centres, 0, static_cast<int>(boxes.size()));
  refit(boxes);
}

int AabbTree::buildRange(std::vector<Eigen::Vector3d>& centres, int first, int count) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  if (count <= 4) {
    nodes_[id].first = first;
    nodes_[id].count = count;
    return id;
  }
  Box extent;
  for (int k = first; k < first + count; ++k) extent.extend(centres[prims_[k]]);
  int axis;
  extent.sizes().maxCoeff(&axis);
  const int mid = first + count / 2;
  std::nth_element(prims_.begin() + first, prims_.begin() + mid, prims_.begin() + first + count,
                   [&](int i, int j) { return centres[i][axis] < centres[j][axis]; });
  const int l = buildRange(centres, first, mid - first);
  const int r = buildRange(centres, mid, first + count - mid);
  nodes_[id].left = l;
  nodes_[id].right = r;
  return id;
}

void AabbTree::refit(const std::vector<Box>& boxes) {
  boxes_ = boxes;
  // Children are created after their parent, so a reverse sweep sees children first.
  for (int id = static_cast<int>(nodes_.size()) - 1; id >= 0; --id) {
    NodeData& n = nodes_[id];
    n.box.setEmpty();
    if (n.left < 0) {
      for (int k = n.first; k < n.first + n.count; ++k) n.box.extend(boxes[prims_[k]]);
    } else {
      n.box.extend(nodes_[n.left].box);
      n.box.extend(nodes_[n.right].box);
    }
  }
}

void AabbTree::query(const Box& q, const std::function<void(int)>& hit) const {
  if (nodes_.empty()) return;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const NodeData& n = nodes_[stack[--top]];
    if (!n.box.intersects(q)) continue;
    if (n.left < 0) {
      for (int k = n.first; k < n.first + n.count; ++k)
        if (boxes_[prims_[k]].intersects(q)) hit(prims_[k]);
    } else {
      stack[top++] = n.left;
      stack[top++] = n.right;
    }
  }
}

}  // namespace viscera::geom
