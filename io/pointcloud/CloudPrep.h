// Preprocessing of depth-camera captures of a specimen on a table: crop, remove the table plane,
// remove statistical outliers, keep one Euclidean cluster (the specimen), down-sample to a target
// count. Distances are in the cloud's units; the defaults are millimetres, sized for a phantom of
// about 70 x 36 x 39 mm seen from about 400 mm by a RealSense camera (for clouds in metres, scale
// every distance by 1e-3).
#pragma once

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <vector>

#include "io/pointcloud/PointCloud.h"

namespace viscera::cloud {

struct CropBox {
  Eigen::Vector3d min, max;  // corners; points with min <= p <= max (every axis) are kept
};

// The stages run in this order: crop, plane, outliers, clustering, down-sampling. Each option names
// the `viscera cloud prep` option that sets it.
struct PrepOptions {
  // --crop: applied first, to cut away what is far from the specimen (the instrument's shaft, the
  // room behind the table).
  std::optional<CropBox> crop;

  // Table removal: the plane with the most points within `planeThreshold` is found by RANSAC
  // (PCL's SACSegmentation, SACMODEL_PLANE, coefficients refined by least squares over the
  // inliers) and its inliers are removed.
  bool removePlane = true;        // off with --no-plane
  double planeThreshold = 2.0;    // --plane-threshold: inlier distance, about twice a RealSense's depth noise at 400 mm
  int planeMaxIterations = 1000;  // --plane-iterations: RANSAC iterations at most
  unsigned seed = 1;              // --seed: RANSAC's random generator; the same seed gives the same result

  // Statistical outlier removal (PCL's StatisticalOutlierRemoval): a point goes when its mean
  // distance to its `outlierNeighbours` nearest neighbours exceeds the mean of that quantity over
  // the cloud by more than `outlierStddev` standard deviations. Flying pixels at depth edges and
  // isolated specks go; it runs before clustering so that they cannot bridge two clusters.
  bool removeOutliers = true;  // off with --no-outliers
  int outlierNeighbours = 20;  // --outlier-k
  double outlierStddev = 2.0;  // --outlier-std

  // Euclidean clustering (PCL's EuclideanClusterExtraction): points closer than `clusterTolerance`
  // are in the same cluster; clusters with fewer than `minClusterSize` or more than
  // `maxClusterSize` points are dropped. The clusters are ranked by size and the one of rank
  // `keepRank` (1 = largest) is kept. With the table removed first the specimen is the largest
  // cluster. The dissertation's pipeline clustered with the table still present and kept the
  // second largest group: `--no-plane --keep-rank 2` reproduces that. An instrument touching the
  // specimen joins its cluster; crop it away or remove it with its known pose downstream.
  double clusterTolerance = 4.0;  // --cluster-tolerance: 2-4 times the point spacing on the phantom at 400 mm (1-2 mm)
  int minClusterSize = 100;       // --min-cluster
  int maxClusterSize = std::numeric_limits<int>::max();  // --max-cluster (default: no limit)
  int keepRank = 1;               // --keep-rank

  // Down-sampling: when the cloud has more than `targetCount` points, a voxel grid (cells aligned
  // with the cloud's bounding-box minimum, one point per occupied cell at the centroid of its
  // points, normals averaged and renormalised) whose leaf size is bisected so that the count is
  // at most `targetCount` and as close to it as the grid allows. 0 keeps every point.
  int targetCount = 45000;  // --target: the dissertation's "about 45k points"
};

struct PrepReport {
  // Point counts after each stage (a stage that is off passes its input on).
  int input = 0, afterCrop = 0, afterPlane = 0, afterOutliers = 0, afterCluster = 0, output = 0;
  // The table plane a x + b y + c z + d = 0 with (a, b, c) a unit normal pointing to the side of
  // the origin (d >= 0; the camera's side for a capture in its frame), and its inlier count; zero
  // when plane removal is off.
  Eigen::Vector4d plane = Eigen::Vector4d::Zero();
  int planeInliers = 0;
  std::vector<int> clusterSizes;  // sizes of the clusters found, largest first
  int keptRank = 0;               // rank of the cluster kept (1 = largest)
  double voxelLeaf = 0.0;         // the voxel leaf size used; 0 when no down-sampling was needed
};

// Checks the options; throws viscera::Error naming the `viscera cloud prep` option at fault.
void validatePrepOptions(const PrepOptions& options);

// Runs the pipeline on `cloud` (finite points; normals, when present, follow their points). Throws
// viscera::Error (naming `cloud.source` when set) for an empty input, a crop that removes every
// point, no plane found, no points left after a stage, or fewer clusters than `keepRank` (with
// the sizes of those found). `report`, when given, is filled in.
PointCloud prepareCloud(const PointCloud& cloud, const PrepOptions& options, PrepReport* report = nullptr);

// The voxel grid used for down-sampling: cells of size `leaf` aligned with the bounding-box
// minimum of `cloud`; one point per occupied cell, the centroid of the cell's points, cells in
// order of their z, then y, then x index. Normals are averaged and renormalised (a cell whose
// normals cancel keeps its first point's normal). At most 2^21 cells per axis.
PointCloud voxelDownsample(const PointCloud& cloud, double leaf);

// Down-samples to at most `targetCount` points with voxelDownsample, bisecting the leaf size to
// the boundary where the count drops to the target or below; returns the cloud unchanged when it
// has `targetCount` points or fewer (or `targetCount` is 0). `leaf`, when given, receives the leaf
// size used (0 when unchanged).
PointCloud downsampleToCount(const PointCloud& cloud, int targetCount, double* leaf = nullptr);

// How planeFitNoise finds a point's neighbours: by image coordinates (x/z, y/z) for a cloud in
// its camera's frame, where a depth error moves a point along its ray and so does not change its
// neighbours; by 3-D distance otherwise (biased low when the noise is comparable to the spacing).
enum class NoiseNeighbours { Image, Space };

// The depth noise of a capture, from the capture alone: around at most `samples` points (evenly
// chosen), the least-squares plane through the k nearest neighbours; with independent noise sigma
// along the normal of a locally flat surface its residual sum of squares is sigma^2 (k - 3) (a
// plane has three parameters). The estimate is the RMS of those sigmas over the patches, less the
// patches across edges (a minority far from planar, above four times the median). The patch must
// be wide against the noise (a plane through a patch hardly wider than the noise follows it and
// reads low) and narrow against the surface's curvature, which adds to the estimate. NaN for a
// cloud of fewer than k points. Nearest neighbours through PCL's k-d tree.
double planeFitNoise(const PointCloud& cloud, int k = 12, int samples = 2000,
                     NoiseNeighbours by = NoiseNeighbours::Image);

}  // namespace viscera::cloud
