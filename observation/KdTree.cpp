#include "observation/KdTree.h"

#include <algorithm>
#include <limits>

namespace viscera::obs {

// The query point and the best candidate so far.
struct KdTree::Search {
  double q[3];
  double best2;
  int best;
};

void KdTree::build(const Eigen::Matrix3Xd& points) {
  const int n = static_cast<int>(points.cols());
  size_ = n;
  nodes_.clear();
  // The points move with their coordinates while the tree is built, so the median searches compare
  // values in hand instead of looking them up through an index.
  std::vector<Point> work(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) work[static_cast<size_t>(i)] = {{points(0, i), points(1, i), points(2, i)}, i};
  if (n > 0) {
    for (int k = 0; k < 3; ++k) {
      lo_[k] = points.row(k).minCoeff();
      hi_[k] = points.row(k).maxCoeff();
    }
    nodes_.reserve(static_cast<size_t>(2 * (n / kBucket) + 1));
    buildRange(work.data(), 0, n, lo_, hi_);
  }
  const size_t slots = static_cast<size_t>((n + kBucket - 1) / kBucket * kBucket);
  x_.resize(slots);
  y_.resize(slots);
  z_.resize(slots);
  index_.resize(slots);
  position_.resize(static_cast<size_t>(n));
  for (size_t i = 0; i < work.size(); ++i) {
    x_[i] = work[i].c[0];
    y_[i] = work[i].c[1];
    z_[i] = work[i].c[2];
    index_[i] = work[i].index;
    position_[static_cast<size_t>(work[i].index)] = static_cast<int>(i);
  }
  // Padding of the last leaf: copies of its first point with an index larger than every real one.
  // A copy is exactly as far from any query as that point, which is scanned first, so it never
  // wins: not a tie (the larger index), not a strict improvement.
  for (size_t i = work.size(); i < slots; ++i) {
    const size_t lastLeaf = slots - kBucket;
    x_[i] = x_[lastLeaf];
    y_[i] = y_[lastLeaf];
    z_[i] = z_[lastLeaf];
    index_[i] = std::numeric_limits<int>::max();
  }
}

int KdTree::buildRange(Point* points, int first, int count, const double lo[3], const double hi[3]) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  if (count <= kBucket) {
    nodes_[static_cast<size_t>(id)].first = first;
    return id;
  }
  Point* begin = points + first;
  Point* end = begin + count;
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
  // The split nearest the median that keeps the left part a whole number of leaves.
  const int half = kBucket * ((count / kBucket + 1) / 2);
  std::nth_element(begin, begin + half, end, [axis](const Point& a, const Point& b) { return a.c[axis] < b.c[axis]; });
  const double split = begin[half].c[axis];
  // The children's cells: this one cut at the split.
  double lhi[3] = {hi[0], hi[1], hi[2]}, rlo[3] = {lo[0], lo[1], lo[2]};
  lhi[axis] = split;
  rlo[axis] = split;
  buildRange(points, first, half, lo, lhi);  // the left child is node id + 1
  const int right = buildRange(points, first + half, count - half, rlo, hi);
  Node& node = nodes_[static_cast<size_t>(id)];
  node.axis = axis;
  node.split = split;
  node.right = right;
  return id;
}

// `gap` holds, per axis, the signed gap from the query to the current cell (0 inside its slab).
// Each gap is one rounded subtraction of a cell bound from the query coordinate, and the bound
// below sums their squares in the same order as a point's squared distance is summed. Rounding is
// monotonic, so the bound never exceeds the computed squared distance of a point in the cell, and
// pruning cells whose bound is above the best distance never drops a point at that distance (a tie).
void KdTree::search(int n, double gap[3], Search& s) const {
  const Node& node = nodes_[static_cast<size_t>(n)];
  if (node.axis == kLeaf) {
    // The leaf's distances as one fixed-size block (vectorised, each summed in the same order as
    // everywhere here), then the comparisons only when it holds a point at least as close as the
    // best.
    const size_t first = static_cast<size_t>(node.first);
    using Block = Eigen::Map<const Eigen::Array<double, kBucket, 1>>;
    const Eigen::Array<double, kBucket, 1> d2 = (Block(x_.data() + first) - s.q[0]).square() +
                                                (Block(y_.data() + first) - s.q[1]).square() +
                                                (Block(z_.data() + first) - s.q[2]).square();
    if (d2.minCoeff() > s.best2) return;
    for (int i = 0; i < kBucket; ++i)
      if (d2[i] <= s.best2 && (d2[i] < s.best2 || index_[first + i] < s.best)) {
        s.best2 = d2[i];
        s.best = index_[first + i];
      }
    return;
  }
  const int a = node.axis;
  const double d = s.q[a] - node.split;
  const bool leftFirst = d <= 0;
  search(leftFirst ? n + 1 : node.right, gap, s);
  // The far child lies beyond the split plane: its gap on this axis is d, never smaller in size
  // than the current cell's.
  const double saved = gap[a];
  gap[a] = d;
  const double bound = gap[0] * gap[0] + gap[1] * gap[1] + gap[2] * gap[2];
  if (bound <= s.best2) search(leftFirst ? node.right : n + 1, gap, s);
  gap[a] = saved;
}

KdTree::Nearest KdTree::nearest(const Eigen::Vector3d& p, double maxDistance2, int hint) const {
  Search s{{p.x(), p.y(), p.z()}, maxDistance2, -1};
  if (nodes_.empty()) return {};
  if (hint >= 0 && hint < size()) {
    const size_t i = static_cast<size_t>(position_[static_cast<size_t>(hint)]);
    const double dx = x_[i] - s.q[0], dy = y_[i] - s.q[1], dz = z_[i] - s.q[2];
    const double d2 = dx * dx + dy * dy + dz * dz;
    if (d2 < s.best2) {
      s.best2 = d2;
      s.best = hint;
    }
  }
  double gap[3];
  for (int k = 0; k < 3; ++k) gap[k] = s.q[k] < lo_[k] ? s.q[k] - lo_[k] : s.q[k] > hi_[k] ? s.q[k] - hi_[k] : 0.0;
  if (gap[0] * gap[0] + gap[1] * gap[1] + gap[2] * gap[2] <= s.best2) search(0, gap, s);
  if (s.best < 0) return {};
  return {s.best, s.best2};
}

}  // namespace viscera::obs
