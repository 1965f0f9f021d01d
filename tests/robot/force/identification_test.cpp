// Least-squares identification against an arm whose dynamics lie in the identified model's family:
// on a held-out trajectory the identified model predicts the efforts to the accuracy of its
// finite-difference accelerations. J^-T against a known wrench; the error measures by hand.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "core/Error.h"
#include "robot/dynamics/ArmSimulator.h"
#include "robot/force/Identification.h"
#include "robot/force/Metrics.h"
#include "robot/force/Stiffness.h"

namespace viscera::robot {
namespace {

// The PSM with friction the identified model can represent (no Stribeck term, its tanh width).
ArmDynamics identifiableArm() {
  const ArmDynamics psm = psmDynamics();
  std::vector<JointFriction> friction = psm.friction();
  for (JointFriction& f : friction) {
    f.stribeck = 0;
    f.smoothing = IdentificationOptions{}.coulombVelocity;
  }
  return ArmDynamics(psm.chain(), psm.links(), psm.gravity(), psm.armature(), friction, psm.springs());
}

JointStateLog noiselessLog(const ArmDynamics& arm, std::uint64_t seed, double duration) {
  ArmSimulationOptions o = psmSimulationDefaults();
  o.duration = duration;
  o.rate = 200;
  o.substeps = 25;
  o.seed = seed;
  o.measurement.makePerfect();
  const ArmRecording r = simulateArm(arm, o);
  return makeJointStateLog(r.t, r.q, r.qd, r.effort, "seed " + std::to_string(seed));
}

TEST(Identification, PredictsAHeldOutTrajectoryOfAnArmInItsFamily) {
  const ArmDynamics arm = identifiableArm();
  const PhysicalModel model = PhysicalModel::identify(arm, {noiselessLog(arm, 1, 120)});
  const JointStateLog test = noiselessLog(arm, 2, 30);
  const ErrorMeasures e = errorMeasures(model.predict(test), test.effort());
  // What is left comes from accelerations by central differences over 10 ms and the implicit
  // step's linearised friction: well under 1 % of each joint's range.
  for (int j = 0; j < arm.dof(); ++j) EXPECT_LT(e.nrmse[j], 0.01) << "joint " << j + 1;
}

TEST(Identification, SavesAndLoadsItsParameters) {
  const ArmDynamics arm = psmDynamics();
  Eigen::VectorXd p = Eigen::VectorXd::LinSpaced(PhysicalModel::parameterCount(6), -1, 1);
  const PhysicalModel a(arm, {}, p);
  const PhysicalModel b = PhysicalModel::fromJson(a.toJson(), "model.json", arm);
  EXPECT_EQ(b.parameters(), p);
  EXPECT_THROW(PhysicalModel::fromJson("{\"kind\":\"network\"}", "x.json", arm), Error);
}

TEST(WrenchFromEfforts, InvertsTheJacobianTranspose) {
  const SerialChain psm = psmLargeNeedleDriver();
  Eigen::VectorXd q(6);
  q << 0.2, -0.3, 0.14, 0.5, 0.3, -0.2;
  const Jacobian J = psm.spatialJacobian(q);
  Vector6d F;
  F << 1.5, -2.0, 3.0, 0.01, -0.02, 0.005;
  const Vector6d back = wrenchFromExternalEfforts(J, J.transpose() * F, 1e-4);
  EXPECT_LT((back - F).norm(), 1e-4 * F.norm());
}

TEST(ErrorMeasures, FollowEquations27And28) {
  Eigen::MatrixXd truth(4, 2), estimate(4, 2);
  truth << 0, 1, 2, 1, 4, 1, 2, 1;
  estimate << 1, 1, 2, 1, 3, 1, 2, 1;
  const ErrorMeasures e = errorMeasures(estimate, truth);
  EXPECT_DOUBLE_EQ(e.rmse[0], std::sqrt(2.0 / 4));
  EXPECT_DOUBLE_EQ(e.nrmse[0], std::sqrt(2.0 / 4) / 4);
  EXPECT_DOUBLE_EQ(e.rele[0], std::sqrt(2.0 / 24));
  EXPECT_TRUE(std::isnan(e.nrmse[1]));  // no range
  EXPECT_DOUBLE_EQ(e.rele[1], 0);
}

TEST(Stiffness, RecoversTheSlopeOfEachPress) {
  // Three presses at different spots (surfaces at different heights), force = k * depth along -z.
  const double k = 350;
  Eigen::MatrixXd tips(300, 3), forces = Eigen::MatrixXd::Zero(300, 3);
  for (int i = 0; i < 300; ++i) {
    const int press = i / 100, s = i % 100;
    const double surface = -0.1 - 0.01 * press, depth = s < 80 ? 0.0001 * s : 0;
    tips.row(i) << 0.01 * press, 0, surface - depth;
    forces(i, 2) = -k * depth;
  }
  const StiffnessFit fit = identifyStiffness(tips, forces, 0.1);
  EXPECT_NEAR(fit.stiffness, k, 1e-9 * k);
  EXPECT_EQ(fit.episodes, 3);
  EXPECT_NEAR(fit.direction.z(), -1, 1e-12);
}

}  // namespace
}  // namespace viscera::robot
