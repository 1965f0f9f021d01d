// The laws SOFA's hyperelastic tetrahedra offer (its material/ folder), with the same parameters.
// Each S is 2 dW/dC of its W, and each dS the exact derivative of S: the tests check both against
// finite differences. Notation: I1 = tr C, Ci = C^-1, T = Ci : H, and d(Ci) = -Ci H Ci.
#include "engine/fem/HyperelasticMaterials.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <stdexcept>

namespace viscera::fem {

namespace {

using Mat = Eigen::Matrix3d;
const Mat kI = Mat::Identity();

double contract(const Mat& A, const Mat& B) { return (A.array() * B.array()).sum(); }

// Ci H Ci, symmetrised.
Mat sandwich(const Mat& Ci, const Mat& H) {
  const Mat M = Ci * H * Ci;
  return 0.5 * (M + M.transpose());
}

// W = mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2 (compressible, Bonet and Wood).
class NeoHookean : public HyperelasticMaterial {
 public:
  NeoHookean(double mu, double lambda) : mu_(mu), lambda_(lambda) {}
  double energy(const Mat& C, double J) const override {
    const double l = std::log(J);
    return 0.5 * mu_ * (C.trace() - 3) - mu_ * l + 0.5 * lambda_ * l * l;
  }
  Mat stress(const Mat& C, double J) const override { return mu_ * kI + (lambda_ * std::log(J) - mu_) * C.inverse(); }
  Mat stressDerivative(const Mat& C, double J, const Mat& H) const override {
    const Mat Ci = C.inverse();
    return (mu_ - lambda_ * std::log(J)) * sandwich(Ci, H) + (0.5 * lambda_ * contract(Ci, H)) * Ci;
  }

 private:
  double mu_, lambda_;
};

// W = lambda/2 (tr E)^2 + mu tr(E^2), E = (C - I) / 2.
class StVenantKirchhoff : public HyperelasticMaterial {
 public:
  StVenantKirchhoff(double mu, double lambda) : mu_(mu), lambda_(lambda) {}
  double energy(const Mat& C, double) const override {
    const Mat E = 0.5 * (C - kI);
    return 0.5 * lambda_ * E.trace() * E.trace() + mu_ * contract(E, E);
  }
  Mat stress(const Mat& C, double) const override { return mu_ * (C - kI) + (0.5 * lambda_ * (C.trace() - 3)) * kI; }
  Mat stressDerivative(const Mat&, double, const Mat& H) const override { return (0.5 * lambda_ * H.trace()) * kI + mu_ * H; }
  bool definedWhenInverted() const override { return true; }

 private:
  double mu_, lambda_;
};

// W = mu sum_i c_i (J^(-2i/3) I1^i - 3^i) + k0 (ln J)^2 / 2: the Arruda-Boyce series to the fifth
// term with SOFA's chain parameter N = 8.
class ArrudaBoyce : public HyperelasticMaterial {
 public:
  ArrudaBoyce(double mu, double k0) : mu_(mu), k0_(k0) {}
  double energy(const Mat& C, double J) const override {
    const double I1 = C.trace(), l = std::log(J);
    double w = 0;
    for (int i = 1; i <= 5; ++i) w += kC[i - 1] * (std::pow(J, -2.0 * i / 3) * std::pow(I1, i) - std::pow(3.0, i));
    return mu_ * w + 0.5 * k0_ * l * l;
  }
  Mat stress(const Mat& C, double J) const override {
    const Mat Ci = C.inverse();
    const double I1 = C.trace();
    Mat S = (k0_ * std::log(J)) * Ci;
    for (int i = 1; i <= 5; ++i) S += (2 * mu_ * kC[i - 1] * std::pow(J, -2.0 * i / 3)) * term(i, I1, Ci);
    return S;
  }
  Mat stressDerivative(const Mat& C, double J, const Mat& H) const override {
    const Mat Ci = C.inverse(), CHC = sandwich(Ci, H);
    const double I1 = C.trace(), T = contract(Ci, H), trH = H.trace();
    Mat d = (0.5 * k0_ * T) * Ci - (k0_ * std::log(J)) * CHC;
    for (int i = 1; i <= 5; ++i) {
      const Mat inner = (-i / 3.0 * T) * term(i, I1, Ci) + (i * (i - 1) * std::pow(I1, i - 2) * trH) * kI -
                        (i * i / 3.0 * std::pow(I1, i - 1) * trH) * Ci + (i / 3.0 * std::pow(I1, i)) * CHC;
      d += (2 * mu_ * kC[i - 1] * std::pow(J, -2.0 * i / 3)) * inner;
    }
    return d;
  }

 private:
  // A_i = i I1^(i-1) I - (i/3) I1^i C^-1: the derivative of J^(-2i/3) I1^i, less its J factor.
  static Mat term(int i, double I1, const Mat& Ci) { return (i * std::pow(I1, i - 1)) * kI - (i / 3.0 * std::pow(I1, i)) * Ci; }
  static constexpr double kC[5] = {0.5, 1.0 / 160, 11.0 / (1050 * 64), 19.0 / (7000 * 512), 519.0 / (673750.0 * 4096)};
  double mu_, k0_;
};

// W = c1 (J^(-2/3) I1 - 3) + c2 (J^(-4/3) I2 - 3) + k0 (ln J)^2 / 2.
class MooneyRivlin : public HyperelasticMaterial {
 public:
  MooneyRivlin(double c1, double c2, double k0) : c1_(c1), c2_(c2), k0_(k0) {}
  double energy(const Mat& C, double J) const override {
    const double I1 = C.trace(), I2 = 0.5 * (I1 * I1 - contract(C, C)), l = std::log(J);
    return c1_ * (std::pow(J, -2.0 / 3) * I1 - 3) + c2_ * (std::pow(J, -4.0 / 3) * I2 - 3) + 0.5 * k0_ * l * l;
  }
  Mat stress(const Mat& C, double J) const override {
    const Mat Ci = C.inverse();
    const double I1 = C.trace(), I2 = 0.5 * (I1 * I1 - contract(C, C));
    return (2 * c1_ * std::pow(J, -2.0 / 3)) * (kI - I1 / 3 * Ci) +
           (2 * c2_ * std::pow(J, -4.0 / 3)) * (I1 * kI - C - 2.0 / 3 * I2 * Ci) + (k0_ * std::log(J)) * Ci;
  }
  Mat stressDerivative(const Mat& C, double J, const Mat& H) const override {
    const Mat Ci = C.inverse(), CHC = sandwich(Ci, H);
    const double I1 = C.trace(), I2 = 0.5 * (I1 * I1 - contract(C, C)), T = contract(Ci, H), trH = H.trace();
    const Mat B = I1 * kI - C - 2.0 / 3 * I2 * Ci;
    const Mat first = (-T / 3) * (kI - I1 / 3 * Ci) + (I1 / 3) * CHC - (trH / 3) * Ci;
    const Mat second = (-2.0 / 3 * T) * B + (2.0 / 3 * I2) * CHC - (2.0 / 3 * (I1 * trH - contract(C, H))) * Ci + trH * kI - H;
    return (2 * c1_ * std::pow(J, -2.0 / 3)) * first + (2 * c2_ * std::pow(J, -4.0 / 3)) * second + (0.5 * k0_ * T) * Ci -
           (k0_ * std::log(J)) * CHC;
  }

 private:
  double c1_, c2_, k0_;
};

// Smith, de Goes and Kim's stable Neo-Hookean without its log term:
// W = [mu (I1 - 3) + (lambda + mu) (J - a)^2] / 2, a = 1 + mu / (lambda + mu).
class StableNeoHookean : public HyperelasticMaterial {
 public:
  StableNeoHookean(double mu, double lambda) : mu_(mu), lambda_(lambda), a_(1 + mu / (lambda + mu)) {}
  double energy(const Mat& C, double J) const override {
    return 0.5 * (mu_ * (C.trace() - 3) + (lambda_ + mu_) * (J - a_) * (J - a_));
  }
  Mat stress(const Mat& C, double J) const override { return mu_ * kI + ((lambda_ + mu_) * J * (J - a_)) * C.inverse(); }
  Mat stressDerivative(const Mat& C, double J, const Mat& H) const override {
    const Mat Ci = C.inverse();
    return (0.5 * (lambda_ + mu_)) * ((-2 * J * (J - a_)) * sandwich(Ci, H) + (J * (2 * J - a_) * contract(Ci, H)) * Ci);
  }
  bool definedWhenInverted() const override { return true; }

 private:
  double mu_, lambda_, a_;
};

// One-term Ogden on the isochoric stretches: W = mu / alpha^2 (J^(-alpha/3) sum_I l_I^(alpha/2) - 3)
// + k0 (ln J)^2 / 2, l_I the eigenvalues of C. The derivative of C^b (b = alpha/2 - 1) is the
// spectral (Daleckii-Krein) one.
class Ogden : public HyperelasticMaterial {
 public:
  Ogden(double mu, double alpha, double k0) : mu_(mu), alpha_(alpha), k0_(k0) {}
  double energy(const Mat& C, double J) const override {
    const Eigen::SelfAdjointEigenSolver<Mat> eig(C);
    const double T = eig.eigenvalues().array().pow(alpha_ / 2).sum(), l = std::log(J);
    return mu_ / (alpha_ * alpha_) * (std::pow(J, -alpha_ / 3) * T - 3) + 0.5 * k0_ * l * l;
  }
  Mat stress(const Mat& C, double J) const override {
    const Eigen::SelfAdjointEigenSolver<Mat> eig(C);
    const Mat Ci = C.inverse();
    const double FJ = std::pow(J, -alpha_ / 3), T = eig.eigenvalues().array().pow(alpha_ / 2).sum();
    return (FJ * mu_ / alpha_) * power(eig, alpha_ / 2 - 1) - (FJ * mu_ * T / (3 * alpha_)) * Ci + (k0_ * std::log(J)) * Ci;
  }
  Mat stressDerivative(const Mat& C, double J, const Mat& H) const override {
    const Eigen::SelfAdjointEigenSolver<Mat> eig(C);
    const Mat Ci = C.inverse(), dCi = -sandwich(Ci, H);
    const double b = alpha_ / 2 - 1, FJ = std::pow(J, -alpha_ / 3), TC = contract(Ci, H);
    const Mat Cb = power(eig, b);
    const double T = eig.eigenvalues().array().pow(alpha_ / 2).sum();
    const double dFJ = -alpha_ / 6 * FJ * TC, dT = alpha_ / 2 * contract(Cb, H);
    // d(C^b)[H] = V (rho o (V^T H V)) V^T, rho_IJ the divided difference of l^b.
    const Mat& V = eig.eigenvectors();
    const Eigen::Vector3d& l = eig.eigenvalues();
    Mat G = V.transpose() * H * V;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        // l_j^b ((1 + gap / l_j)^b - 1) / gap, without cancellation for close eigenvalues.
        const double gap = l[i] - l[j];
        const double rho = gap != 0 ? std::pow(l[j], b) * std::expm1(b * std::log1p(gap / l[j])) / gap
                                    : b * std::pow(l[i], b - 1);
        G(i, j) *= rho;
      }
    const Mat dCb = V * G * V.transpose();
    return (dFJ * mu_ / alpha_) * Cb + (FJ * mu_ / alpha_) * dCb - (mu_ / (3 * alpha_) * (dFJ * T + FJ * dT)) * Ci -
           (FJ * mu_ * T / (3 * alpha_)) * dCi + (0.5 * k0_ * TC) * Ci + (k0_ * std::log(J)) * dCi;
  }

 private:
  static Mat power(const Eigen::SelfAdjointEigenSolver<Mat>& eig, double p) {
    return eig.eigenvectors() * eig.eigenvalues().array().pow(p).matrix().asDiagonal() * eig.eigenvectors().transpose();
  }
  double mu_, alpha_, k0_;
};

}  // namespace

const std::vector<MaterialInfo>& hyperelasticMaterials() {
  static const std::vector<MaterialInfo> all = {
      {"ArrudaBoyce", "mu k0 (shear and bulk moduli)", 2},
      {"StVenantKirchhoff", "mu lambda (Lame coefficients)", 2},
      {"NeoHookean", "mu lambda (Lame coefficients)", 2},
      {"MooneyRivlin", "c1 c2 k0", 3},
      {"Ogden", "mu alpha k0", 3},
      {"StableNeoHookean", "mu lambda", 2},
  };
  return all;
}

std::unique_ptr<HyperelasticMaterial> makeHyperelasticMaterial(const std::string& name, const std::vector<double>& p) {
  if (name == "ArrudaBoyce") return std::make_unique<ArrudaBoyce>(p.at(0), p.at(1));
  if (name == "StVenantKirchhoff") return std::make_unique<StVenantKirchhoff>(p.at(0), p.at(1));
  if (name == "NeoHookean") return std::make_unique<NeoHookean>(p.at(0), p.at(1));
  if (name == "MooneyRivlin") return std::make_unique<MooneyRivlin>(p.at(0), p.at(1), p.at(2));
  if (name == "Ogden") return std::make_unique<Ogden>(p.at(0), p.at(1), p.at(2));
  if (name == "StableNeoHookean") return std::make_unique<StableNeoHookean>(p.at(0), p.at(1));
  throw std::invalid_argument("unknown hyperelastic material '" + name + "'");
}

}  // namespace viscera::fem
