// The PCL-free parts of the preprocessing: option checks and the voxel-grid down-sampling.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

#include "core/Error.h"
#include "io/pointcloud/CloudPrep.h"

namespace viscera::cloud {
namespace {

// Cell indices are packed into one 64-bit key, 21 bits per axis.
constexpr int kCellBits = 21;
constexpr double kMaxCellsPerAxis = double((std::int64_t(1) << kCellBits) - 1);

std::string num(double v) {
  std::string s = std::to_string(v);
  s.erase(s.find_last_not_of('0') + 1);
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s;
}

// (cell key, point index) of every point, sorted by key (z cell slowest, x fastest), then by index.
std::vector<std::pair<std::uint64_t, int>> sortedCells(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& origin,
                                                       double leaf) {
  std::vector<std::pair<std::uint64_t, int>> cells(points.cols());
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    std::uint64_t key = 0;
    for (int k = 2; k >= 0; --k) {
      const double c = std::floor((points(k, i) - origin[k]) / leaf);
      key = (key << kCellBits) | static_cast<std::uint64_t>(std::clamp(c, 0.0, kMaxCellsPerAxis));
    }
    cells[i] = {key, static_cast<int>(i)};
  }
  std::sort(cells.begin(), cells.end());
  return cells;
}

int countCells(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& origin, double leaf) {
  const auto cells = sortedCells(points, origin, leaf);
  int count = 0;
  for (size_t i = 0; i < cells.size(); ++i) count += i == 0 || cells[i].first != cells[i - 1].first;
  return count;
}

}  // namespace

void validatePrepOptions(const PrepOptions& o) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (o.crop) {
    const auto& b = *o.crop;
    if (!b.min.allFinite() || !b.max.allFinite()) throw Error("--crop: the corners must be finite numbers");
    for (int k = 0; k < 3; ++k)
      if (!(b.min[k] < b.max[k]))
        throw Error(std::string("--crop: the minimum must be below the maximum on every axis, but on ") + "xyz"[k] +
                    " it is " + num(b.min[k]) + " >= " + num(b.max[k]));
  }
  if (o.removePlane) {
    if (!positive(o.planeThreshold)) throw Error("--plane-threshold: must be a positive distance, got " + num(o.planeThreshold));
    if (o.planeMaxIterations < 1)
      throw Error("--plane-iterations: must be at least 1, got " + std::to_string(o.planeMaxIterations));
  }
  if (o.removeOutliers) {
    if (o.outlierNeighbours < 1) throw Error("--outlier-k: must be at least 1, got " + std::to_string(o.outlierNeighbours));
    if (!positive(o.outlierStddev)) throw Error("--outlier-std: must be a positive number, got " + num(o.outlierStddev));
  }
  if (!positive(o.clusterTolerance))
    throw Error("--cluster-tolerance: must be a positive distance, got " + num(o.clusterTolerance));
  if (o.minClusterSize < 1) throw Error("--min-cluster: must be at least 1, got " + std::to_string(o.minClusterSize));
  if (o.maxClusterSize < o.minClusterSize)
    throw Error("--max-cluster: must be at least --min-cluster (" + std::to_string(o.minClusterSize) + "), got " +
                std::to_string(o.maxClusterSize));
  if (o.keepRank < 1) throw Error("--keep-rank: must be at least 1 (1 = the largest cluster), got " + std::to_string(o.keepRank));
  if (o.targetCount < 0) throw Error("--target: must be 0 (no down-sampling) or a positive count, got " + std::to_string(o.targetCount));
}

PointCloud voxelDownsample(const PointCloud& cloud, double leaf) {
  if (!(std::isfinite(leaf) && leaf > 0)) throw Error(SourceLoc{cloud.source}, "voxel leaf size must be positive, got " + num(leaf));
  if (cloud.empty()) return cloud;
  const Eigen::Vector3d origin = cloud.points.rowwise().minCoeff();
  const Eigen::Vector3d extent = cloud.points.rowwise().maxCoeff() - origin;
  if (extent.maxCoeff() / leaf >= kMaxCellsPerAxis)
    throw Error(SourceLoc{cloud.source}, "voxel leaf size " + num(leaf) + " is too small for the cloud's extent " +
                                             num(extent.maxCoeff()) + " (at most 2^21 cells per axis)");
  const bool withNormals = cloud.normals.cols() == cloud.points.cols();
  const auto cells = sortedCells(cloud.points, origin, leaf);

  PointCloud out;
  out.time = cloud.time;
  out.source = cloud.source;
  out.points.resize(3, cloud.size());
  if (withNormals) out.normals.resize(3, cloud.size());
  int count = 0;
  for (size_t begin = 0; begin < cells.size();) {
    size_t end = begin;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), normalSum = Eigen::Vector3d::Zero();
    for (; end < cells.size() && cells[end].first == cells[begin].first; ++end) {
      sum += cloud.points.col(cells[end].second);
      if (withNormals) normalSum += cloud.normals.col(cells[end].second);
    }
    out.points.col(count) = sum / double(end - begin);
    if (withNormals) {
      const double length = normalSum.norm();
      out.normals.col(count) = length > 1e-12 ? Eigen::Vector3d(normalSum / length)
                                               : Eigen::Vector3d(cloud.normals.col(cells[begin].second));
    }
    ++count;
    begin = end;
  }
  out.points.conservativeResize(3, count);
  if (withNormals) out.normals.conservativeResize(3, count);
  return out;
}

PointCloud downsampleToCount(const PointCloud& cloud, int targetCount, double* leafOut) {
  if (leafOut) *leafOut = 0.0;
  if (targetCount < 0) throw Error(SourceLoc{cloud.source}, "target point count must not be negative");
  if (targetCount == 0 || cloud.size() <= targetCount) return cloud;

  const Eigen::Vector3d origin = cloud.points.rowwise().minCoeff();
  const double extent = (cloud.points.rowwise().maxCoeff() - origin).maxCoeff();
  // hi: a leaf larger than the cloud, one cell (count 1 <= target). lo: the smallest leaf the cell
  // keys allow; at it (cells of extent / 2 million) the count is that of distinct points.
  double hi = extent > 0 ? 1.5 * extent : 1.0;
  double lo = extent > 0 ? extent / (kMaxCellsPerAxis - 1) : 0.5;
  if (countCells(cloud.points, origin, lo) <= targetCount) {
    hi = lo;  // the cloud has few distinct points: merging exact duplicates is enough
  } else {
    // Invariant: count(lo) > target >= count(hi). The count is not strictly monotonic in the leaf
    // size (cell boundaries move), so this finds a boundary, not the global optimum; on dense
    // captures the count lands within a fraction of a percent below the target.
    while (hi - lo > 1e-6 * hi) {
      const double mid = 0.5 * (lo + hi);
      const int count = countCells(cloud.points, origin, mid);
      if (count == targetCount) {
        hi = mid;
        break;
      }
      (count < targetCount ? hi : lo) = mid;
    }
  }
  if (leafOut) *leafOut = hi;
  return voxelDownsample(cloud, hi);
}

}  // namespace viscera::cloud
