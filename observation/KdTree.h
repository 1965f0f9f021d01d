// Nearest-neighbour queries on a fixed set of 3-D points: a k-d tree with median splits and
// buckets of points at the leaves. Used to match depth-camera points to a super-sampled surface,
// where tens of thousands of queries run against a few thousand points every frame, so both the
// build and the query are kept lean. The answer is exact: the tree computes each squared distance
// as (x - p_x)^2 + (y - p_y)^2 + (z - p_z)^2, in that order, and never prunes a point that could be
// as close as the best found.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <vector>

namespace viscera::obs {

class KdTree {
 public:
  struct Nearest {
    int index = -1;  // column of the nearest point; -1 when none lies within the search radius
    double distance2 = std::numeric_limits<double>::infinity();  // its squared distance
  };

  KdTree() = default;
  explicit KdTree(const Eigen::Matrix3Xd& points) { build(points); }

  // Builds over `points` (3 x n, copied). Each level splits a cell across its longest side (the
  // root's cell is the points' bounding box), at the multiple of kBucket points nearest the median;
  // cells of at most kBucket points are leaves.
  void build(const Eigen::Matrix3Xd& points);

  // The point nearest to p among those strictly closer than sqrt(maxDistance2); of points at the
  // same distance, the one with the smallest index. `hint`, an index likely to be near p (the
  // previous query's answer, for coherent queries such as the rows of a depth image), starts the
  // search with a tight radius; it never changes the answer.
  Nearest nearest(const Eigen::Vector3d& p, double maxDistance2 = std::numeric_limits<double>::infinity(),
                  int hint = -1) const;

  int size() const { return size_; }
  bool empty() const { return size_ == 0; }

  // Points per leaf. Every leaf but the last holds exactly this many (the splits fall at multiples
  // of it) and the last is padded, so a leaf's distances are one fixed-size vectorised block. On
  // the phantom benchmark (8,066 samples) leaves of 16 to 32 points were the fastest, 8 and 64
  // clearly slower.
  static constexpr int kBucket = 32;

 private:
  // Nodes in depth-first order (a left child follows its parent). Internal nodes split on `axis`
  // at `split`: the points of the left child have coordinate <= split, those of the right child
  // >= split. Leaves have axis kLeaf and hold the kBucket slots from `first` of the reordered
  // coordinate arrays.
  static constexpr int kLeaf = 3;
  struct Node {
    double split = 0;
    int axis = kLeaf;
    int right = -1;
    int first = 0;
  };
  struct Point {
    double c[3];
    int index;
  };
  struct Search;

  // Builds the subtree over points[first, first + count), whose cell is [lo, hi]; returns its node.
  int buildRange(Point* points, int first, int count, const double lo[3], const double hi[3]);
  void search(int node, double gap[3], Search& s) const;

  std::vector<Node> nodes_;
  double lo_[3] = {0, 0, 0}, hi_[3] = {0, 0, 0};  // bounding box of all points
  // Coordinates in tree order, one array per axis so that a leaf's distances vectorise, padded to a
  // whole number of leaves with copies of the last leaf's first point.
  std::vector<double> x_, y_, z_;
  std::vector<int> index_;     // tree order -> column of the input (padding: INT_MAX, which loses every tie)
  std::vector<int> position_;  // column of the input -> tree order (for hints)
  int size_ = 0;
};

}  // namespace viscera::obs
