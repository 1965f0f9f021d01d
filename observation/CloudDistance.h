// One-sided distance from a measured point cloud to a simulated triangle surface: how far each
// camera point lies from the tissue. Only the cloud -> surface direction is measured: parts of the
// surface the camera does not see (occluded, or facing away) have no points, so the other
// direction would count them as errors.
//
// Two methods:
//  - Vertices: the distance to the nearest point of the surface super-sampled `factor` times per
//    edge (a k-d tree over the samples, rebuilt each frame). Cheap, and the measure used for the
//    gel phantom; it over-estimates the true distance by at most the distance from a surface point
//    to its nearest sample (under the circumradius of the sub-triangles).
//  - Triangles: the exact distance to the nearest point on any triangle (a bounding-volume
//    hierarchy refitted each frame), with a sign: positive outside the surface.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "observation/KdTree.h"
#include "observation/SurfaceIndex.h"
#include "observation/SurfaceSampling.h"
#include "io/mesh/Mesh.h"

namespace viscera::obs {

enum class DistanceMethod { Vertices, Triangles };

// "vertices" / "triangles".
const char* methodName(DistanceMethod method);

struct DistanceOptions {
  DistanceMethod method = DistanceMethod::Vertices;
  // Subdivisions per triangle edge for the Vertices method (1: the vertices only).
  int factor = 3;
  // Cloud points farther than this from the surface (background, other objects) are left out of
  // the statistics and the per-vertex means and counted in DistanceStats::beyond.
  double maxDistance = std::numeric_limits<double>::infinity();
  // Spread the points over TBB's threads. The result does not depend on it, nor on the number of
  // threads: every point is measured on its own, and sums run over the points in order.
  bool parallel = true;
};

// Statistics of one frame's distances (of the points within maxDistance). NaN when count is 0.
struct DistanceStats {
  int count = 0;   // points within maxDistance
  int beyond = 0;  // points farther than maxDistance
  double mean = std::numeric_limits<double>::quiet_NaN();
  double rms = std::numeric_limits<double>::quiet_NaN();          // sqrt(meanSquared)
  double meanSquared = std::numeric_limits<double>::quiet_NaN();  // mean of distance^2
  double median = std::numeric_limits<double>::quiet_NaN();       // mean of the two middle values for an even count
  double p95 = std::numeric_limits<double>::quiet_NaN();          // 95th percentile, see percentile()
  double max = std::numeric_limits<double>::quiet_NaN();
  double signedMean = std::numeric_limits<double>::quiet_NaN();   // mean signed distance (Triangles only)
};

// The q-quantile (q in [0, 1]) of `values`, interpolating linearly between order statistics: with
// the values sorted v_0 <= ... <= v_{n-1} and h = q (n - 1), it is v_floor(h) + (h - floor(h))
// (v_floor(h)+1 - v_floor(h)) (numpy's default "linear" method; q = 0.5 gives the median). NaN for
// no values. The values must be finite.
double percentile(const std::vector<double>& values, double q);

// Statistics of `distances` (and of `signedDistances` when not empty, same length) over the entries
// with `within` set (all when `within` is empty); entries without it count as beyond.
DistanceStats summarize(const std::vector<double>& distances, const std::vector<double>& signedDistances = {},
                        const std::vector<char>& within = {});

struct DistanceResult {
  // Per cloud point (n points).
  std::vector<double> distance;        // n
  Eigen::Matrix3Xd residual;           // 3 x n: nearest surface point - cloud point
  std::vector<double> signedDistance;  // n, Triangles only (empty for Vertices): + outside, - inside
  std::vector<int> nearest;            // n: the nearest sample (Vertices) or triangle (Triangles)
  Eigen::Matrix3Xd barycentric;        // 3 x n, Triangles only: weights of the nearest point on its triangle
  std::vector<char> within;            // n: 1 when distance <= maxDistance
  double maxDistance = std::numeric_limits<double>::infinity();  // the cut-off measured with

  DistanceStats stats;

  // Per surface vertex (all numVertices of the surface, used by the triangles or not). A cloud point
  // is attributed to vertex v with weight w > 0 when its nearest surface point has weight w on v:
  // the sample's row of the sampling weights (Vertices; 1 for a sample at a vertex), the barycentric
  // weight (Triangles). Points beyond maxDistance are not attributed.
  Eigen::Matrix3Xd meanResidual;  // 3 x #vertices: sum w residual / sum w; NaN where pointCount is 0
  std::vector<double> meanDistance;  // #vertices: sum w distance / sum w; NaN where pointCount is 0
  std::vector<int> pointCount;       // #vertices: number of points attributed
};

class CloudDistance {
 public:
  // The surface's connectivity: `triangles` (3 x #triangles, oriented outwards for the sign) over
  // numVertices vertices. Throws std::invalid_argument for an index out of range or a factor < 1.
  CloudDistance(const TriangleList& triangles, int numVertices, const DistanceOptions& options = {});

  // Places the surface at positions x (3 x numVertices): re-samples it and rebuilds the k-d tree
  // (Vertices) or refits the hierarchy and the pseudo-normals (Triangles). Call before measure().
  void setSurface(const Eigen::Matrix3Xd& x);

  // Measures `cloud` (3 x n, in the surface's frame) against the current surface. The overload
  // with `out` reuses its storage, for a frame loop.
  void measure(const Eigen::Matrix3Xd& cloud, DistanceResult& out) const;
  DistanceResult measure(const Eigen::Matrix3Xd& cloud) const;

  const DistanceOptions& options() const { return options_; }
  const TriangleList& triangles() const { return triangles_; }
  int numVertices() const { return numVertices_; }
  const SurfaceSampling& sampling() const { return sampling_; }  // Vertices only
  const Eigen::Matrix3Xd& samples() const { return samples_; }   // 3 x #samples at the current surface

 private:
  void measureRange(const Eigen::Matrix3Xd& cloud, int first, int last, DistanceResult& out) const;
  void attribute(DistanceResult& out) const;
  void updatePseudoNormals(const Eigen::Matrix3Xd& x);

  DistanceOptions options_;
  TriangleList triangles_;
  int numVertices_ = 0;
  bool placed_ = false;
  // Vertices method.
  SurfaceSampling sampling_;
  Eigen::Matrix3Xd samples_;
  KdTree tree_;
  // Triangles method: the hierarchy and the pseudo-normals that give the sign at a closest point
  // on a face, an edge or a vertex (Baerentzen and Aanaes, IEEE TVCG 11(3), 2005).
  SurfaceIndex index_;
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangleEdges_;  // 3 x #triangles: ids of the edges ab, bc, ca
  int numEdges_ = 0;
  Eigen::Matrix3Xd faceNormals_;                         // 3 x #triangles, unit
  Eigen::Matrix3Xd edgeNormals_;                         // 3 x #edges: sum of the adjacent face normals
  Eigen::Matrix3Xd vertexNormals_;                       // 3 x #vertices: angle-weighted face normals
};

// Writes the measured cloud as a .vtp of vertex cells with point fields `distance`, `residual`
// (3 components) and, for the Triangles method, `signedDistance`; with a cut-off also `within`
// (1 inside it, 0 beyond). `cloud` is the 3 x n cloud that was measured.
void writeCloudResiduals(const std::string& path, const Eigen::Matrix3Xd& cloud, const DistanceResult& result,
                         const io::VtuWriteOptions& options = {});
// Writes the surface (points x, 3 x #vertices, and its triangles) as a .vtp with point fields
// `meanResidual` (3), `meanDistance` and `pointCount`.
void writeSurfaceResiduals(const std::string& path, const Eigen::Matrix3Xd& x, const TriangleList& triangles,
                           const DistanceResult& result, const io::VtuWriteOptions& options = {});

}  // namespace viscera::obs
