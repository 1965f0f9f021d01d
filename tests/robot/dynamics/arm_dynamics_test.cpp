// The arm's dynamics against answers computed without the Newton-Euler recursion: Lagrange's
// equations from the energies by finite differences, the energy balance, and the potential's
// gradient for gravity.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>

#include "robot/dynamics/ArmDynamics.h"

namespace viscera::robot {
namespace {

Eigen::VectorXd randomState(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Eigen::VectorXd v(kPsmDof);
  for (int i = 0; i < kPsmDof; ++i) v[i] = u(rng);
  return v;
}

Eigen::VectorXd randomPose(std::mt19937_64& rng) {
  Eigen::VectorXd q = randomState(rng, 0.8);
  q[2] = 0.05 + 0.15 * (q[2] + 0.8) / 1.6;  // insertion within [0.05, 0.2] m
  return q;
}

TEST(ArmDynamics, MassMatrixIsSymmetricPositiveDefinite) {
  const ArmDynamics arm = psmDynamics();
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::VectorXd q = randomPose(rng);
    const Eigen::MatrixXd M = arm.massMatrix(q);
    // The recursion computes each column independently; symmetry is a property, not a construction
    // (massMatrix only averages away rounding).
    Eigen::MatrixXd raw(kPsmDof, kPsmDof);
    for (int j = 0; j < kPsmDof; ++j) {
      Eigen::VectorXd e = Eigen::VectorXd::Zero(kPsmDof);
      e[j] = 1;
      raw.col(j) = arm.rigidBody(q, Eigen::VectorXd::Zero(kPsmDof), e, arm.linkParameters(), false);
    }
    EXPECT_LT((raw - raw.transpose()).norm(), 1e-12 * raw.norm());
    EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(M).info(), Eigen::Success);
  }
}

// tau = d/dt dL/dqd - dL/dq with L = T - U, along q(t) = q + qd t + qdd t^2 / 2, every derivative by
// central differences of the energies (step 1e-5: truncation ~1e-10, rounding ~1e-11 relative).
TEST(ArmDynamics, NewtonEulerMatchesLagrangeFromEnergies) {
  const ArmDynamics arm = psmDynamics();
  std::mt19937_64 rng(7);
  const double h = 1e-5;
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::VectorXd q = randomPose(rng), qd = randomState(rng, 1.0), qdd = randomState(rng, 2.0);
    auto qAt = [&](double t) { return Eigen::VectorXd(q + qd * t + 0.5 * qdd * t * t); };
    auto qdAt = [&](double t) { return Eigen::VectorXd(qd + qdd * t); };
    auto lagrangian = [&](const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
      return arm.kineticEnergy(x, v) - arm.potentialEnergy(x);
    };
    auto dLdqd = [&](double t) {
      Eigen::VectorXd g(kPsmDof);
      for (int i = 0; i < kPsmDof; ++i) {
        Eigen::VectorXd vp = qdAt(t), vm = qdAt(t);
        vp[i] += h;
        vm[i] -= h;
        g[i] = (lagrangian(qAt(t), vp) - lagrangian(qAt(t), vm)) / (2 * h);
      }
      return g;
    };
    Eigen::VectorXd expected = (dLdqd(h) - dLdqd(-h)) / (2 * h);
    for (int i = 0; i < kPsmDof; ++i) {
      Eigen::VectorXd xp = q, xm = q;
      xp[i] += h;
      xm[i] -= h;
      expected[i] -= (lagrangian(xp, qd) - lagrangian(xm, qd)) / (2 * h);
    }
    // The model without friction: rigid body, armature and springs.
    Eigen::VectorXd tau = arm.inverseDynamics(q, qd, qdd) - arm.frictionEfforts(qd);
    EXPECT_LT((tau - expected).norm(), 1e-5 * (1 + expected.norm())) << "trial " << trial << "\n"
                                                                       << tau.transpose() << "\n"
                                                                       << expected.transpose();
  }
}

TEST(ArmDynamics, GravityIsThePotentialsGradient) {
  const ArmDynamics arm = psmDynamics();
  std::mt19937_64 rng(11);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(kPsmDof);
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::VectorXd q = randomPose(rng);
    Eigen::VectorXd grad(kPsmDof);
    for (int i = 0; i < kPsmDof; ++i) {
      Eigen::VectorXd xp = q, xm = q;
      xp[i] += 1e-6;
      xm[i] -= 1e-6;
      grad[i] = (arm.potentialEnergy(xp) - arm.potentialEnergy(xm)) / 2e-6;
    }
    EXPECT_LT((arm.bias(q, zero) - grad).norm(), 1e-7 * (1 + grad.norm()));
  }
}

TEST(ArmDynamics, EffortsAreLinearInTheLinkParameters) {
  const ArmDynamics arm = psmDynamics();
  std::mt19937_64 rng(5);
  const Eigen::VectorXd q = randomPose(rng), qd = randomState(rng, 1), qdd = randomState(rng, 1);
  const Eigen::VectorXd p = arm.linkParameters();
  const Eigen::VectorXd p2 = p.cwiseProduct(Eigen::VectorXd::LinSpaced(p.size(), 0.5, 1.5));
  const Eigen::VectorXd sum = arm.rigidBody(q, qd, qdd, p) + 2 * arm.rigidBody(q, qd, qdd, p2);
  EXPECT_LT((arm.rigidBody(q, qd, qdd, Eigen::VectorXd(p + 2 * p2)) - sum).norm(), 1e-12 * sum.norm());
}

TEST(JointFriction, SlopeIsTheDerivative) {
  const JointFriction f{0.5, 0.2, 0.02, 0.3, 1e-3};
  for (double v : {-0.1, -0.01, -1e-4, 0.0, 3e-4, 0.015, 0.2}) {
    const double fd = (f.effort(v + 1e-8) - f.effort(v - 1e-8)) / 2e-8;
    EXPECT_NEAR(f.slope(v), fd, 1e-5 * (1 + std::abs(fd))) << v;
  }
  // Far from rest: Coulomb plus viscous, with the sign of the velocity.
  EXPECT_NEAR(f.effort(1.0), 0.5 + 0.3, 1e-9);
  EXPECT_NEAR(f.effort(-1.0), -0.8, 1e-9);
}

}  // namespace
}  // namespace viscera::robot
