// prepareCloud: crop, RANSAC table plane, statistical outliers and Euclidean clustering through
// PCL, then the voxel-grid down-sampling of CloudPrep.cpp. The PCL stages work on float copies of
// the surviving points and report indices; the output takes the original double-precision points
// (and normals) at those indices.
#include <pcl/console/print.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/sample_consensus/sac_model_plane.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "core/Error.h"
#include "io/pointcloud/CloudPrep.h"

namespace viscera::cloud {
namespace {

using XyzCloud = pcl::PointCloud<pcl::PointXYZ>;

// SampleConsensusModelPlane with its random generator seeded by us (PCL seeds it with a fixed
// 12345 or the clock, and SACSegmentation has no way to pass a seed).
class SeededPlaneModel : public pcl::SampleConsensusModelPlane<pcl::PointXYZ> {
 public:
  SeededPlaneModel(const PointCloudConstPtr& cloud, const pcl::Indices& indices, unsigned seed)
      : pcl::SampleConsensusModelPlane<pcl::PointXYZ>(cloud, indices, false) {
    rng_alg_.seed(seed);
  }
};

// SACSegmentation (RANSAC, SACMODEL_PLANE) drawing its samples from a SeededPlaneModel.
class SeededPlaneSegmentation : public pcl::SACSegmentation<pcl::PointXYZ> {
 public:
  explicit SeededPlaneSegmentation(unsigned seed) : seed_(seed) {
    setModelType(pcl::SACMODEL_PLANE);
    setMethodType(pcl::SAC_RANSAC);
  }

 protected:
  bool initSACModel(const int /*model_type: always a plane*/) override {
    model_.reset(new SeededPlaneModel(input_, *indices_, seed_));
    return true;
  }

 private:
  unsigned seed_;
};

// Float copies of the points at `kept` (PCL's filters work in float; millimetre coordinates of a
// capture a metre away keep ~0.1 micrometre).
XyzCloud::Ptr toPcl(const Eigen::Matrix3Xd& points, const std::vector<int>& kept) {
  XyzCloud::Ptr out(new XyzCloud);
  out->resize(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    const auto p = points.col(kept[i]).cast<float>();
    (*out)[i] = pcl::PointXYZ(p.x(), p.y(), p.z());
  }
  out->width = static_cast<std::uint32_t>(kept.size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

std::string num(double v) {
  std::ostringstream o;
  o << v;
  return o.str();
}

std::string vec(const Eigen::Vector3d& v) { return "(" + num(v.x()) + " " + num(v.y()) + " " + num(v.z()) + ")"; }

// "3 clusters: 5120, 3300 and 140 points" (at most 10 sizes listed).
std::string describeClusters(const std::vector<int>& sizes) {
  if (sizes.empty()) return "no cluster";
  std::string s = std::to_string(sizes.size()) + (sizes.size() == 1 ? " cluster: " : " clusters: ");
  const size_t shown = std::min<size_t>(sizes.size(), 10);
  for (size_t i = 0; i < shown; ++i)
    s += (i == 0 ? "" : i + 1 == sizes.size() ? " and " : ", ") + std::to_string(sizes[i]);
  if (shown < sizes.size()) s += ", ... (" + std::to_string(sizes.size() - shown) + " more)";
  return s + (sizes.size() == 1 && sizes[0] == 1 ? " point" : " points");
}

const char* kUnitsHint = " (distances are in the cloud's units; the defaults assume millimetres)";

}  // namespace

PointCloud prepareCloud(const PointCloud& cloud, const PrepOptions& o, PrepReport* reportOut) {
  validatePrepOptions(o);
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);  // failures are reported below, with the file
  auto fail = [&](const std::string& what) { throw Error(SourceLoc{cloud.source}, what); };
  const int n = cloud.size();
  if (n == 0) fail("the cloud is empty: nothing to prepare");
  for (int i = 0; i < n; ++i)
    if (!cloud.points.col(i).allFinite()) fail("point " + std::to_string(i) + " is not finite");
  const bool withNormals = cloud.normals.cols() > 0;
  if (withNormals && cloud.normals.cols() != n)
    fail(std::to_string(cloud.normals.cols()) + " normals for " + std::to_string(n) + " points");

  PrepReport r;
  r.input = n;
  // Indices into `cloud` of the points still in, in their original order.
  std::vector<int> kept;
  kept.reserve(n);
  if (o.crop) {
    for (int i = 0; i < n; ++i) {
      const auto p = cloud.points.col(i);
      if ((p.array() >= o.crop->min.array()).all() && (p.array() <= o.crop->max.array()).all()) kept.push_back(i);
    }
    if (kept.empty())
      fail("the crop box " + vec(o.crop->min) + " .. " + vec(o.crop->max) + " (--crop) removes every point; the cloud spans " +
           vec(cloud.points.rowwise().minCoeff()) + " .. " + vec(cloud.points.rowwise().maxCoeff()));
  } else {
    for (int i = 0; i < n; ++i) kept.push_back(i);
  }
  r.afterCrop = static_cast<int>(kept.size());

  if (o.removePlane) {
    SeededPlaneSegmentation seg(o.seed);
    seg.setDistanceThreshold(o.planeThreshold);
    seg.setMaxIterations(o.planeMaxIterations);
    seg.setOptimizeCoefficients(true);
    seg.setInputCloud(toPcl(cloud.points, kept));
    pcl::PointIndices inliers;
    pcl::ModelCoefficients coefficients;
    if (kept.size() >= 3) seg.segment(inliers, coefficients);
    if (inliers.indices.empty() || coefficients.values.size() != 4)
      fail("no plane found among the " + std::to_string(kept.size()) +
           " points (the table is removed as the largest plane; use --no-plane when there is none)");
    Eigen::Vector4d plane(coefficients.values[0], coefficients.values[1], coefficients.values[2], coefficients.values[3]);
    plane /= plane.head<3>().norm();
    if (plane[3] < 0) plane = -plane;  // normal towards the origin: the camera, for a capture in its frame
    r.plane = plane;
    r.planeInliers = static_cast<int>(inliers.indices.size());
    std::vector<char> onPlane(kept.size(), 0);
    for (const auto i : inliers.indices) onPlane[i] = 1;
    std::vector<int> rest;
    for (size_t i = 0; i < kept.size(); ++i)
      if (!onPlane[i]) rest.push_back(kept[i]);
    kept.swap(rest);
    if (kept.empty())
      fail("every point lies within " + num(o.planeThreshold) + " of the plane found (--plane-threshold): nothing is left" +
           kUnitsHint);
  }
  r.afterPlane = static_cast<int>(kept.size());

  if (o.removeOutliers) {
    pcl::StatisticalOutlierRemoval<pcl::PointXYZ> sor;
    sor.setInputCloud(toPcl(cloud.points, kept));
    sor.setMeanK(o.outlierNeighbours);
    sor.setStddevMulThresh(o.outlierStddev);
    pcl::Indices inliers;
    sor.filter(inliers);
    std::vector<int> rest;
    rest.reserve(inliers.size());
    for (const auto i : inliers) rest.push_back(kept[i]);
    std::sort(rest.begin(), rest.end());
    kept.swap(rest);
    if (kept.empty()) fail("the outlier removal (--outlier-k, --outlier-std) removed every point");
  }
  r.afterOutliers = static_cast<int>(kept.size());

  {
    const XyzCloud::Ptr points = toPcl(cloud.points, kept);
    pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
    tree->setInputCloud(points);
    pcl::EuclideanClusterExtraction<pcl::PointXYZ> ece;
    ece.setClusterTolerance(o.clusterTolerance);
    ece.setMinClusterSize(o.minClusterSize);
    ece.setMaxClusterSize(o.maxClusterSize);
    ece.setSearchMethod(tree);
    ece.setInputCloud(points);
    std::vector<pcl::PointIndices> clusters;
    ece.extract(clusters);
    std::stable_sort(clusters.begin(), clusters.end(),
                     [](const pcl::PointIndices& a, const pcl::PointIndices& b) { return a.indices.size() > b.indices.size(); });
    for (const auto& c : clusters) r.clusterSizes.push_back(static_cast<int>(c.indices.size()));
    if (static_cast<int>(clusters.size()) < o.keepRank) {
      std::string what = "--keep-rank " + std::to_string(o.keepRank) + " asks for cluster " + std::to_string(o.keepRank) +
                         " by size, but clustering the " + std::to_string(kept.size()) + " remaining points with --cluster-tolerance " +
                         num(o.clusterTolerance) + " and --min-cluster " + std::to_string(o.minClusterSize) + " found " +
                         describeClusters(r.clusterSizes) + ". ";
      what += clusters.empty() ? "Try a larger --cluster-tolerance or a smaller --min-cluster"
                               : "Try a lower --keep-rank, or a smaller --cluster-tolerance to split objects that nearly touch";
      fail(what + kUnitsHint);
    }
    std::vector<int> rest;
    for (const auto i : clusters[o.keepRank - 1].indices) rest.push_back(kept[i]);
    std::sort(rest.begin(), rest.end());
    kept.swap(rest);
    r.keptRank = o.keepRank;
  }
  r.afterCluster = static_cast<int>(kept.size());

  PointCloud specimen;
  specimen.time = cloud.time;
  specimen.source = cloud.source;
  specimen.points.resize(3, kept.size());
  if (withNormals) specimen.normals.resize(3, kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    specimen.points.col(i) = cloud.points.col(kept[i]);
    if (withNormals) specimen.normals.col(i) = cloud.normals.col(kept[i]);
  }
  PointCloud out = downsampleToCount(specimen, o.targetCount, &r.voxelLeaf);
  r.output = out.size();
  if (reportOut) *reportOut = r;
  return out;
}

double planeFitNoise(const PointCloud& cloud, int k, int samples, NoiseNeighbours by) {
  const int n = cloud.size();
  if (k < 4 || n < k) return std::numeric_limits<double>::quiet_NaN();
  // Neighbours are found in image coordinates (x/z, y/z) for a camera-frame cloud: a depth error
  // moves a point along its pixel's ray, so it does not change which points are neighbours. In 3-D
  // they would be chosen by the noise itself (points displaced alike look close) and the estimate
  // would come out low.
  XyzCloud::Ptr search(new XyzCloud);
  search->resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = cloud.points.col(i);
    (*search)[static_cast<size_t>(i)] = by == NoiseNeighbours::Image && p.z() > 0
                                            ? pcl::PointXYZ(static_cast<float>(p.x() / p.z()), static_cast<float>(p.y() / p.z()), 0.f)
                                            : pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  }
  pcl::search::KdTree<pcl::PointXYZ> tree;
  tree.setInputCloud(search);
  const int m = std::min(n, std::max(1, samples));
  std::vector<int> index;
  std::vector<float> d2;
  std::vector<double> v;  // each patch's sigma^2: its residual sum of squares / (k - 3)
  for (int s = 0; s < m; ++s) {
    const int i = static_cast<int>(static_cast<long>(s) * n / m);
    if (tree.nearestKSearch((*search)[static_cast<size_t>(i)], k, index, d2) < k) continue;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int j : index) mean += cloud.points.col(j);
    mean /= static_cast<double>(index.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (int j : index) cov += (cloud.points.col(j) - mean) * (cloud.points.col(j) - mean).transpose();
    // The least-squares plane's residual sum of squares is the scatter's smallest eigenvalue.
    v.push_back(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov, Eigen::EigenvaluesOnly).eigenvalues()(0) / (k - 3));
  }
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  // Patches across an edge or the silhouette, a minority, are far from planar: they are left out
  // by a cut at four times the median patch's sigma^2, which keeps a patch whose noise is half as
  // large again as the median's even when its own estimate (relative spread sqrt(2 / (k - 3)))
  // reads high. The mean of the rest is the mean square of the noise, what a residual RMS is
  // compared with (depth noise grows with depth: the median patch's is lower).
  std::vector<double> sorted = v;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double cut = 4 * sorted[sorted.size() / 2];
  double sum = 0;
  int count = 0;
  for (double x : v)
    if (x <= cut) sum += x, ++count;
  return std::sqrt(sum / count);
}

}  // namespace viscera::cloud
