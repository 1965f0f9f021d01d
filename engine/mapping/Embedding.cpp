#include "engine/mapping/Embedding.h"

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include "engine/collision/Geometry.h"

namespace viscera {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Barycentric coordinates are computed with round-off; a point on a face shared by two
// tetrahedra, or on the mesh boundary, may come out at -1e-16 for both. Coordinates down to this
// value count as inside (the point then sits within 1e-9 of an element size of the tetrahedron).
constexpr double kInsideTolerance = 1e-9;

// The faces of tetrahedron (n0, n1, n2, n3): face f is opposite node f.
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

// What a tetrahedron needs to give barycentric coordinates: its first node and the inverse of
// the 3 x 3 matrix whose columns are its edges from that node.
struct TetFrame {
  Eigen::Vector3d origin;
  Eigen::Matrix3d inverse;
  bool valid = false;  // false for a degenerate tetrahedron
};

Eigen::Vector4d barycentric(const TetFrame& f, const Eigen::Vector3d& p) {
  const Eigen::Vector3d l = f.inverse * (p - f.origin);
  return Eigen::Vector4d(1.0 - l.sum(), l[0], l[1], l[2]);
}

}  // namespace

int TetEmbedding::extrapolatedCount() const {
  int n = 0;
  for (int p = 0; p < size(); ++p) n += element[p] >= 0 && distance[p] > 0;
  return n;
}

int TetEmbedding::unplacedCount() const {
  int n = 0;
  for (int p = 0; p < size(); ++p) n += element[p] < 0;
  return n;
}

double distanceToTetrahedron(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  Eigen::Matrix3d m;
  m << b - a, c - a, d - a;
  const double det = m.determinant();
  if (det != 0) {
    const Eigen::Vector3d l = m.inverse() * (p - a);
    if (l.minCoeff() >= 0 && l.sum() <= 1) return 0.0;
  }
  const std::array<const Eigen::Vector3d*, 4> v = {&a, &b, &c, &d};
  double best = kInf;
  for (const auto& face : kFace) {
    const auto q = geom::closestOnTriangle(p, *v[face[0]], *v[face[1]], *v[face[2]]);
    best = std::min(best, (p - q.point).norm());
  }
  return best;
}

std::pair<int, double> nearestTetrahedron(const Eigen::Matrix3Xd& nodes, const TetList& tets, const Eigen::Vector3d& p) {
  std::pair<int, double> best{-1, kInf};
  for (int e = 0; e < tets.cols(); ++e) {
    const double d = distanceToTetrahedron(p, nodes.col(tets(0, e)), nodes.col(tets(1, e)), nodes.col(tets(2, e)),
                                           nodes.col(tets(3, e)));
    if (d < best.second) best = {e, d};
  }
  return best;
}

double meanEdgeLength(const Eigen::Matrix3Xd& nodes, const TetList& tets) {
  if (tets.cols() == 0) return 0.0;
  double sum = 0;
  for (int e = 0; e < tets.cols(); ++e)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) sum += (nodes.col(tets(i, e)) - nodes.col(tets(j, e))).norm();
  return sum / (6.0 * static_cast<double>(tets.cols()));
}

TetEmbedding embedInTetrahedra(const Eigen::Matrix3Xd& nodes, const TetList& tets, const Eigen::Matrix3Xd& points,
                               double maxDistance) {
  const int numTets = static_cast<int>(tets.cols());
  const int numPoints = static_cast<int>(points.cols());
  TetEmbedding out;
  out.nodes = TetList::Zero(4, numPoints);
  out.weights = Eigen::Matrix4Xd::Zero(4, numPoints);
  out.element = Eigen::VectorXi::Constant(numPoints, -1);
  out.distance = Eigen::VectorXd::Constant(numPoints, kInf);
  if (numTets == 0 || numPoints == 0) return out;

  // Per tetrahedron: its box for the hierarchy and its barycentric frame. A tetrahedron is
  // degenerate when its volume is negligible against the cube of its longest edge.
  std::vector<geom::AabbTree::Box> boxes(numTets);
  std::vector<TetFrame> frames(numTets);
  for (int e = 0; e < numTets; ++e) {
    const Eigen::Vector3d a = nodes.col(tets(0, e));
    Eigen::Matrix3d m;
    m << nodes.col(tets(1, e)) - a, nodes.col(tets(2, e)) - a, nodes.col(tets(3, e)) - a;
    for (int k = 0; k < 4; ++k) boxes[e].extend(nodes.col(tets(k, e)));
    const double longest = boxes[e].diagonal().norm();
    frames[e].origin = a;
    frames[e].valid = std::abs(m.determinant()) > 1e-12 * longest * longest * longest;
    if (frames[e].valid) frames[e].inverse = m.inverse();
  }
  geom::AabbTree tree;
  tree.build(boxes);

  // Points within round-off of a box still look for their tetrahedron in it.
  const Eigen::Vector3d pad = Eigen::Vector3d::Constant(kInsideTolerance * meanEdgeLength(nodes, tets));
  const Eigen::Vector3d reach = Eigen::Vector3d::Constant(maxDistance);
  for (int p = 0; p < numPoints; ++p) {
    const Eigen::Vector3d x = points.col(p);
    int best = -1;
    Eigen::Vector4d bestW;
    double bestMin = -kInf;
    tree.query(geom::AabbTree::Box(x - pad, x + pad), [&](int e) {
      if (!frames[e].valid) return;
      const Eigen::Vector4d w = barycentric(frames[e], x);
      const double lowest = w.minCoeff();
      if (lowest >= -kInsideTolerance && (lowest > bestMin || (lowest == bestMin && e < best))) {
        best = e;
        bestW = w;
        bestMin = lowest;
      }
    });
    double dist = 0.0;
    if (best < 0 && maxDistance > 0) {
      // Outside every tetrahedron: the nearest one within reach, extrapolated.
      dist = kInf;
      tree.query(geom::AabbTree::Box(x - reach, x + reach), [&](int e) {
        if (!frames[e].valid) return;
        const double d = distanceToTetrahedron(x, nodes.col(tets(0, e)), nodes.col(tets(1, e)), nodes.col(tets(2, e)),
                                               nodes.col(tets(3, e)));
        if (d <= maxDistance && (d < dist || (d == dist && e < best))) {
          best = e;
          dist = d;
        }
      });
      if (best >= 0) bestW = barycentric(frames[best], x);
    }
    if (best < 0) continue;
    out.element[p] = best;
    out.distance[p] = dist;
    out.nodes.col(p) = tets.col(best);
    out.weights.col(p) = bestW;
  }
  return out;
}

void applyEmbedding(const TetEmbedding& embedding, const Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& out) {
  const int n = embedding.size();
  out.resize(3, n);
  for (int p = 0; p < n; ++p) {
    const auto& idx = embedding.nodes.col(p);
    const auto& w = embedding.weights.col(p);
    out.col(p) = w[0] * x.col(idx[0]) + w[1] * x.col(idx[1]) + w[2] * x.col(idx[2]) + w[3] * x.col(idx[3]);
  }
}


namespace {

// Trilinear shape functions of a hexahedron in SOFA's node order at local coordinates u in [0,1]^3,
// and their derivatives (8 x 3).
void trilinear(const Eigen::Vector3d& u, Eigen::Matrix<double, 8, 1>& N, Eigen::Matrix<double, 8, 3>& dN) {
  static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  for (int k = 0; k < 8; ++k) {
    double f[3], d[3];
    for (int a = 0; a < 3; ++a) {
      f[a] = corner[k][a] ? u[a] : 1 - u[a];
      d[a] = corner[k][a] ? 1.0 : -1.0;
    }
    N[k] = f[0] * f[1] * f[2];
    dN.row(k) << d[0] * f[1] * f[2], f[0] * d[1] * f[2], f[0] * f[1] * d[2];
  }
}

// Local coordinates of p in hexahedron h (Newton from its centre); false if it does not converge.
bool localCoordinates(const Eigen::Matrix<double, 3, 8>& X, const Eigen::Vector3d& p, Eigen::Vector3d& u) {
  u = Eigen::Vector3d::Constant(0.5);
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> dN;
  const double scale = (X.rowwise().maxCoeff() - X.rowwise().minCoeff()).norm();
  for (int it = 0; it < 30; ++it) {
    trilinear(u, N, dN);
    const Eigen::Vector3d r = X * N - p;
    if (r.norm() <= 1e-13 * scale) return true;
    const Eigen::Matrix3d J = X * dN;
    const Eigen::Vector3d step = J.fullPivLu().solve(r);
    if (!step.allFinite()) return false;
    u -= step;
  }
  trilinear(u, N, dN);
  return (X * N - p).norm() <= 1e-9 * scale;
}

double boxDistance(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const Eigen::Vector3d& p) {
  return (p.cwiseMax(lo).cwiseMin(hi) - p).norm();
}

}  // namespace

int HexEmbedding::extrapolatedCount() const {
  int n = 0;
  for (int p = 0; p < size(); ++p) n += distance[p] > 0;
  return n;
}

HexEmbedding embedInHexahedra(const Eigen::Matrix3Xd& nodes, const HexList& hexa, const Eigen::Matrix3Xd& points) {
  const int n = static_cast<int>(points.cols());
  HexEmbedding e;
  e.nodes.resize(8, n);
  e.weights.resize(8, n);
  e.distance.resize(n);
  std::vector<Eigen::Matrix<double, 3, 8>> X(hexa.size());
  std::vector<Eigen::Vector3d> lo(hexa.size()), hi(hexa.size());
  for (size_t h = 0; h < hexa.size(); ++h) {
    for (int k = 0; k < 8; ++k) X[h].col(k) = nodes.col(hexa[h][k]);
    lo[h] = X[h].rowwise().minCoeff();
    hi[h] = X[h].rowwise().maxCoeff();
  }
  for (int p = 0; p < n; ++p) {
    const Eigen::Vector3d q = points.col(p);
    int chosen = -1;
    Eigen::Vector3d u;
    double nearest = std::numeric_limits<double>::infinity();
    int nearestHex = -1;
    for (size_t h = 0; h < hexa.size(); ++h) {
      const double d = boxDistance(lo[h], hi[h], q);
      if (d < nearest) {
        nearest = d;
        nearestHex = static_cast<int>(h);
      }
      if (d > 1e-9 * (hi[h] - lo[h]).norm()) continue;
      Eigen::Vector3d v;
      if (localCoordinates(X[h], q, v) && v.minCoeff() >= -1e-9 && v.maxCoeff() <= 1 + 1e-9) {
        chosen = static_cast<int>(h);
        u = v;
        break;
      }
    }
    double distance = 0;
    if (chosen < 0) {
      chosen = nearestHex;
      distance = std::max(nearest, 1e-300);  // outside: extrapolated
      if (!localCoordinates(X[chosen], q, u)) u = Eigen::Vector3d::Constant(0.5);
    }
    Eigen::Matrix<double, 8, 1> N;
    Eigen::Matrix<double, 8, 3> dN;
    trilinear(u, N, dN);
    for (int k = 0; k < 8; ++k) e.nodes(k, p) = hexa[chosen][k];
    e.weights.col(p) = N;
    e.distance[p] = distance;
  }
  return e;
}

void applyEmbedding(const HexEmbedding& embedding, const Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& out) {
  const int n = embedding.size();
  out.resize(3, n);
  for (int p = 0; p < n; ++p) {
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    for (int k = 0; k < 8; ++k) v += embedding.weights(k, p) * x.col(embedding.nodes(k, p));
    out.col(p) = v;
  }
}

}  // namespace viscera
