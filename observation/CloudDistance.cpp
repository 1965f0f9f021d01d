#include "observation/CloudDistance.h"

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <utility>

namespace viscera::obs {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// Points per task when measuring in parallel: enough work to amortise scheduling, and long runs of
// neighbouring points so the previous answer stays a good hint.
constexpr int kGrain = 2048;

}  // namespace

const char* methodName(DistanceMethod method) { return method == DistanceMethod::Vertices ? "vertices" : "triangles"; }

namespace {

// The values that stand at positions `ranks` (each below values.size()) of `values` sorted, for
// finite values in any order. The values are spread over buckets by where they lie between the
// minimum and the maximum; that map is monotonic (even rounded), so the buckets are in value order
// and only the few holding the wanted ranks need a selection. Linear time, two passes for the
// buckets and one to gather, instead of selections over everything.
std::vector<double> orderStatistics(const std::vector<double>& values, const std::vector<size_t>& ranks) {
  const auto [minIt, maxIt] = std::minmax_element(values.begin(), values.end());
  const double lo = *minIt, hi = *maxIt;
  if (!(hi > lo)) return std::vector<double>(ranks.size(), lo);
  constexpr int kBuckets = 4096;
  const double scale = kBuckets / (hi - lo);
  std::vector<uint16_t> bucket(values.size());
  std::vector<size_t> first(kBuckets + 1, 0);  // first[b + 1]: values in buckets 0..b
  for (size_t i = 0; i < values.size(); ++i) {
    bucket[i] = static_cast<uint16_t>(std::min(kBuckets - 1, static_cast<int>((values[i] - lo) * scale)));
    ++first[bucket[i] + 1u];
  }
  for (int b = 0; b < kBuckets; ++b) first[static_cast<size_t>(b) + 1] += first[static_cast<size_t>(b)];
  // The bucket of each rank, and the values of those buckets (slot[b]: where bucket b's go, -1 if unwanted).
  std::vector<int> rankBucket, slot(kBuckets, -1);
  std::vector<std::vector<double>> members;
  for (size_t r : ranks) {
    const int b = static_cast<int>(std::upper_bound(first.begin(), first.end(), r) - first.begin()) - 1;
    rankBucket.push_back(b);
    if (slot[static_cast<size_t>(b)] < 0) {
      slot[static_cast<size_t>(b)] = static_cast<int>(members.size());
      members.emplace_back();
    }
  }
  for (size_t i = 0; i < values.size(); ++i)
    if (const int k = slot[bucket[i]]; k >= 0) members[static_cast<size_t>(k)].push_back(values[i]);
  std::vector<double> out;
  for (size_t i = 0; i < ranks.size(); ++i) {
    std::vector<double>& m = members[static_cast<size_t>(slot[static_cast<size_t>(rankBucket[i])])];
    const auto nth = m.begin() + static_cast<std::ptrdiff_t>(ranks[i] - first[static_cast<size_t>(rankBucket[i])]);
    std::nth_element(m.begin(), nth, m.end());
    out.push_back(*nth);
  }
  return out;
}

// The qs-quantiles of `values` (non-empty), as percentile() defines them.
std::vector<double> quantiles(const std::vector<double>& values, const std::vector<double>& qs) {
  std::vector<size_t> ranks;
  for (double q : qs) {
    const size_t lo = static_cast<size_t>(std::floor(q * static_cast<double>(values.size() - 1)));
    ranks.push_back(lo);
    ranks.push_back(std::min(lo + 1, values.size() - 1));
  }
  const std::vector<double> at = orderStatistics(values, ranks);
  std::vector<double> out;
  for (size_t i = 0; i < qs.size(); ++i) {
    const double h = qs[i] * static_cast<double>(values.size() - 1);
    const double a = at[2 * i], b = at[2 * i + 1];
    out.push_back(a + (h - std::floor(h)) * (b - a));
  }
  return out;
}

}  // namespace

double percentile(const std::vector<double>& values, double q) { return values.empty() ? kNaN : quantiles(values, {q})[0]; }

DistanceStats summarize(const std::vector<double>& distances, const std::vector<double>& signedDistances,
                        const std::vector<char>& within) {
  if (!signedDistances.empty() && signedDistances.size() != distances.size())
    throw std::invalid_argument("summarize: " + std::to_string(signedDistances.size()) + " signed distances for " +
                                std::to_string(distances.size()) + " distances");
  if (!within.empty() && within.size() != distances.size())
    throw std::invalid_argument("summarize: " + std::to_string(within.size()) + " flags for " + std::to_string(distances.size()) +
                                " distances");
  DistanceStats s;
  std::vector<double> kept;
  kept.reserve(distances.size());
  double sum = 0, sum2 = 0, signedSum = 0, max = 0;
  for (size_t i = 0; i < distances.size(); ++i) {
    if (!within.empty() && !within[i]) {
      ++s.beyond;
      continue;
    }
    const double d = distances[i];
    kept.push_back(d);
    sum += d;
    sum2 += d * d;
    max = std::max(max, d);
    if (!signedDistances.empty()) signedSum += signedDistances[i];
  }
  s.count = static_cast<int>(kept.size());
  if (s.count == 0) return s;
  const double n = static_cast<double>(s.count);
  s.mean = sum / n;
  s.meanSquared = sum2 / n;
  s.rms = std::sqrt(s.meanSquared);
  s.max = max;
  if (!signedDistances.empty()) s.signedMean = signedSum / n;
  const std::vector<double> q = quantiles(kept, {0.5, 0.95});
  s.median = q[0];
  s.p95 = q[1];
  return s;
}

CloudDistance::CloudDistance(const TriangleList& triangles, int numVertices, const DistanceOptions& options)
    : options_(options), triangles_(triangles), numVertices_(numVertices) {
  if (triangles.cols() == 0) throw std::invalid_argument("CloudDistance: the surface has no triangles");
  if (options.factor < 1) throw std::invalid_argument("CloudDistance: the factor must be at least 1, got " + std::to_string(options.factor));
  if (!(options.maxDistance >= 0)) throw std::invalid_argument("CloudDistance: the cut-off distance must be >= 0");
  // superSample checks the indices (for both methods: it is cheap and the sampling is also the
  // Vertices method's attribution of samples to vertices).
  sampling_ = superSample(triangles, numVertices, options.method == DistanceMethod::Vertices ? options.factor : 1);
  if (options.method == DistanceMethod::Vertices) return;

  // Edge ids: edges sorted by their vertex pair; triangleEdges_(k, t) is the edge from vertex k to k + 1.
  const Eigen::Index m = triangles.cols();
  std::vector<std::pair<std::pair<int, int>, int>> halfEdges;  // (sorted vertex pair, 3 t + k)
  halfEdges.reserve(static_cast<size_t>(3 * m));
  for (Eigen::Index t = 0; t < m; ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = triangles(k, t), b = triangles((k + 1) % 3, t);
      halfEdges.push_back({{std::min(a, b), std::max(a, b)}, static_cast<int>(3 * t + k)});
    }
  std::sort(halfEdges.begin(), halfEdges.end());
  triangleEdges_.resize(3, m);
  numEdges_ = 0;
  for (size_t i = 0; i < halfEdges.size(); ++i) {
    if (i > 0 && halfEdges[i].first != halfEdges[i - 1].first) ++numEdges_;
    triangleEdges_(halfEdges[i].second % 3, halfEdges[i].second / 3) = numEdges_;
  }
  ++numEdges_;
}

void CloudDistance::setSurface(const Eigen::Matrix3Xd& x) {
  if (x.cols() != numVertices_)
    throw std::invalid_argument("CloudDistance::setSurface: " + std::to_string(x.cols()) + " positions for a surface of " +
                                std::to_string(numVertices_) + " vertices");
  if (options_.method == DistanceMethod::Vertices) {
    sampling_.sample(x, samples_);
    tree_.build(samples_);
  } else {
    if (placed_) index_.update(x);
    else index_.build(x, triangles_);
    updatePseudoNormals(x);
  }
  placed_ = true;
}

void CloudDistance::updatePseudoNormals(const Eigen::Matrix3Xd& x) {
  const Eigen::Index m = triangles_.cols();
  faceNormals_.resize(3, m);
  edgeNormals_.setZero(3, numEdges_);
  vertexNormals_.setZero(3, numVertices_);
  for (Eigen::Index t = 0; t < m; ++t) {
    const Eigen::Vector3d n = index_.normal(static_cast<int>(t));
    faceNormals_.col(t) = n;
    for (int k = 0; k < 3; ++k) {
      edgeNormals_.col(triangleEdges_(k, t)) += n;
      // The angle of the triangle at vertex k weighs its normal in the vertex's pseudo-normal.
      const Eigen::Vector3d u = x.col(triangles_((k + 1) % 3, t)) - x.col(triangles_(k, t));
      const Eigen::Vector3d v = x.col(triangles_((k + 2) % 3, t)) - x.col(triangles_(k, t));
      vertexNormals_.col(triangles_(k, t)) += std::atan2(u.cross(v).norm(), u.dot(v)) * n;
    }
  }
}

void CloudDistance::measureRange(const Eigen::Matrix3Xd& cloud, int first, int last, DistanceResult& out) const {
  int hint = -1;
  if (options_.method == DistanceMethod::Vertices) {
    for (int i = first; i < last; ++i) {
      const Eigen::Vector3d p = cloud.col(i);
      const KdTree::Nearest nn = tree_.nearest(p, kInf, hint);
      hint = nn.index;
      out.nearest[static_cast<size_t>(i)] = nn.index;
      out.distance[static_cast<size_t>(i)] = std::sqrt(nn.distance2);
      out.residual.col(i) = samples_.col(nn.index) - p;
    }
    return;
  }
  for (int i = first; i < last; ++i) {
    const Eigen::Vector3d p = cloud.col(i);
    const SurfaceIndex::Hit hit = index_.closest(p, kInf, hint);
    hint = hit.triangle;
    const int t = hit.triangle;
    const double d = std::sqrt(hit.distance2);
    out.nearest[static_cast<size_t>(i)] = t;
    out.distance[static_cast<size_t>(i)] = d;
    out.residual.col(i) = hit.point - p;
    out.barycentric.col(i) = Eigen::Vector3d(hit.w[0], hit.w[1], hit.w[2]);
    // The pseudo-normal of the feature the closest point lies on: the face, an edge (regions 1-3:
    // ab, bc, ca) or a vertex (regions 4-6: a, b, c).
    Eigen::Vector3d normal;
    if (hit.region == 0) normal = faceNormals_.col(t);
    else if (hit.region <= 3) normal = edgeNormals_.col(triangleEdges_(hit.region - 1, t));
    else normal = vertexNormals_.col(triangles_(hit.region - 4, t));
    out.signedDistance[static_cast<size_t>(i)] = (p - hit.point).dot(normal) < 0 ? -d : d;
  }
}

void CloudDistance::attribute(DistanceResult& out) const {
  Eigen::Matrix3Xd residualSum = Eigen::Matrix3Xd::Zero(3, numVertices_);
  std::vector<double> distanceSum(static_cast<size_t>(numVertices_), 0.0), weightSum(static_cast<size_t>(numVertices_), 0.0);
  out.pointCount.assign(static_cast<size_t>(numVertices_), 0);
  // Adds `count` points with summed residual r and summed distance d to vertex v with weight w.
  auto add = [&](int v, double w, const Eigen::Vector3d& r, double d, int count) {
    if (w <= 0) return;
    residualSum.col(v) += w * r;
    distanceSum[static_cast<size_t>(v)] += w * d;
    weightSum[static_cast<size_t>(v)] += w * count;
    out.pointCount[static_cast<size_t>(v)] += count;
  };
  if (options_.method == DistanceMethod::Vertices) {
    // Every point of a sample shares its weights: sum per sample first (in point order), then
    // spread each sample's sums over its vertices.
    const int numSamples = sampling_.numSamples();
    Eigen::Matrix3Xd sampleResidual = Eigen::Matrix3Xd::Zero(3, numSamples);
    std::vector<double> sampleDistance(static_cast<size_t>(numSamples), 0.0);
    std::vector<int> sampleCount(static_cast<size_t>(numSamples), 0);
    for (size_t i = 0; i < out.distance.size(); ++i) {
      if (!out.within[i]) continue;
      const int s = out.nearest[i];
      sampleResidual.col(s) += out.residual.col(static_cast<Eigen::Index>(i));
      sampleDistance[static_cast<size_t>(s)] += out.distance[i];
      ++sampleCount[static_cast<size_t>(s)];
    }
    const int* outer = sampling_.weights.outerIndexPtr();
    const int* inner = sampling_.weights.innerIndexPtr();
    const double* weights = sampling_.weights.valuePtr();
    for (int s = 0; s < numSamples; ++s) {
      if (sampleCount[static_cast<size_t>(s)] == 0) continue;
      for (int k = outer[s]; k < outer[s + 1]; ++k)
        add(inner[k], weights[k], sampleResidual.col(s), sampleDistance[static_cast<size_t>(s)], sampleCount[static_cast<size_t>(s)]);
    }
  } else {
    for (size_t i = 0; i < out.distance.size(); ++i) {
      if (!out.within[i]) continue;
      const Eigen::Index c = static_cast<Eigen::Index>(i);
      for (int k = 0; k < 3; ++k) add(triangles_(k, out.nearest[i]), out.barycentric(k, c), out.residual.col(c), out.distance[i], 1);
    }
  }
  out.meanResidual.resize(3, numVertices_);
  out.meanDistance.resize(static_cast<size_t>(numVertices_));
  for (int v = 0; v < numVertices_; ++v) {
    const double w = weightSum[static_cast<size_t>(v)];
    out.meanResidual.col(v) = w > 0 ? Eigen::Vector3d(residualSum.col(v) / w) : Eigen::Vector3d::Constant(kNaN);
    out.meanDistance[static_cast<size_t>(v)] = w > 0 ? distanceSum[static_cast<size_t>(v)] / w : kNaN;
  }
}

void CloudDistance::measure(const Eigen::Matrix3Xd& cloud, DistanceResult& out) const {
  if (!placed_) throw std::logic_error("CloudDistance::measure: setSurface() was not called");
  if (!cloud.allFinite()) throw std::invalid_argument("CloudDistance::measure: the cloud has non-finite coordinates");
  const int n = static_cast<int>(cloud.cols());
  const bool triangles = options_.method == DistanceMethod::Triangles;
  out.distance.resize(static_cast<size_t>(n));
  out.residual.resize(3, n);
  out.nearest.resize(static_cast<size_t>(n));
  out.signedDistance.resize(triangles ? static_cast<size_t>(n) : 0);
  out.barycentric.resize(3, triangles ? n : 0);
  if (options_.parallel && n > kGrain)
    tbb::parallel_for(tbb::blocked_range<int>(0, n, kGrain),
                      [&](const tbb::blocked_range<int>& r) { measureRange(cloud, r.begin(), r.end(), out); });
  else
    measureRange(cloud, 0, n, out);
  out.maxDistance = options_.maxDistance;
  out.within.resize(static_cast<size_t>(n));
  for (size_t i = 0; i < out.distance.size(); ++i) out.within[i] = out.distance[i] <= options_.maxDistance;
  out.stats = summarize(out.distance, out.signedDistance, out.within);
  attribute(out);
}

DistanceResult CloudDistance::measure(const Eigen::Matrix3Xd& cloud) const {
  DistanceResult out;
  measure(cloud, out);
  return out;
}

void writeCloudResiduals(const std::string& path, const Eigen::Matrix3Xd& cloud, const DistanceResult& result,
                         const io::VtuWriteOptions& options) {
  std::vector<io::DataArray> fields;
  fields.push_back({"distance", 1, result.distance});
  fields.push_back({"residual", 3, std::vector<double>(result.residual.data(), result.residual.data() + result.residual.size())});
  if (!result.signedDistance.empty()) fields.push_back({"signedDistance", 1, result.signedDistance});
  if (std::isfinite(result.maxDistance)) fields.push_back({"within", 1, std::vector<double>(result.within.begin(), result.within.end())});
  io::writeVtp(path, cloud, TriangleList(3, 0), true, fields, options);
}

void writeSurfaceResiduals(const std::string& path, const Eigen::Matrix3Xd& x, const TriangleList& triangles,
                           const DistanceResult& result, const io::VtuWriteOptions& options) {
  std::vector<io::DataArray> fields;
  fields.push_back(
      {"meanResidual", 3, std::vector<double>(result.meanResidual.data(), result.meanResidual.data() + result.meanResidual.size())});
  fields.push_back({"meanDistance", 1, result.meanDistance});
  fields.push_back({"pointCount", 1, std::vector<double>(result.pointCount.begin(), result.pointCount.end())});
  io::writeVtp(path, x, triangles, false, fields, options);
}

}  // namespace viscera::obs
