// Small geometric kernels for contact: closest point on a triangle and an axis-aligned bounding
// volume hierarchy refitted every step.
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
