#include "observation/Registration.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string_view>

#include "core/Error.h"
#include "core/Text.h"

namespace viscera::obs {
namespace {

// ---------------------------------------------------------------------------------------------
// ICP

// One cloud point matched to its closest surface point.
struct Pair {
  int index = 0;                                   // column in the cloud
  Eigen::Vector3d y = Eigen::Vector3d::Zero();     // the cloud point under the current transform
  Eigen::Vector3d q = Eigen::Vector3d::Zero();     // its closest surface point
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();    // the surface normal there (sign irrelevant)
  double d = 0;                                    // |y - q|
};

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string vec3Text(const Eigen::Vector3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.3f, %.3f, %.3f)", v.x(), v.y(), v.z());
  return buf;
}

// A vector with its largest-magnitude component positive, so that reported directions do not
// depend on the eigen solver's sign choice.
template <class V>
V canonicalSign(V v) {
  Eigen::Index k;
  v.cwiseAbs().maxCoeff(&k);
  return v(k) < 0 ? V(-v) : v;
}

class IcpRun {
 public:
  IcpRun(const Eigen::Matrix3Xd& cloud, const SurfaceIndex& surface, const IcpOptions& o, const std::string& source)
      : cloud_(cloud), surface_(surface), o_(o), source_(source), hints_(static_cast<size_t>(cloud.cols()), -1) {
    const Eigen::Vector3d c = cloud.rowwise().mean();
    radius_ = std::sqrt((cloud.colwise() - c).colwise().squaredNorm().mean());
  }

  double radius() const { return radius_; }

  // The kept pairs for transform T and correspondence limit `limit`: of the cloud points whose
  // closest surface point is nearer than the limit, the closest `trim` fraction. `withinRms` is
  // the RMS distance of all pairs within the limit, before trimming.
  std::vector<Pair> correspond(const RigidTransform& T, double limit, double& withinRms) {
    std::vector<Pair> pairs;
    pairs.reserve(static_cast<size_t>(cloud_.cols()));
    const double limit2 = std::isinf(limit) ? limit : limit * limit;
    for (Eigen::Index i = 0; i < cloud_.cols(); ++i) {
      Pair p;
      p.index = static_cast<int>(i);
      p.y = T * cloud_.col(i);
      const SurfaceIndex::Hit hit = surface_.closest(p.y, limit2, hints_[static_cast<size_t>(i)]);
      if (hit.triangle < 0) continue;
      hints_[static_cast<size_t>(i)] = hit.triangle;
      p.q = hit.point;
      p.d = std::sqrt(hit.distance2);
      // On an edge or a vertex the surface normal is not unique; the direction to the point lies
      // in its normal cone and makes the plane residual the true distance.
      if (hit.region != 0 && p.d > 0) p.n = (p.y - p.q) / p.d;
      else p.n = surface_.normal(hit.triangle);
      if (p.n.squaredNorm() == 0) continue;  // a degenerate triangle has no plane
      pairs.push_back(p);
    }
    double sum2 = 0;
    for (const Pair& p : pairs) sum2 += p.d * p.d;
    withinRms = pairs.empty() ? 0.0 : std::sqrt(sum2 / static_cast<double>(pairs.size()));
    // Closest first; ties by index so that the kept set does not depend on the sort.
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.d < b.d || (a.d == b.d && a.index < b.index); });
    const size_t keep = std::min(pairs.size(), static_cast<size_t>(std::max<long long>(1, std::llround(o_.trim * static_cast<double>(pairs.size())))));
    pairs.resize(keep);
    if (pairs.size() < 6)
      throw Error(SourceLoc{source_},
                  "ICP: only " + std::to_string(pairs.size()) + " cloud point(s) have a surface point within the maximum distance " +
                      number(limit) + " (6 are needed for a rigid transform); check the initial transform and the maximum distance");
    return pairs;
  }

  // The point-to-plane normal equations at the pairs, in the scaled unknowns (w L, t) with w the
  // small rotation about `centre` and L the cloud's RMS radius: A (6 x 6) = sum J J^T / m,
  // b (6) = -sum J r / m, J = [(y - centre) x n / L; n], r = n . (y - q).
  void planeSystem(const std::vector<Pair>& pairs, const Eigen::Vector3d& centre, Eigen::Matrix<double, 6, 6>& A,
                   Eigen::Matrix<double, 6, 1>& b) const {
    A.setZero();
    b.setZero();
    for (const Pair& p : pairs) {
      Eigen::Matrix<double, 6, 1> J;
      J.head<3>() = (p.y - centre).cross(p.n) / radius_;
      J.tail<3>() = p.n;
      A.noalias() += J * J.transpose();
      b -= J * p.n.dot(p.y - p.q);
    }
    A /= static_cast<double>(pairs.size());
    b /= static_cast<double>(pairs.size());
  }

 private:
  const Eigen::Matrix3Xd& cloud_;
  const SurfaceIndex& surface_;
  const IcpOptions& o_;
  const std::string& source_;
  std::vector<int> hints_;  // each point's last closest triangle: coherent queries start near it
  double radius_ = 0;
};

Eigen::Vector3d centroid(const std::vector<Pair>& pairs) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const Pair& p : pairs) c += p.y;
  return c / static_cast<double>(pairs.size());
}

// The rigid increment y -> R (y - c) + c + t from the solution x = (w L, t) of the plane system,
// with R the exact rotation of the rotation vector w.
RigidTransform planeIncrement(const Eigen::Matrix<double, 6, 1>& x, const Eigen::Vector3d& c, double radius) {
  const Eigen::Vector3d w = x.head<3>() / radius;
  const double angle = w.norm();
  RigidTransform T = RigidTransform::Identity();
  if (angle > 0) T.linear() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  T.translation() = c + x.tail<3>() - T.linear() * c;
  return T;
}

// The point-to-point (Kabsch) increment taking the pairs' points to their closest surface points.
RigidTransform pointIncrement(const std::vector<Pair>& pairs) {
  Eigen::Matrix3Xd Y(3, pairs.size()), Q(3, pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    Y.col(static_cast<Eigen::Index>(k)) = pairs[k].y;
    Q.col(static_cast<Eigen::Index>(k)) = pairs[k].q;
  }
  RigidTransform T;
  T.matrix() = Eigen::umeyama(Y, Q, false);
  return T;
}

// The weakly constrained subspace of A (eigenvalues below ratio x the largest), in a basis whose
// vectors are each as purely rotation or purely translation as the subspace allows: the right
// singular vectors of its rotation block. For a plane this separates the rotation about the
// normal from the two in-plane translations, which the eigenvectors of a repeated eigenvalue
// would mix arbitrarily.
std::vector<WeakDirection> weakDirections(const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>& eig,
                                          const Eigen::Matrix<double, 6, 6>& A, double ratio) {
  const double top = eig.eigenvalues()(5);
  int k = 0;
  while (k < 6 && eig.eigenvalues()(k) < ratio * top) ++k;
  std::vector<WeakDirection> out;
  if (k == 0) return out;
  const Eigen::MatrixXd W = eig.eigenvectors().leftCols(k);  // 6 x k, orthonormal columns
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(W.topRows(3), Eigen::ComputeFullV);
  const Eigen::MatrixXd B = W * svd.matrixV();  // 6 x k, orthonormal, ordered by rotation content
  for (int j = 0; j < k; ++j) {
    const Eigen::Matrix<double, 6, 1> v = canonicalSign(Eigen::Matrix<double, 6, 1>(B.col(j)));
    WeakDirection d;
    d.rotation = v.head<3>();
    d.translation = v.tail<3>();
    d.ratio = v.dot(A * v) / top;
    out.push_back(d);
  }
  return out;
}

void checkOptions(const IcpOptions& o) {
  if (!(o.maxDistance > 0)) throw Error("ICP: the maximum distance must be > 0 (got " + number(o.maxDistance) + ")");
  if (!(o.shrinkFactor >= 0) || std::isinf(o.shrinkFactor))
    throw Error("ICP: the shrink factor must be a finite number >= 0 (got " + number(o.shrinkFactor) + ")");
  if (!(o.trim > 0 && o.trim <= 1)) throw Error("ICP: the trim fraction must be in (0, 1] (got " + number(o.trim) + ")");
  if (o.maxIterations < 1) throw Error("ICP: the number of iterations must be >= 1 (got " + std::to_string(o.maxIterations) + ")");
  if (!(o.tolerance > 0) || std::isinf(o.tolerance))
    throw Error("ICP: the tolerance must be a finite number > 0 (got " + number(o.tolerance) + ")");
  if (!(o.degeneracyRatio >= 0 && o.degeneracyRatio < 1))
    throw Error("ICP: the degeneracy ratio must be in [0, 1) (got " + number(o.degeneracyRatio) + ")");
}

}  // namespace

std::string WeakDirection::describe() const {
  const double r2 = rotation.squaredNorm();
  // More than 90 % of the (unit) motion in one part counts as that part alone.
  if (r2 >= 0.9) return "rotation about " + vec3Text(rotation.normalized());
  if (r2 <= 0.1) return "translation along " + vec3Text(translation.normalized());
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.2f", std::sqrt(r2));
  return "rotation about " + vec3Text(rotation.normalized()) + " with translation along " + vec3Text(translation.normalized()) +
         " (rotation share " + buf + ")";
}

IcpResult registerIcp(const Eigen::Matrix3Xd& cloud, const SurfaceIndex& surface, const RigidTransform& initial,
                      const IcpOptions& options, const std::string& source) {
  checkOptions(options);
  if (cloud.cols() == 0) throw Error(SourceLoc{source}, "ICP: the cloud has no points");
  if (cloud.cols() < 6)
    throw Error(SourceLoc{source}, "ICP: the cloud has " + std::to_string(cloud.cols()) + " points; at least 6 are needed");
  for (Eigen::Index i = 0; i < cloud.cols(); ++i)
    if (!cloud.col(i).allFinite()) throw Error(SourceLoc{source}, "ICP: point " + std::to_string(i) + " is not finite");
  if (surface.numTriangles() == 0) throw Error("ICP: the surface has no triangles");
  if (!initial.matrix().allFinite()) throw Error("ICP: the initial transform is not finite");

  IcpRun run(cloud, surface, options, source);
  if (!(run.radius() > 0)) throw Error(SourceLoc{source}, "ICP: all points of the cloud coincide");
  IcpResult res;
  RigidTransform T = initial;
  double limit = options.maxDistance;
  for (int it = 1; it <= options.maxIterations; ++it) {
    double withinRms = 0;
    const std::vector<Pair> pairs = run.correspond(T, limit, withinRms);
    const Eigen::Vector3d c = centroid(pairs);
    Eigen::Matrix<double, 6, 6> A;
    Eigen::Matrix<double, 6, 1> b;
    run.planeSystem(pairs, c, A, b);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(A, Eigen::EigenvaluesOnly);
    RigidTransform step;
    if (eig.eigenvalues()(0) >= options.degeneracyRatio * eig.eigenvalues()(5)) {
      step = planeIncrement(A.ldlt().solve(b), c, run.radius());
    } else {
      // Along a direction the planes do not constrain, the plane step would follow rounding and
      // the odd edge point; the point-to-point step stays put along it.
      step = pointIncrement(pairs);
      ++res.pointToPointIterations;
    }
    T = step * T;
    res.iterations = it;
    if (options.shrinkFactor > 0 && withinRms > 0) limit = std::min(limit, options.shrinkFactor * withinRms);
    const double angle = Eigen::AngleAxisd(step.linear()).angle();
    const double shift = (step * c - c).norm();
    if (angle <= options.tolerance && shift <= options.tolerance * run.radius()) {
      res.converged = true;
      break;
    }
  }

  // Residuals and conditioning at the final transform.
  double withinRms = 0;
  const std::vector<Pair> pairs = run.correspond(T, limit, withinRms);
  res.transform = T;
  res.finalMaxDistance = limit;
  res.pairs = static_cast<int>(pairs.size());
  res.keptFraction = static_cast<double>(pairs.size()) / static_cast<double>(cloud.cols());
  double sum = 0, sum2 = 0;
  for (const Pair& p : pairs) {
    sum += p.d;
    sum2 += p.d * p.d;
    res.max = std::max(res.max, p.d);
  }
  res.mean = sum / static_cast<double>(pairs.size());
  res.rms = std::sqrt(sum2 / static_cast<double>(pairs.size()));
  res.centroid = centroid(pairs);
  Eigen::Matrix<double, 6, 6> A;
  Eigen::Matrix<double, 6, 1> b;
  run.planeSystem(pairs, res.centroid, A, b);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(A);
  res.eigenvalues = eig.eigenvalues();
  res.conditionRatio = eig.eigenvalues()(0) / eig.eigenvalues()(5);
  res.degenerate = res.conditionRatio < options.degeneracyRatio;
  res.weakDirections = weakDirections(eig, A, options.degeneracyRatio);

  res.distances.resize(cloud.cols());
  res.kept.assign(static_cast<size_t>(cloud.cols()), false);
  for (const Pair& p : pairs) res.kept[static_cast<size_t>(p.index)] = true;
  int hint = -1;
  for (Eigen::Index i = 0; i < cloud.cols(); ++i) {
    const SurfaceIndex::Hit hit = surface.closest(T * cloud.col(i), std::numeric_limits<double>::infinity(), hint);
    hint = hit.triangle;
    res.distances(i) = std::sqrt(hit.distance2);
  }
  return res;
}

// ---------------------------------------------------------------------------------------------
// Corresponding points

namespace {

// Whether the points (3 x n, n >= 3) span a plane: their spread across the best-fit line must be
// at least this fraction of the spread along it, or the rotation about the line would rest on
// less than a thousandth of the set's extent.
constexpr double kMinSpreadRatio = 1e-3;

void checkSpread(const Eigen::Matrix3Xd& P, const std::string& what) {
  const Eigen::Matrix3Xd centred = P.colwise() - P.rowwise().mean();
  const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::Matrix3Xd>(centred).singularValues();
  const double scale = std::max(1.0, P.cwiseAbs().maxCoeff());
  if (!(s(0) > 1e-12 * scale)) throw Error(SourceLoc{what}, "all " + std::to_string(P.cols()) + " points coincide; a rigid transform needs 3 points not on a line");
  if (s(1) < kMinSpreadRatio * s(0)) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "the %d points are (nearly) collinear: their spread across the best-fit line is %.3g of the spread along it (at least %g needed)",
                  static_cast<int>(P.cols()), s(1) / s(0), kMinSpreadRatio);
    throw Error(SourceLoc{what}, std::string(buf) + "; the rotation about that line is undetermined");
  }
}

bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::string_view trimmed(std::string_view s) {
  while (!s.empty() && isBlank(s.front())) s.remove_prefix(1);
  while (!s.empty() && isBlank(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> splitCommas(std::string_view line) {
  std::vector<std::string_view> f;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    f.push_back(trimmed(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return f;
}


}  // namespace

PointRegistration registerPoints(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target, const std::string& sourceName,
                                 const std::string& targetName) {
  if (source.cols() != target.cols())
    throw Error(sourceName + " has " + std::to_string(source.cols()) + " points but " + targetName + " has " +
                std::to_string(target.cols()) + "; corresponding points come in pairs");
  if (source.cols() < 3)
    throw Error(SourceLoc{sourceName}, std::to_string(source.cols()) + " point(s): a rigid transform needs at least 3 corresponding points");
  for (Eigen::Index i = 0; i < source.cols(); ++i) {
    if (!source.col(i).allFinite()) throw Error(SourceLoc{sourceName}, "point " + std::to_string(i + 1) + " is not finite");
    if (!target.col(i).allFinite()) throw Error(SourceLoc{targetName}, "point " + std::to_string(i + 1) + " is not finite");
  }
  checkSpread(source, sourceName);
  checkSpread(target, targetName);

  PointRegistration r;
  r.transform.matrix() = Eigen::umeyama(source, target, false);
  r.residuals = (r.transform.linear() * source).colwise() + r.transform.translation();
  r.residuals -= target;
  r.norms = r.residuals.colwise().norm().transpose();
  r.rms = std::sqrt(r.norms.squaredNorm() / static_cast<double>(r.norms.size()));
  r.max = r.norms.maxCoeff();
  return r;
}

PointList parsePointList(const std::string& text, const std::string& source) {
  PointList list;
  list.source = source;
  std::vector<Eigen::Vector3d> pts;
  std::map<std::string, int> nameLine;
  int columns = 0;  // 3 or 4 once the first line with content is seen
  bool first = true;
  std::istringstream in(text);
  std::string raw;
  for (int lineNo = 1; std::getline(in, raw); ++lineNo) {
    const std::string_view line = trimmed(raw);
    if (line.empty() || line.front() == '#') continue;
    const auto f = splitCommas(line);
    const SourceLoc at{source, lineNo, 0};
    if (columns == 0) {
      if (f.size() != 3 && f.size() != 4)
        throw Error(at, "expected 3 columns (x,y,z) or 4 (name,x,y,z), found " + std::to_string(f.size()));
      columns = static_cast<int>(f.size());
    } else if (static_cast<int>(f.size()) != columns) {
      throw Error(at, "expected " + std::to_string(columns) + " columns (" + (columns == 3 ? "x,y,z" : "name,x,y,z") +
                          ") as on the first line, found " + std::to_string(f.size()));
    }
    const size_t c0 = static_cast<size_t>(columns - 3);
    double v[3];
    bool number[3];
    for (int k = 0; k < 3; ++k) number[k] = parseNumber(f[c0 + static_cast<size_t>(k)], v[k]);
    // A header is a first line none of whose coordinate fields is a number.
    if (first && !number[0] && !number[1] && !number[2]) {
      first = false;
      continue;
    }
    first = false;
    static const char* kAxis[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) {
      if (!number[k]) throw Error(at, std::string(kAxis[k]) + ": " + quoted(f[c0 + static_cast<size_t>(k)]) + " is not a number");
      if (!std::isfinite(v[k])) throw Error(at, std::string(kAxis[k]) + ": " + quoted(f[c0 + static_cast<size_t>(k)]) + " is not finite");
    }
    if (columns == 4) {
      const std::string name(f[0]);
      if (name.empty()) throw Error(at, "empty point name");
      auto [it, fresh] = nameLine.try_emplace(name, lineNo);
      if (!fresh) throw Error(at, "point name " + quoted(name) + " repeated (first on line " + std::to_string(it->second) + ")");
      list.names.push_back(name);
    }
    pts.emplace_back(v[0], v[1], v[2]);
    list.lines.push_back(lineNo);
  }
  if (pts.empty()) throw Error(SourceLoc{source}, "no points (expected lines x,y,z or name,x,y,z)");
  list.points.resize(3, static_cast<Eigen::Index>(pts.size()));
  for (size_t i = 0; i < pts.size(); ++i) list.points.col(static_cast<Eigen::Index>(i)) = pts[i];
  return list;
}

PointList readPointList(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(SourceLoc{path}, "cannot open point file");
  std::stringstream ss;
  ss << f.rdbuf();
  return parsePointList(ss.str(), path);
}

void pairPoints(const PointList& source, const PointList& target, Eigen::Matrix3Xd& sourceOut, Eigen::Matrix3Xd& targetOut,
                std::vector<std::string>& labels) {
  const bool sn = !source.names.empty(), tn = !target.names.empty();
  if (sn != tn)
    throw Error((sn ? source.source : target.source) + " names its points but " + (sn ? target.source : source.source) +
                " does not: give names in both files (points pair by name) or in neither (they pair by order)");
  labels.clear();
  if (!sn) {
    if (source.points.cols() != target.points.cols())
      throw Error(source.source + " has " + std::to_string(source.points.cols()) + " points but " + target.source + " has " +
                  std::to_string(target.points.cols()) + "; without names the points pair by order");
    sourceOut = source.points;
    targetOut = target.points;
    for (Eigen::Index i = 0; i < source.points.cols(); ++i) labels.push_back(std::to_string(i + 1));
    return;
  }
  std::map<std::string, Eigen::Index> inTarget, inSource;
  for (size_t i = 0; i < target.names.size(); ++i) inTarget[target.names[i]] = static_cast<Eigen::Index>(i);
  for (size_t i = 0; i < source.names.size(); ++i) inSource[source.names[i]] = static_cast<Eigen::Index>(i);
  for (size_t i = 0; i < source.names.size(); ++i)
    if (!inTarget.count(source.names[i]))
      throw Error(SourceLoc{source.source, source.lines[i], 0},
                  "point " + quoted(source.names[i]) + " has no point of the same name in " + target.source);
  for (size_t i = 0; i < target.names.size(); ++i)
    if (!inSource.count(target.names[i]))
      throw Error(SourceLoc{target.source, target.lines[i], 0},
                  "point " + quoted(target.names[i]) + " has no point of the same name in " + source.source);
  sourceOut = source.points;
  targetOut.resize(3, source.points.cols());
  for (size_t i = 0; i < source.names.size(); ++i) targetOut.col(static_cast<Eigen::Index>(i)) = target.points.col(inTarget[source.names[i]]);
  labels = source.names;
}

}  // namespace viscera::obs
