// Small geometric kernels for contact and observation: closest point on a triangle and the one
// axis-aligned bounding volume hierarchy (refitted every step; queried with a box, or nearest first).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <functional>
#include <vector>

namespace viscera::geom {

// Closest point of a triangle (a, b, c) to p (Ericson, Real-Time Collision Detection, 5.1.5).
// `region`: 0 interior, 1 edge ab, 2 edge bc, 3 edge ca, 4 vertex a, 5 vertex b, 6 vertex c.
struct TriangleClosest {
  Eigen::Vector3d point;
  std::array<double, 3> w;  // barycentric weights of a, b, c
  int region = 0;
};
TriangleClosest closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  const Eigen::Vector3d& c);

// A bounding volume hierarchy over primitives whose boxes change every step but whose number does
// not: built once (median splits), refitted in O(n), queried with a box.
class AabbTree {
 public:
  using Box = Eigen::AlignedBox3d;
  // Builds over `boxes` (one per primitive).
  void build(const std::vector<Box>& boxes);
  // Recomputes every node's box from new primitive boxes (same order as at build).
  void refit(const std::vector<Box>& boxes);
  // Calls `hit(i)` for each primitive whose box intersects `query`.
  void query(const Box& query, const std::function<void(int)>& hit) const;
  // Nearest first from p: calls `test(i)` for the primitives in leaves whose boxes lie within
  // sqrt(bound2) of p, nearer subtrees first. `test` may lower bound2 (it found something closer),
  // which prunes the rest; bound2 is read, never written, here.
  template <class Test>
  void nearest(const Eigen::Vector3d& p, const double& bound2, Test&& test) const {
    if (nodes_.empty()) return;
    auto dist2 = [&](const Box& b) { return (b.min() - p).cwiseMax(p - b.max()).cwiseMax(0.0).squaredNorm(); };
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const NodeData& n = nodes_[stack[--top]];
      if (dist2(n.box) > bound2) continue;
      if (n.left < 0) {
        for (int k = n.first; k < n.first + n.count; ++k) test(prims_[k]);
        continue;
      }
      const double dl = dist2(nodes_[n.left].box), dr = dist2(nodes_[n.right].box);
      // The nearer child last, so that it is searched first.
      if (dl < dr) {
        if (dr <= bound2) stack[top++] = n.right;
        if (dl <= bound2) stack[top++] = n.left;
      } else {
        if (dl <= bound2) stack[top++] = n.left;
        if (dr <= bound2) stack[top++] = n.right;
      }
    }
  }
  int size() const { return static_cast<int>(prims_.size()); }

 private:
  struct NodeData {
    Box box;
    int left = -1, right = -1;  // children, -1 for a leaf
    int first = 0, count = 0;   // leaf: range in prims_
  };
  int buildRange(std::vector<Eigen::Vector3d>& centres, int first, int count);
  std::vector<NodeData> nodes_;
  std::vector<int> prims_;
  std::vector<Box> boxes_;  // primitive boxes of the last build or refit (leaves test each one)
};

}  // namespace viscera::geom
