#include <Eigen/Dense>
#include "engine/fem/TetKernel.h"

#include <Eigen/LU>
#include <cmath>
#include <stdexcept>

namespace viscera::fem {

namespace {

Eigen::Matrix3d edgeRows(const Mat34& p) {
  Eigen::Matrix3d A;
  A.row(0) = (p.col(1) - p.col(0)).transpose();
  A.row(1) = (p.col(2) - p.col(0)).transpose();
  A.row(2) = (p.col(3) - p.col(0)).transpose();
  return A;
}

Eigen::Matrix3d cofactor(const Eigen::Matrix3d& M) {
  Eigen::Matrix3d C;
  C.row(0) = M.row(1).cross(M.row(2));
  C.row(1) = M.row(2).cross(M.row(0));
  C.row(2) = M.row(0).cross(M.row(1));
  return C;
}

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d S;
  S << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return S;
}

}  // namespace

Eigen::Matrix3d frameLarge(const Mat34& p) {
  Eigen::Vector3d ex = (p.col(1) - p.col(0)).normalized();
  Eigen::Vector3d ez = ex.cross(p.col(2) - p.col(0)).normalized();
  Eigen::Vector3d ey = ez.cross(ex);
  Eigen::Matrix3d R;
  R.row(0) = ex.transpose();
  R.row(1) = ey.transpose();
  R.row(2) = ez.transpose();
  return R;
}

Eigen::Matrix3d polarFactor(const Eigen::Matrix3d& A) {
  // Scaled Newton iteration X <- (g X + X^-T / g) / 2, with X^-T = cof(X) / det(X).
  Eigen::Matrix3d X = A;
  for (int it = 0; it < 30; ++it) {
    const Eigen::Matrix3d C = cofactor(X);
    const double det = X.row(0).dot(C.row(0));
    if (det == 0.0 || !std::isfinite(det)) break;
    const Eigen::Matrix3d Xinvt = C / det;
    const double g = std::sqrt(std::sqrt((Xinvt.cwiseAbs().colwise().sum().maxCoeff() * Xinvt.cwiseAbs().rowwise().sum().maxCoeff()) /
                                         (X.cwiseAbs().colwise().sum().maxCoeff() * X.cwiseAbs().rowwise().sum().maxCoeff())));
    const Eigen::Matrix3d next = 0.5 * (g * X + Xinvt / g);
    const double change = (next - X).cwiseAbs().colwise().sum().maxCoeff();
    X = next;
    if (change <= 1e-14 * X.cwiseAbs().colwise().sum().maxCoeff()) break;
  }
  return X;
}

Eigen::Matrix3d framePolar(const Mat34& p) { return polarFactor(edgeRows(p)); }

Eigen::Matrix3d frame(Method m, const Mat34& p) {
  switch (m) {
    case Method::Small: return Eigen::Matrix3d::Identity();
    case Method::Large: return frameLarge(p);
    case Method::Polar: return framePolar(p);
  }
  return Eigen::Matrix3d::Identity();
}

Eigen::Matrix3d frameDerivative(Method m, const Mat34& p, const Eigen::Matrix3d& R, int node, int dir) {
  if (m == Method::Small) return Eigen::Matrix3d::Zero();
  const Eigen::Vector3d e = Eigen::Vector3d::Unit(dir);
  if (m == Method::Large) {
    const Eigen::Vector3d a = p.col(1) - p.col(0), b = p.col(2) - p.col(0);
    const Eigen::Vector3d da = ((node == 1) - (node == 0)) * e, db = ((node == 2) - (node == 0)) * e;
    const Eigen::Vector3d ex = R.row(0).transpose(), ez = R.row(2).transpose();
    const Eigen::Vector3d dex = (da - ex * ex.dot(da)) / a.norm();
    const Eigen::Vector3d w = ex.cross(b);
    const Eigen::Vector3d dw = dex.cross(b) + ex.cross(db);
    const Eigen::Vector3d dez = (dw - ez * ez.dot(dw)) / w.norm();
    const Eigen::Vector3d dey = dez.cross(ex) + ez.cross(dex);
    Eigen::Matrix3d dR;
    dR.row(0) = dex.transpose();
    dR.row(1) = dey.transpose();
    dR.row(2) = dez.transpose();
    return dR;
  }
  // Polar: A = R S; R^T dA - dA^T R = [ (tr S I - S) w ]x and dR = R [w]x.
  const Eigen::Matrix3d A = edgeRows(p);
  Eigen::Matrix3d dA = Eigen::Matrix3d::Zero();
  for (int k = 1; k <= 3; ++k) dA.row(k - 1) = (((node == k) - (node == 0)) * e).transpose();
  const Eigen::Matrix3d S = R.transpose() * A;
  const Eigen::Matrix3d W = R.transpose() * dA - dA.transpose() * R;
  const Eigen::Vector3d rhs(W(2, 1), W(0, 2), W(1, 0));
  const Eigen::Vector3d w = (S.trace() * Eigen::Matrix3d::Identity() - 0.5 * (S + S.transpose())).inverse() * rhs;
  return R * skew(w);
}

ElementRest restElement(Method m, const Mat34& Xw, const Lame& lame) {
  ElementRest e;
  e.lame = lame;
  const Eigen::Matrix3d R0 = frame(m, Xw);
  e.X = localPositions(m, R0, Xw);
  Eigen::Matrix3d E;
  E << e.X.col(1) - e.X.col(0), e.X.col(2) - e.X.col(0), e.X.col(3) - e.X.col(0);
  const double det = E.determinant();
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) throw std::domain_error("degenerate tetrahedron");
  e.volume = std::abs(det) / 6.0;
  // Orientation in the world: the polar frame of a negatively oriented element is a reflection.
  e.sign = det * R0.determinant() > 0 ? 1.0 : -1.0;
  // Rows of E^-1 are the gradients of N1..N3; N0 = 1 - N1 - N2 - N3.
  const Eigen::Matrix3d Einv = E.inverse();
  e.G.col(1) = Einv.row(0).transpose();
  e.G.col(2) = Einv.row(1).transpose();
  e.G.col(3) = Einv.row(2).transpose();
  e.G.col(0) = -(e.G.col(1) + e.G.col(2) + e.G.col(3));
  return e;
}

Eigen::Matrix3d stress(const ElementRest& e, const Mat34& U) {
  return e.lame.stress(U * e.G.transpose());
}

Mat34 plasticForce(const ElementRest& e, const Mat34& U, const Plasticity& law, Eigen::Ref<Voigt> P) {
  const Eigen::Matrix3d H = U * e.G.transpose();
  const Voigt total = (Voigt() << H(0, 0), H(1, 1), H(2, 2), H(0, 1) + H(1, 0), H(1, 2) + H(2, 1), H(2, 0) + H(0, 2)).finished();
  const double scale = 6.0 * e.volume;  // SOFA's strain is 6 V times this one
  const Voigt elastic = total - P;
  if (scale * scale * elastic.squaredNorm() > law.yield * law.yield) P += law.creep * elastic;
  const double n2 = scale * scale * P.squaredNorm();
  if (n2 > law.max * law.max) P *= law.max / std::sqrt(n2);
  const Voigt r = total - P;
  Eigen::Matrix3d eps;
  eps << r[0], 0.5 * r[3], 0.5 * r[5], 0.5 * r[3], r[1], 0.5 * r[4], 0.5 * r[5], 0.5 * r[4], r[2];
  const Eigen::Matrix3d sigma = e.lame.lambda * eps.trace() * Eigen::Matrix3d::Identity() + 2.0 * e.lame.mu * eps;
  return -e.volume * sigma * e.G;
}

double vonMises(const Eigen::Matrix3d& s) {
  const double a = s(0, 0) - s(1, 1), b = s(1, 1) - s(2, 2), c = s(2, 2) - s(0, 0);
  return std::sqrt(0.5 * (a * a + b * b + c * c) + 3.0 * (s(0, 1) * s(0, 1) + s(1, 2) * s(1, 2) + s(2, 0) * s(2, 0)));
}

Mat34 elementForce(Method m, const ElementRest& e, const Mat34& x, Eigen::Matrix3d& R) {
  R = frame(m, x);
  const Mat34 U = localPositions(m, R, x) - e.X;
  return R.transpose() * elasticForce(e, U);
}

Eigen::Matrix3d frameSvd(const ElementRest& e, const Mat34& x) {
  Eigen::Matrix3d Ecur;
  Ecur << x.col(1) - x.col(0), x.col(2) - x.col(0), x.col(3) - x.col(0);
  const double J = Ecur.determinant() / (e.sign * 6.0 * e.volume);
  if (J >= 1e-6) return framePolar(x);
  // F_local maps the rest edges in the element frame to the current edges in the world:
  // F_local = F R0^T, whose rotation factor is Q R0^T; the frame is R0 Q^T, its transpose.
  Eigen::Matrix3d restInverse;  // rows: gradients of N1..N3, the inverse of the local rest edges
  restInverse << e.G.col(1).transpose(), e.G.col(2).transpose(), e.G.col(3).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(Ecur * restInverse, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  // det(rotation factor) = e.sign, as the rest frame (a reflection for a negatively oriented element).
  D(2, 2) = e.sign * (svd.matrixU() * svd.matrixV().transpose()).determinant() > 0 ? 1.0 : -1.0;
  return (svd.matrixU() * D * svd.matrixV().transpose()).transpose();
}

Mat34 elementForceInFrame(const ElementRest& e, const Mat34& x, const Eigen::Matrix3d& R) {
  return R.transpose() * elasticForce(e, localPositions(Method::Polar, R, x) - e.X);
}

Mat12 elementStiffness(Method m, const ElementRest& e, const Eigen::Matrix3d& R) {
  // Block (i, j) = -V times the law's coupling of the rotated gradients h = R^T G.
  const Mat34 h = R.transpose() * e.G;
  Mat12 K;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) K.block<3, 3>(3 * i, 3 * j) = -e.volume * e.lame.coupling(h.col(i), h.col(j), e.G.col(i).dot(e.G.col(j)));
  return K;
}

Mat12 elementTangent(Method m, const ElementRest& e, const Mat34& x) {
  Eigen::Matrix3d R;
  elementForce(m, e, x, R);
  if (m == Method::Small) return elementStiffness(m, e, R);
  const Mat34 Floc = elasticForce(e, localPositions(m, R, x) - e.X);
  Mat12 K;
  for (int node = 0; node < 4; ++node)
    for (int dir = 0; dir < 3; ++dir) {
      const Eigen::Matrix3d dR = frameDerivative(m, x, R, node, dir);
      Mat34 dx = Mat34::Zero();
      dx(dir, node) = 1.0;
      // dY = dR (x - c) + R (dx - dc), c = x0 for large, 0 for polar.
      Mat34 dY = m == Method::Large ? Mat34(dR * (x.colwise() - x.col(0)) + R * (dx.colwise() - dx.col(0)))
                                    : Mat34(dR * x + R * dx);
      // f = R^T L(Y - X), with L linear.
      const Mat34 df = dR.transpose() * Floc + R.transpose() * elasticForce(e, dY);
      K.col(3 * node + dir) = Eigen::Map<const Eigen::Matrix<double, 12, 1>>(df.data());
    }
  return K;
}

double elementEnergy(Method m, const ElementRest& e, const Mat34& x) {
  const Eigen::Matrix3d R = frame(m, x);
  const Mat34 U = localPositions(m, R, x) - e.X;
  const Mat34 f = elasticForce(e, U);
  return -0.5 * (U.cwiseProduct(f)).sum();
}

}  // namespace viscera::fem
