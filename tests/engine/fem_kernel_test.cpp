// Per-element kernels of the linear tetrahedron (engine/fem/TetKernel.h) checked against
// independent definitions: forces against finite differences of the energy, stiffnesses and
// tangents against finite differences of the force, the corotational stiffness against a
// textbook B^T D B built here, rigid-motion invariance, the polar decomposition and the svd frame
// of inverted elements.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <vector>

#include "engine/fem/TetKernel.h"

namespace fem = viscera::fem;
using fem::Mat12;
using fem::Mat34;
using fem::Method;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

const char* name(Method m) { return m == Method::Small ? "small" : m == Method::Large ? "large" : "polar"; }

struct Rng {
  std::mt19937_64 g;
  explicit Rng(unsigned long long seed) : g(seed) {}
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(g); }
  Mat34 mat34(double a) {
    Mat34 m;
    for (int i = 0; i < 12; ++i) m.data()[i] = uniform(-a, a);
    return m;
  }
  Matrix3d mat3(double a) {
    Matrix3d m;
    for (int i = 0; i < 9; ++i) m.data()[i] = uniform(-a, a);
    return m;
  }
  Vector3d unitVector() {
    Vector3d v;
    do v = Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    while (v.norm() < 0.1 || v.norm() > 1);
    return v.normalized();
  }
  // A rotation by an angle in [minAngle, maxAngle] about a random axis.
  Matrix3d rotation(double minAngle = 0.3, double maxAngle = M_PI) {
    return Eigen::AngleAxisd(uniform(minAngle, maxAngle), unitVector()).toRotationMatrix();
  }
};

// A random well-shaped tetrahedron: a regular one, mildly sheared (condition number of the
// shear < 3), scaled to edge ~ L in [0.5, 2], translated, and with either orientation.
Mat34 randomTet(Rng& r, double* sizeOut = nullptr) {
  Mat34 reg;
  reg << 1, 1, -1, -1,  //
      1, -1, 1, -1,     //
      1, -1, -1, 1;
  Matrix3d M;
  do M = Matrix3d::Identity() + r.mat3(0.3);
  while (M.determinant() < 0.3 || Eigen::JacobiSVD<Matrix3d>(M).singularValues()(0) /
                                          Eigen::JacobiSVD<Matrix3d>(M).singularValues()(2) > 3.0);
  const double s = r.uniform(0.5, 2.0);
  Mat34 X = (s * M * reg).colwise() + Vector3d(r.uniform(-5, 5), r.uniform(-5, 5), r.uniform(-5, 5));
  if (r.uniform(0, 1) < 0.5) X.col(1).swap(X.col(2));  // negative orientation
  if (sizeOut) *sizeOut = 2.0 * std::sqrt(2.0) * s;  // edge length of the regular tet scaled by s
  return X;
}

fem::Lame randomLame(Rng& r, double* E = nullptr, double* nu = nullptr) {
  const double e = r.uniform(1e3, 1e5), n = r.uniform(0.05, 0.45);
  if (E) *E = e;
  if (nu) *nu = n;
  return fem::Lame::fromYoungPoisson(e, n);
}

using Vec12 = Eigen::Matrix<double, 12, 1>;
Vec12 flat(const Mat34& m) { return Eigen::Map<const Vec12>(m.data()); }

// -dE/dx by central differences with step h.
Mat34 energyGradientFD(Method m, const fem::ElementRest& e, const Mat34& x, double h) {
  Mat34 g;
  for (int k = 0; k < 4; ++k)
    for (int d = 0; d < 3; ++d) {
      Mat34 xp = x, xm = x;
      xp(d, k) += h;
      xm(d, k) -= h;
      g(d, k) = -(fem::elementEnergy(m, e, xp) - fem::elementEnergy(m, e, xm)) / (2 * h);
    }
  return g;
}

// d(elementForce)/dx by central differences with step h (12 x 12, node-major).
Mat12 forceJacobianFD(Method m, const fem::ElementRest& e, const Mat34& x, double h) {
  Mat12 J;
  Matrix3d R;
  for (int k = 0; k < 4; ++k)
    for (int d = 0; d < 3; ++d) {
      Mat34 xp = x, xm = x;
      xp(d, k) += h;
      xm(d, k) -= h;
      J.col(3 * k + d) = flat(fem::elementForce(m, e, xp, R) - fem::elementForce(m, e, xm, R)) / (2 * h);
    }
  return J;
}

Mat34 force(Method m, const fem::ElementRest& e, const Mat34& x) {
  Matrix3d R;
  return fem::elementForce(m, e, x, R);
}

constexpr Method kAll[] = {Method::Small, Method::Large, Method::Polar};
constexpr int kTets = 20;  // random elements per check

}  // namespace

// 1a. Small: the force is exactly -dE/dx. Energy is quadratic, so central differences are exact
// up to rounding; tolerance 1e-6 relative leaves a margin of ~1e4 over the rounding error.
TEST(FemKernel, SmallForceIsMinusEnergyGradient) {
  Rng r(101);
  for (int t = 0; t < kTets; ++t) {
    double L;
    const Mat34 X = randomTet(r, &L);
    const auto e = fem::restElement(Method::Small, X, randomLame(r));
    const Mat34 x = X + r.mat34(0.1 * L);
    const Mat34 f = force(Method::Small, e, x);
    const Mat34 g = energyGradientFD(Method::Small, e, x, 1e-6 * L);
    EXPECT_LT((f - g).norm(), 1e-6 * f.norm()) << "tet " << t;
  }
}

// 1b. Large and polar: SOFA's corotational force f = -R^T K0 (R x - X) leaves out the term of
// the derivative of R, so it is not exactly -dE/dx (the force field is not conservative). The
// missing term is quadratic in the strain: with a rotation plus a strain of size eps, the
// mismatch relative to |f| must be O(eps) (< 1e-2 at eps = 1e-4) and shrink ~10x when eps
// shrinks 10x (ratio in [7, 14]; it is ~10 with an O(eps) correction). Any error of first order
// in the force (e.g. a wrong frame or a wrong K0) would make the ratio ~1.
TEST(FemKernel, CorotationalForceIsEnergyGradientToSecondOrder) {
  for (Method m : {Method::Large, Method::Polar}) {
    Rng r(202);
    double worst = 0, minRatio = 1e300, maxRatio = 0;
    for (int t = 0; t < kTets; ++t) {
      double L;
      const Mat34 X = randomTet(r, &L);
      const auto e = fem::restElement(m, X, randomLame(r));
      const Matrix3d Q = r.rotation();
      const Vector3d c(r.uniform(-3, 3), r.uniform(-3, 3), r.uniform(-3, 3));
      const Mat34 D = r.mat34(L);  // nodal displacement pattern
      double mismatch[2];
      for (int s = 0; s < 2; ++s) {
        const double eps = s == 0 ? 1e-4 : 1e-5;
        const Mat34 x = (Q * (X + eps * D)).colwise() + c;
        const Mat34 f = force(m, e, x);
        const Mat34 g = energyGradientFD(m, e, x, 1e-6 * L);
        mismatch[s] = (f - g).norm() / f.norm();
      }
      worst = std::max(worst, mismatch[0]);
      const double ratio = mismatch[0] / mismatch[1];
      minRatio = std::min(minRatio, ratio);
      maxRatio = std::max(maxRatio, ratio);
      EXPECT_LT(mismatch[0], 1e-2) << name(m) << " tet " << t;
      EXPECT_GT(ratio, 7.0) << name(m) << " tet " << t << ": mismatch " << mismatch[0] << " -> " << mismatch[1];
      EXPECT_LT(ratio, 14.0) << name(m) << " tet " << t << ": mismatch " << mismatch[0] << " -> " << mismatch[1];
    }
    std::printf("  %s: worst |f + dE/dx| / |f| at eps 1e-4 = %.2e, shrink ratio for eps / 10 in [%.2f, %.2f]\n", name(m),
                worst, minRatio, maxRatio);
  }
}

// 1c. Small: elementStiffness is the exact (constant) Jacobian of the force; central
// differences of a linear function are exact up to rounding -> 1e-6 relative.
TEST(FemKernel, SmallStiffnessIsForceJacobian) {
  Rng r(303);
  for (int t = 0; t < kTets; ++t) {
    double L;
    const Mat34 X = randomTet(r, &L);
    const auto e = fem::restElement(Method::Small, X, randomLame(r));
    const Mat34 x = X + r.mat34(0.2 * L);
    const Mat12 J = forceJacobianFD(Method::Small, e, x, 1e-6 * L);
    const Mat12 K = fem::elementStiffness(Method::Small, e, Matrix3d::Identity());
    EXPECT_LT((K - J).norm(), 1e-6 * K.norm()) << "tet " << t;
    EXPECT_LT((fem::elementTangent(Method::Small, e, x) - K).norm(), 1e-12 * K.norm()) << "tet " << t;
    // Symmetric and negative semi-definite with exactly 6 zero modes (rigid motions).
    EXPECT_LT((K - K.transpose()).norm(), 1e-12 * K.norm());
    Eigen::SelfAdjointEigenSolver<Mat12> es(-K);
    const auto ev = es.eigenvalues();
    for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(ev[i]), 1e-10 * ev[11]) << "tet " << t;
    EXPECT_GT(ev[6], 1e-3 * ev[11]) << "tet " << t;
  }
}

// 1c. Large and polar: elementTangent (with the derivative of the frame) is the Jacobian of the
// force, at large rotations (up to pi) and moderate strains (~10%). Central differences with
// h = 1e-6 L have truncation error ~1e-12 and rounding ~1e-10 relative -> tolerance 1e-5.
TEST(FemKernel, CorotationalTangentIsForceJacobian) {
  for (Method m : {Method::Large, Method::Polar}) {
    Rng r(404);
    double worst = 0, sofaWorst = 0;
    for (int t = 0; t < kTets; ++t) {
      double L;
      const Mat34 X = randomTet(r, &L);
      const auto e = fem::restElement(m, X, randomLame(r));
      const Mat34 x = (r.rotation() * (X + r.mat34(0.1 * L))).colwise() + Vector3d(r.uniform(-3, 3), 0.5, -1);
      const Mat12 J = forceJacobianFD(m, e, x, 1e-6 * L);
      const Mat12 K = fem::elementTangent(m, e, x);
      const double err = (K - J).norm() / J.norm();
      worst = std::max(worst, err);
      EXPECT_LT(err, 1e-5) << name(m) << " tet " << t;
      // SOFA's stiffness R^T K0 R is only an approximation of it (it omits dR): it must differ at
      // these strains, else this check would not see the frame derivative at all.
      Matrix3d R;
      fem::elementForce(m, e, x, R);
      sofaWorst = std::max(sofaWorst, (fem::elementStiffness(m, e, R) - J).norm() / J.norm());
    }
    EXPECT_GT(sofaWorst, 1e-3) << name(m);
    std::printf("  %s: worst |tangent - FD| / |FD| = %.2e (SOFA's R^T K0 R: %.2e)\n", name(m), worst, sofaWorst);
  }
}

// 1d. Large: elementStiffness = -blockdiag(R^T) K0 blockdiag(R), with K0 = V B^T D B built here
// from the rest positions in the element frame (ElementRest::X), the classic 6 x 12 B (Voigt
// xx, yy, zz, xy, yz, zx with engineering shear) and the isotropic D from E and nu, and R the
// edge frame built here. Same quantities by a different route: tolerance 1e-10 relative.
TEST(FemKernel, LargeStiffnessMatchesTextbookBtDB) {
  Rng r(505);
  for (int t = 0; t < kTets; ++t) {
    double L, E, nu;
    const Mat34 Xw = randomTet(r, &L);
    const auto lame = randomLame(r, &E, &nu);
    const auto e = fem::restElement(Method::Large, Xw, lame);

    // The rest frame: node 0 at the origin, node 1 on +x, node 2 in the xy plane (y > 0), and
    // the same shape (edge lengths) as in the world.
    const Mat34& X = e.X;
    EXPECT_LT(X.col(0).norm(), 1e-12 * L);
    EXPECT_LT(std::abs(X(1, 1)) + std::abs(X(2, 1)) + std::abs(X(2, 2)), 1e-12 * L);
    EXPECT_GT(X(0, 1), 0);
    EXPECT_GT(X(1, 2), 0);
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j)
        EXPECT_NEAR((X.col(i) - X.col(j)).norm(), (Xw.col(i) - Xw.col(j)).norm(), 1e-12 * L);

    // Shape-function gradients from [1 X^T] C = I, volume from the edge determinant.
    Eigen::Matrix4d P;
    for (int k = 0; k < 4; ++k) P.row(k) << 1, X(0, k), X(1, k), X(2, k);
    const Eigen::Matrix4d C = P.inverse();
    Matrix3d Ed;
    Ed << X.col(1) - X.col(0), X.col(2) - X.col(0), X.col(3) - X.col(0);
    const double V = std::abs(Ed.determinant()) / 6.0;
    EXPECT_NEAR(e.volume, V, 1e-12 * V);
    EXPECT_EQ(e.sign, Ed.determinant() > 0 ? 1.0 : -1.0);
    Eigen::Matrix<double, 6, 12> B = Eigen::Matrix<double, 6, 12>::Zero();
    for (int k = 0; k < 4; ++k) {
      const double bx = C(1, k), by = C(2, k), bz = C(3, k);
      B(0, 3 * k) = bx;
      B(1, 3 * k + 1) = by;
      B(2, 3 * k + 2) = bz;
      B(3, 3 * k) = by, B(3, 3 * k + 1) = bx;      // gamma_xy
      B(4, 3 * k + 1) = bz, B(4, 3 * k + 2) = by;  // gamma_yz
      B(5, 3 * k) = bz, B(5, 3 * k + 2) = bx;      // gamma_zx
    }
    Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
    const double c = E / ((1 + nu) * (1 - 2 * nu));
    D.topLeftCorner<3, 3>().setConstant(c * nu);
    for (int i = 0; i < 3; ++i) D(i, i) = c * (1 - nu), D(3 + i, 3 + i) = c * (1 - 2 * nu) / 2;
    const Mat12 K0 = V * B.transpose() * D * B;

    // Deformed, rotated configuration and its edge frame.
    const Mat34 x = (r.rotation() * (Xw + r.mat34(0.1 * L))).colwise() + Vector3d(1, 2, 3);
    const Vector3d ex = (x.col(1) - x.col(0)).normalized();
    const Vector3d ez = ex.cross(x.col(2) - x.col(0)).normalized();
    Matrix3d R;
    R.row(0) = ex;
    R.row(1) = ez.cross(ex);
    R.row(2) = ez;
    Matrix3d Rf;
    const Mat34 f = fem::elementForce(Method::Large, e, x, Rf);
    EXPECT_LT((Rf - R).norm(), 1e-12) << "tet " << t;
    Mat12 Rb = Mat12::Zero();
    for (int k = 0; k < 4; ++k) Rb.block<3, 3>(3 * k, 3 * k) = R;
    const Mat12 expected = -Rb.transpose() * K0 * Rb;
    const Mat12 K = fem::elementStiffness(Method::Large, e, R);
    EXPECT_LT((K - expected).norm(), 1e-10 * expected.norm()) << "tet " << t;

    // The force is the same operator on the local displacement: f = -R^T K0 (R (x - x0) - X).
    const Mat34 U = R * (x.colwise() - x.col(0)) - X;
    const Vec12 fExpected = -Rb.transpose() * (K0 * flat(U));
    EXPECT_LT((flat(f) - fExpected).norm(), 1e-10 * fExpected.norm()) << "tet " << t;
  }
}

// 1e. Rigid motion: large and polar give no force for a rigidly rotated and translated rest
// element (1e-9 of the force of a 10% strain; rounding is ~1e-14), small gives a force of the
// order of that of a large strain (> 0.1 of it at a rotation >= 0.5 rad). Large and polar forces
// rotate with the element: f(Q x + c) = Q f(x) to 1e-10 relative.
TEST(FemKernel, RigidMotionInvariance) {
  Rng r(606);
  for (Method m : kAll) {
    for (int t = 0; t < kTets; ++t) {
      double L;
      const Mat34 X = randomTet(r, &L);
      const auto e = fem::restElement(m, X, randomLame(r));
      const Matrix3d Q = r.rotation(0.5, M_PI);
      const Vector3d c(r.uniform(-10, 10), r.uniform(-10, 10), r.uniform(-10, 10));
      const Mat34 typical = force(m, e, X + r.mat34(0.1 * L));
      const Mat34 fRigid = force(m, e, (Q * X).colwise() + c);
      if (m == Method::Small) {
        EXPECT_GT(fRigid.norm(), 0.1 * typical.norm()) << "tet " << t;
        continue;
      }
      EXPECT_LT(fRigid.norm(), 1e-9 * typical.norm()) << name(m) << " tet " << t;
      EXPECT_LT(std::abs(fem::elementEnergy(m, e, (Q * X).colwise() + c)), 1e-18 * e.lame.mu * e.volume)
          << name(m) << " tet " << t;
      const Mat34 x = X + r.mat34(0.1 * L);
      const Mat34 fx = force(m, e, x);
      const Mat34 fQx = force(m, e, (Q * x).colwise() + c);
      EXPECT_LT((fQx - Q * fx).norm(), 1e-10 * fx.norm()) << name(m) << " tet " << t;
      // The forces of one element have no resultant (1e-10 relative). (They do have a net torque
      // of second order in the strain: linear stress does not conserve angular momentum.)
      EXPECT_LT(fx.rowwise().sum().norm(), 1e-10 * fx.norm());
    }
  }
}

// 1f. polarFactor: A = Q S with Q orthogonal (Q^T Q = I to 1e-12) and S symmetric (1e-12 relative)
// positive definite; Q equals U V^T from the SVD (1e-10). Random, ill-conditioned (cond 1e6),
// nearly orthogonal and reflected (det < 0) matrices.
TEST(FemKernel, PolarFactor) {
  Rng r(707);
  std::vector<Matrix3d> cases;
  for (int i = 0; i < 30; ++i) cases.push_back(r.mat3(1.0));
  for (int i = 0; i < 5; ++i) {
    const Matrix3d U = r.rotation(), V = r.rotation();
    cases.push_back(U * Eigen::Vector3d(1.0, 1e-3, 1e-6).asDiagonal() * V.transpose() * r.uniform(0.1, 100));
    cases.push_back(U + 1e-9 * r.mat3(1.0));
    Matrix3d Ref = U;
    Ref.col(0) *= -1;
    cases.push_back(Ref * Eigen::Vector3d(2.0, 0.5, 1.5).asDiagonal());
  }
  for (size_t i = 0; i < cases.size(); ++i) {
    const Matrix3d& A = cases[i];
    if (std::abs(A.determinant()) < 1e-12 * std::pow(A.norm(), 3)) continue;
    const Matrix3d Q = fem::polarFactor(A);
    EXPECT_LT((Q.transpose() * Q - Matrix3d::Identity()).norm(), 1e-12) << "case " << i;
    const Matrix3d S = Q.transpose() * A;
    EXPECT_LT((S - S.transpose()).norm(), 1e-12 * A.norm()) << "case " << i;
    Eigen::SelfAdjointEigenSolver<Matrix3d> es(0.5 * (S + S.transpose()));
    EXPECT_GT(es.eigenvalues()[0], 0.0) << "case " << i;
    Eigen::JacobiSVD<Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
    EXPECT_LT((Q - svd.matrixU() * svd.matrixV().transpose()).norm(), 1e-10) << "case " << i;
  }
}

// The frames: each is a rotation (orthonormal, det +1), and framePolar is the polar factor of the
// edge-row matrix. Frame derivatives against central differences of the frame (1e-6 relative).
TEST(FemKernel, FramesAndTheirDerivatives) {
  Rng r(808);
  for (Method m : {Method::Large, Method::Polar}) {
    for (int t = 0; t < kTets; ++t) {
      double L;
      const Mat34 x = (r.rotation() * (randomTet(r, &L) + r.mat34(0.1))).colwise() + Vector3d(0, 1, 2);
      const Matrix3d R = fem::frame(m, x);
      EXPECT_LT((R * R.transpose() - Matrix3d::Identity()).norm(), 1e-12);
      if (m == Method::Large) {
        EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
      } else {
        Matrix3d A;
        for (int k = 0; k < 3; ++k) A.row(k) = (x.col(k + 1) - x.col(0)).transpose();
        EXPECT_LT((R - fem::polarFactor(A)).norm(), 1e-14);
      }
      const double h = 1e-6 * L;
      for (int k = 0; k < 4; ++k)
        for (int d = 0; d < 3; ++d) {
          Mat34 xp = x, xm = x;
          xp(d, k) += h;
          xm(d, k) -= h;
          const Matrix3d fd = (fem::frame(m, xp) - fem::frame(m, xm)) / (2 * h);
          const Matrix3d dR = fem::frameDerivative(m, x, R, k, d);
          EXPECT_LT((dR - fd).norm(), 1e-6 * std::max(fd.norm(), 1.0 / L)) << name(m) << " tet " << t << " node " << k;
        }
    }
  }
}

// SOFA's svd frame: the polar frame while the element keeps its orientation; an inverted element
// (here the apex pushed through its base) gets a proper rotation instead of the polar reflection,
// so its force pushes the apex back out. A rigid motion of the inverted state changes nothing
// but the frame.
TEST(TetKernel, SvdFrameTurnsAnInvertedElementBack) {
  Mat34 X;
  X << 0, 1, 0, 0,  //
      0, 0, 1, 0,   //
      0, 0, 0, 1;
  const fem::ElementRest rest = fem::restElement(Method::Polar, X, fem::Lame::fromYoungPoisson(1000, 0.3));
  Mat34 x = X;
  x(2, 3) = 0.4;  // squashed, not inverted
  x(0, 1) = 1.2;
  EXPECT_LT((fem::frameSvd(rest, x) - fem::framePolar(x)).norm(), 1e-14);
  x(2, 3) = -0.3;  // the apex through the base: J = -0.3
  const Matrix3d Rpolar = fem::framePolar(x), Rsvd = fem::frameSvd(rest, x);
  EXPECT_NEAR(Rpolar.determinant(), -1.0, 1e-12);
  EXPECT_NEAR(Rsvd.determinant(), 1.0, 1e-12);
  EXPECT_LT((Rsvd * Rsvd.transpose() - Matrix3d::Identity()).norm(), 1e-12);
  const Mat34 f = fem::elementForceInFrame(rest, x, Rsvd);
  EXPECT_GT(f(2, 3), 0.0) << f;                        // the apex is pushed back up
  EXPECT_LT(f.rowwise().sum().norm(), 1e-9 * f.norm());  // no net force
  // A rigid rotation Q of the inverted state: the frame becomes R Q^T and the force Q f.
  const Matrix3d Q = Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Mat34 xr = Q * x;
  EXPECT_LT((fem::frameSvd(rest, xr) - Rsvd * Q.transpose()).norm(), 1e-12);
  EXPECT_LT((fem::elementForceInFrame(rest, xr, fem::frameSvd(rest, xr)) - Q * f).norm(), 1e-9 * f.norm());
}

// SOFA's plasticity, against the rule as SOFA writes it, in SOFA's units: the strain-displacement
// product J^T D is 6 V B (rest - current), the plastic strain lives in those units, and the force is
// J K (J^T D - P) = -V B^T C (B u - p) with p the plastic strain in true units. A sequence of local
// displacements of growing and shrinking size drives the element below the yield threshold, across
// it and into the cap; every force agrees to 1e-10 relative (rounding: ~1e-14).
TEST(FemKernel, PlasticityFollowsSofasRule) {
  Rng r(808);
  int crossed = 0, capped = 0;
  for (int t = 0; t < kTets; ++t) {
    double L, E, nu;
    const Mat34 Xw = randomTet(r, &L);
    const auto lame = randomLame(r, &E, &nu);
    const auto e = fem::restElement(Method::Large, Xw, lame);
    Eigen::Matrix4d Pm;
    for (int k = 0; k < 4; ++k) Pm.row(k) << 1, e.X(0, k), e.X(1, k), e.X(2, k);
    const Eigen::Matrix4d C = Pm.inverse();
    Eigen::Matrix<double, 6, 12> B = Eigen::Matrix<double, 6, 12>::Zero();
    for (int k = 0; k < 4; ++k) {
      const double bx = C(1, k), by = C(2, k), bz = C(3, k);
      B(0, 3 * k) = bx, B(1, 3 * k + 1) = by, B(2, 3 * k + 2) = bz;
      B(3, 3 * k) = by, B(3, 3 * k + 1) = bx;
      B(4, 3 * k + 1) = bz, B(4, 3 * k + 2) = by;
      B(5, 3 * k) = bz, B(5, 3 * k + 2) = bx;
    }
    Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
    const double c = E / ((1 + nu) * (1 - 2 * nu));
    D.topLeftCorner<3, 3>().setConstant(c * nu);
    for (int i = 0; i < 3; ++i) D(i, i) = c * (1 - nu), D(3 + i, 3 + i) = c * (1 - 2 * nu) / 2;
    const double V = e.volume;
    // Thresholds in SOFA's units (6 V |strain|): yield at a strain of 2 %, cap at 5 %.
    const fem::Plasticity law{0.02 * 6 * V, 0.05 * 6 * V, r.uniform(0.2, 1.0)};
    const Mat34 dir = r.mat34(1.0);
    const double unit = 1.0 / (B * flat(dir)).norm();  // the size of dir giving a strain of norm 1
    fem::Voigt P = fem::Voigt::Zero();
    Eigen::Matrix<double, 6, 1> sofaP = Eigen::Matrix<double, 6, 1>::Zero();
    for (double size : {0.01, 0.03, 0.06, 0.12, 0.12, 0.04, 0.0, -0.05}) {
      const Mat34 U = size * unit * dir;
      const Eigen::Matrix<double, 6, 1> JtD = 6 * V * (B * (-flat(U)));
      const Eigen::Matrix<double, 6, 1> elastic = JtD - sofaP;
      if (elastic.squaredNorm() > law.yield * law.yield) sofaP += law.creep * elastic, ++crossed;
      if (sofaP.squaredNorm() > law.max * law.max) sofaP *= law.max / sofaP.norm(), ++capped;
      const Vec12 expected = -V * B.transpose() * D * (B * flat(U) + sofaP / (6 * V));
      const Mat34 f = fem::plasticForce(e, U, law, P);
      EXPECT_LT((flat(f) - expected).norm(), 1e-10 * expected.norm() + 1e-14) << "tet " << t << " size " << size;
      EXPECT_LT((P + sofaP / (6 * V)).norm(), 1e-10 * (1 + P.norm())) << "tet " << t;
    }
  }
  EXPECT_GT(crossed, kTets);  // the yield threshold was crossed ...
  EXPECT_GT(capped, kTets);   // ... and the cap reached, in most elements
}

// Fully plastic creep: a displacement beyond the yield threshold becomes the element's new rest
// shape in one evaluation (zero force there, the elastic force of the difference elsewhere); below
// the threshold the element is elastic.
TEST(FemKernel, PlasticCreepOfOneMovesTheRestShape) {
  Rng r(909);
  const Mat34 Xw = randomTet(r);
  const auto e = fem::restElement(Method::Small, Xw, randomLame(r));
  const fem::Plasticity law{1e-3 * 6 * e.volume, 1e6, 1.0};
  fem::Voigt P = fem::Voigt::Zero();
  const Mat34 tiny = 1e-6 * r.mat34(1.0);
  EXPECT_LT((fem::plasticForce(e, tiny, law, P) - fem::elasticForce(e, tiny)).norm(), 1e-12 * fem::elasticForce(e, tiny).norm());
  EXPECT_EQ(P.norm(), 0.0);
  const Mat34 U = 0.05 * r.mat34(1.0);
  const Mat34 f = fem::plasticForce(e, U, law, P);
  EXPECT_LT(f.norm(), 1e-12 * fem::elasticForce(e, U).norm());
  EXPECT_GT(P.norm(), 0.0);
  const Mat34 W = U + tiny;  // near the new rest shape: elastic again, from it
  EXPECT_LT((fem::plasticForce(e, W, law, P) - fem::elasticForce(e, tiny)).norm(), 1e-9 * fem::elasticForce(e, tiny).norm());
}
