// The simulated arm keeps Eq. 2.4 (motor effort = free-space dynamics + trocar + J^T F_ext) at every
// sample, tracks its reference, and its phantom pushes back with its stiffness times the depth.
#include <gtest/gtest.h>

#include <cmath>

#include "core/Error.h"
#include "robot/dynamics/ArmSimulator.h"

namespace viscera::robot {
namespace {

ArmSimulationOptions noiseless(double duration) {
  ArmSimulationOptions o = psmSimulationDefaults();
  o.duration = duration;
  o.measurement.makePerfect();
  return o;
}

// RMS over samples of a - b, relative to the RMS of a, per column.
Eigen::VectorXd relativeRms(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).colwise().norm().cwiseQuotient(a.colwise().norm()).transpose();
}

TEST(ArmSimulator, MotorEffortBalancesTheModelInFreeSpace) {
  const ArmDynamics arm = psmDynamics();
  const ArmRecording r = simulateArm(arm, noiseless(4));
  ASSERT_EQ(r.samples(), 4001);
  const Eigen::VectorXd rel = relativeRms(r.effort, r.freeEffort);
  for (int i = 0; i < arm.dof(); ++i) EXPECT_LT(rel[i], 1e-9) << "joint " << i + 1;
  // The free-space effort is the model's at the recorded state, up to the step's linearisation of
  // friction over 0.2 ms and its acceleration being the step's mean.
  Eigen::MatrixXd model(r.samples(), arm.dof());
  for (int s = 1; s + 1 < r.samples(); ++s) {
    const Eigen::VectorXd qdd = (r.qdTrue.row(s + 1) - r.qdTrue.row(s - 1)).transpose() * 500.0;
    model.row(s) = arm.inverseDynamics(r.qTrue.row(s).transpose(), r.qdTrue.row(s).transpose(), qdd).transpose();
  }
  model.row(0) = r.freeEffort.row(0);
  model.row(r.samples() - 1) = r.freeEffort.row(r.samples() - 1);
  const Eigen::VectorXd relModel = relativeRms(r.freeEffort, model);
  for (int i = 0; i < arm.dof(); ++i) EXPECT_LT(relModel[i], 0.05) << "joint " << i + 1;
  EXPECT_EQ(r.externalEffort.norm(), 0.0);
  EXPECT_EQ(r.trocarEffort.norm(), 0.0);
}

TEST(ArmSimulator, TrocarAndSealEffortsAddToTheMotors) {
  const ArmDynamics arm = psmDynamics();
  ArmSimulationOptions o = noiseless(4);
  o.trocar.enabled = o.seal.enabled = true;
  const ArmRecording r = simulateArm(arm, o);
  EXPECT_GT(r.trocarEffort.col(0).cwiseAbs().maxCoeff(), 0.01);   // N m on yaw
  EXPECT_GT(r.trocarEffort.col(2).cwiseAbs().maxCoeff(), 0.5);    // N on insertion (seal)
  const Eigen::VectorXd rel = relativeRms(r.effort, Eigen::MatrixXd(r.freeEffort + r.trocarEffort));
  for (int i = 0; i < arm.dof(); ++i) EXPECT_LT(rel[i], 1e-9) << "joint " << i + 1;
}

TEST(ArmSimulator, PhantomPushesBackWithItsStiffness) {
  const ArmDynamics arm = psmDynamics();
  ArmSimulationOptions o = noiseless(20);
  o.phantom.enabled = true;
  o.phantom.damping = 0;
  o.phantom.friction = 0;
  const ArmRecording r = simulateArm(arm, o);
  int contact = 0;
  double worst = 0, peak = 0;
  for (int s = 0; s < r.samples(); ++s) {
    const Eigen::Vector3d tip = r.tip.row(s).transpose();
    const double depth = -(tip - o.phantom.point).dot(o.phantom.normal);
    const Eigen::Vector3d f = r.wrench.row(s).head<3>().transpose();
    // The tool presses into the surface: F_ext along the inward normal, |F| = k * depth.
    const Eigen::Vector3d expected = depth > 0 ? Eigen::Vector3d(-o.phantom.stiffness * depth * o.phantom.normal)
                                               : Eigen::Vector3d::Zero();
    worst = std::max(worst, (f - expected).norm());
    peak = std::max(peak, f.norm());
    contact += depth > 0;
  }
  EXPECT_GT(contact, r.samples() / 10);
  EXPECT_GT(peak, 1.0);  // N
  EXPECT_LT(worst, 1e-9);
  const Eigen::VectorXd rel = relativeRms(r.effort, Eigen::MatrixXd(r.freeEffort + r.externalEffort));
  for (int i = 0; i < arm.dof(); ++i) EXPECT_LT(rel[i], 1e-9) << "joint " << i + 1;
  // J^T F_ext at the recorded state against the step's external effort (0.2 ms apart).
  double err = 0, norm = 0;
  for (int s = 0; s < r.samples(); ++s) {
    const Jacobian J = arm.chain().spatialJacobian(r.qTrue.row(s).transpose());
    err += (J.transpose() * r.wrench.row(s).transpose() - r.externalEffort.row(s).transpose()).squaredNorm();
    norm += r.externalEffort.row(s).squaredNorm();
  }
  EXPECT_LT(std::sqrt(err / norm), 0.02);
}

TEST(ArmSimulator, FollowsItsReferenceAndRepeatsWithItsSeed) {
  const ArmDynamics arm = psmDynamics();
  const ArmRecording a = simulateArm(arm, noiseless(2));
  const ArmRecording b = simulateArm(arm, noiseless(2));
  EXPECT_EQ(a.effort, b.effort);
  ArmSimulationOptions o = noiseless(2);
  o.seed = 2;
  EXPECT_NE(simulateArm(arm, o).effort, a.effort);
  // Within the joint limits throughout.
  for (int s = 0; s < a.samples(); ++s) EXPECT_TRUE(arm.chain().limitViolations(a.qTrue.row(s).transpose()).empty());
}

// The step bounds each move between waypoints: small steps stay near the start, a step of the
// whole range reaches across the workspace in the same time.
TEST(ArmSimulator, StepSetsHowFarTheMovesReach) {
  const ArmDynamics arm = psmDynamics();
  auto span = [&](double step) {
    ArmSimulationOptions o = noiseless(30);
    o.rate = 200;
    o.excitation.step = step;
    const ArmRecording r = simulateArm(arm, o);
    Eigen::VectorXd s(2);
    for (int i = 0; i < 2; ++i) s[i] = (r.qTrue.col(i).maxCoeff() - r.qTrue.col(i).minCoeff()) / (o.excitation.upper[i] - o.excitation.lower[i]);
    return s;
  };
  const Eigen::VectorXd small = span(0.02), whole = span(1.0);
  for (int i = 0; i < 2; ++i) {
    EXPECT_LT(small[i], 0.25) << "joint " << i + 1;
    EXPECT_GT(whole[i], 0.6) << "joint " << i + 1;
  }
}

TEST(ArmSimulator, RejectsOptionsThatDoNotFitTheArm) {
  const ArmDynamics arm = psmDynamics();
  ArmSimulationOptions o = psmSimulationDefaults();
  o.gains.kp.pop_back();
  EXPECT_THROW(simulateArm(arm, o), Error);
  o = psmSimulationDefaults();
  o.excitation.upper[2] = 0.3;  // beyond the insertion limit
  EXPECT_THROW(simulateArm(arm, o), Error);
  for (double step : {0.0, -0.1, 1.5, std::nan("")}) {
    o = psmSimulationDefaults();
    o.excitation.step = step;
    EXPECT_THROW(simulateArm(arm, o), Error) << step;
  }
}

}  // namespace
}  // namespace viscera::robot

namespace viscera::robot {
namespace {

// An environment outside the simulator (here a push that starts after a second and depends on the
// tip's height): its wrench is the recorded truth and enters the balance as J^T F.
TEST(ArmSimulator, AnExternalEnvironmentsWrenchIsTheTruth) {
  const ArmDynamics arm = psmDynamics();
  ArmSimulationOptions o = noiseless(3);
  int calls = 0;
  o.environment = [&](double t, const Eigen::Isometry3d& tip, const Vector6d&) {
    ++calls;
    Vector6d w = Vector6d::Zero();
    if (t >= 1) w.head<3>() = Eigen::Vector3d(0.5, -1.0, -2.0) * (1 - tip.translation().z());
    return w;
  };
  const ArmRecording r = simulateArm(arm, o);
  EXPECT_EQ(calls, r.samples());  // once per sample
  int pushed = 0;
  for (int s = 0; s < r.samples(); ++s) pushed += r.wrench(s, 2) < 0;
  EXPECT_GT(pushed, 100);
  const Eigen::VectorXd rel = relativeRms(r.effort, Eigen::MatrixXd(r.freeEffort + r.externalEffort));
  for (int i = 0; i < arm.dof(); ++i) EXPECT_LT(rel[i], 1e-9) << "joint " << i + 1;
  for (int s = 1; s < r.samples(); ++s) {
    if (r.wrench.row(s).isZero()) continue;
    const Jacobian J = arm.chain().spatialJacobian(r.qTrue.row(s).transpose());
    // The wrench was held over the sample: J at the sample's end differs from the steps' by 1 ms.
    EXPECT_LT((J.transpose() * r.wrench.row(s).transpose() - r.externalEffort.row(s).transpose()).norm(), 0.05);
  }
}

}  // namespace
}  // namespace viscera::robot
