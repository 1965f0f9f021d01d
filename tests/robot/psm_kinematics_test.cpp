// dVRK PSM kinematics: forward kinematics against hand-derived poses, both Jacobians against
// central finite differences, inverse kinematics round trips, joint limits and the wrench helper.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <random>

#include "robot/kinematics/PsmKinematics.h"

using namespace viscera;
using namespace viscera::robot;

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;

Vec6 psmQ(double q1, double q2, double q3, double q4, double q5, double q6) {
  Vec6 q;
  q << q1, q2, q3, q4, q5, q6;
  return q;
}

// Uniform random joint values within the PSM's limits, kept a margin (fraction of each range)
// away from them so that finite-difference stencils and IK starting points stay inside.
Vec6 randomPsmQ(const SerialChain& psm, std::mt19937& rng, double margin = 0.05) {
  Vec6 q;
  for (int i = 0; i < 6; ++i) {
    const DhJoint& j = psm.joints()[i];
    const double m = margin * (j.upper - j.lower);
    q[i] = std::uniform_real_distribution<double>(j.lower + m, j.upper - m)(rng);
  }
  return q;
}

// Random poses with the instrument out of the cannula: insertion of at least 5 cm keeps the wrist
// away from the remote centre, where it sits at insertion 0.4318 - 0.4162 = 0.0156 m and yaw and
// pitch no longer move it (a singular configuration, in which no local method is reliable).
Vec6 randomWorkspaceQ(const SerialChain& psm, std::mt19937& rng) {
  Vec6 q = randomPsmQ(psm, rng);
  q[2] = std::uniform_real_distribution<double>(0.05, 0.23)(rng);
  return q;
}

// Rotation by `angle` about the unit axis `axis`.
Eigen::Matrix3d rot(const Eigen::Vector3d& axis, double angle) { return Eigen::AngleAxisd(angle, axis).toRotationMatrix(); }

// The tool-tip orientation at q = 0, derived by hand from the DH table: with all joints at zero,
// the frame of joint 6 has x = -X, y = -Z, z = -Y (base axes), and the tool offset
// [[0,-1,0],[0,0,1],[-1,0,0]] turns that into x = Y, y = X, z = -Z: the tool's z axis points down
// the shaft.
Eigen::Matrix3d homeOrientation() {
  Eigen::Matrix3d R;
  R << 0, 1, 0,  //
      1, 0, 0,   //
      0, 0, -1;
  return R;
}

// Distance from the remote centre of motion to the tip along the shaft at q = 0: the insertion
// offset minus the shaft length minus the wrist link, 0.4318 - 0.4162 - 0.0091 = 0.0065 m above
// the RCM, i.e. the tip's z at q = 0; insertion moves it down one for one.
constexpr double kTipZAtZero = 0.4318 - 0.4162 - 0.0091;

}  // namespace

TEST(PsmKinematics, CheckPoseTipFromTheDvrkTable) {
  const SerialChain psm = psmLargeNeedleDriver();
  const Eigen::Isometry3d tip = psm.tipPose(psmQ(0, 0, 0.12, 0, 0, 0));
  // Only rounding of a product of six 4 x 4 transforms (entries <= 0.5 m): 1e-12 m is ~1e3 ulps.
  EXPECT_NEAR(tip.translation().x(), 0, 1e-12);
  EXPECT_NEAR(tip.translation().y(), 0, 1e-12);
  EXPECT_NEAR(tip.translation().z(), -0.1135, 1e-12);
  EXPECT_LT((tip.linear() - homeOrientation()).norm(), 1e-12);
}

TEST(PsmKinematics, ZeroPoseAndInsertionMoveAlongTheShaft) {
  const SerialChain psm = psmLargeNeedleDriver();
  for (double insertion : {0.0, 0.05, 0.1, 0.2, 0.24}) {
    const Eigen::Isometry3d tip = psm.tipPose(psmQ(0, 0, insertion, 0, 0, 0));
    EXPECT_LT((tip.translation() - Eigen::Vector3d(0, 0, kTipZAtZero - insertion)).norm(), 1e-12) << insertion;
    EXPECT_LT((tip.linear() - homeOrientation()).norm(), 1e-12) << insertion;
  }
  // Insertion at any yaw/pitch/roll/wrist moves the tip along the shaft axis (frame 3's z), one
  // metre per metre, without rotating it.
  const ChainPose a = psm.forwardKinematics(psmQ(0.4, -0.3, 0.1, 1.0, 0.5, -0.7));
  const ChainPose b = psm.forwardKinematics(psmQ(0.4, -0.3, 0.13, 1.0, 0.5, -0.7));
  const Eigen::Vector3d shaft = a.frames[2].linear().col(2);
  EXPECT_LT((b.tip.translation() - a.tip.translation() - 0.03 * shaft).norm(), 1e-12);
  EXPECT_LT((b.tip.linear() - a.tip.linear()).norm(), 1e-12);
}

TEST(PsmKinematics, YawAndPitchRotateAboutTheRemoteCentre) {
  const SerialChain psm = psmLargeNeedleDriver();
  const double z = kTipZAtZero - 0.12;  // tip z at the check pose
  // Yaw's axis is frame 1's z = RotX(pi/2) * Z = -Y of the base: the tip swings in the x-z plane,
  // (-z sin q1, 0, z cos q1), and the whole tool frame turns with it.
  for (double yaw : {-1.2, -0.3, 0.5, 1.5}) {
    const Eigen::Isometry3d tip = psm.tipPose(psmQ(yaw, 0, 0.12, 0, 0, 0));
    EXPECT_LT((tip.translation() - Eigen::Vector3d(-z * std::sin(yaw), 0, z * std::cos(yaw))).norm(), 1e-12);
    EXPECT_LT((tip.linear() - rot(-Eigen::Vector3d::UnitY(), yaw) * homeOrientation()).norm(), 1e-12);
  }
  // Pitch's axis at zero yaw is -X of the base: the tip swings in the y-z plane, (0, z sin q2, z cos q2).
  for (double pitch : {-0.9, 0.2, 0.8}) {
    const Eigen::Isometry3d tip = psm.tipPose(psmQ(0, pitch, 0.12, 0, 0, 0));
    EXPECT_LT((tip.translation() - Eigen::Vector3d(0, z * std::sin(pitch), z * std::cos(pitch))).norm(), 1e-12);
    EXPECT_LT((tip.linear() - rot(-Eigen::Vector3d::UnitX(), pitch) * homeOrientation()).norm(), 1e-12);
  }
  // Roll turns the tool about the shaft (-Z at the check pose) and leaves the tip where it is.
  for (double roll : {-4.0, 1.0, 3.0}) {
    const Eigen::Isometry3d tip = psm.tipPose(psmQ(0, 0, 0.12, roll, 0, 0));
    EXPECT_LT((tip.translation() - Eigen::Vector3d(0, 0, z)).norm(), 1e-12);
    EXPECT_LT((tip.linear() - rot(-Eigen::Vector3d::UnitZ(), roll) * homeOrientation()).norm(), 1e-12);
  }
}

TEST(PsmKinematics, ShaftAlwaysPassesThroughTheRemoteCentre) {
  const SerialChain psm = psmLargeNeedleDriver();
  std::mt19937 rng(11);
  for (int k = 0; k < 100; ++k) {
    const Vec6 q = randomPsmQ(psm, rng, 0);
    const ChainPose pose = psm.forwardKinematics(q);
    // Frame 4 (the shaft's end, where the wrist starts) lies on the shaft axis through the base
    // origin, at distance q3 - (0.4318 - 0.4162) from it.
    const Eigen::Vector3d shaft = pose.frames[2].linear().col(2);
    const Eigen::Vector3d wrist = pose.frames[3].translation();
    EXPECT_LT(wrist.cross(shaft).norm(), 1e-12);
    EXPECT_NEAR(wrist.dot(shaft), q[2] - (0.4318 - 0.4162), 1e-12);
    // The tip is the wrist-yaw link (0.0091 m) beyond the wrist-pitch axis.
    EXPECT_NEAR((pose.tip.translation() - pose.frames[4].translation()).norm(), 0.0091, 1e-12);
  }
}

TEST(PsmKinematics, NoAllocationFormMatchesTheAllocatingOne) {
  const SerialChain psm = psmLargeNeedleDriver();
  const Vec6 q = psmQ(0.3, -0.2, 0.15, 2.0, -0.4, 0.9);
  std::array<Eigen::Isometry3d, 6> frames;
  const Eigen::Isometry3d tip = psm.forwardKinematics(q, frames);
  const ChainPose pose = psm.forwardKinematics(q);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(frames[i].matrix(), pose.frames[i].matrix());
  EXPECT_EQ(tip.matrix(), pose.tip.matrix());
  std::array<Eigen::Isometry3d, 5> tooFew;
  EXPECT_THROW(psm.forwardKinematics(q, tooFew), Error);
  EXPECT_THROW(psm.forwardKinematics(Eigen::VectorXd::Zero(5)), Error);
}

TEST(PsmKinematics, JacobiansEqualFiniteDifferencesOfForwardKinematics) {
  const SerialChain psm = psmLargeNeedleDriver();
  std::mt19937 rng(3);
  const double h = 1e-6;
  double worstSpatial = 0, worstBody = 0;
  for (int k = 0; k < 50; ++k) {
    const Vec6 q = randomPsmQ(psm, rng);
    const Eigen::Isometry3d T = psm.tipPose(q);
    Jacobian spatialFd(6, 6), bodyFd(6, 6);
    for (int j = 0; j < 6; ++j) {
      Vec6 qp = q, qm = q;
      qp[j] += h;
      qm[j] -= h;
      const Eigen::Isometry3d Tp = psm.tipPose(qp), Tm = psm.tipPose(qm);
      const Eigen::Vector3d dp = (Tp.translation() - Tm.translation()) / (2 * h);
      // Base-frame angular velocity: R(q+h) = Exp(w 2h) R(q-h); body: R(q+h) = R(q-h) Exp(w_b 2h).
      spatialFd.col(j) << dp, rotationLog(Tp.linear() * Tm.linear().transpose()) / (2 * h);
      bodyFd.col(j) << T.linear().transpose() * dp, rotationLog(Tm.linear().transpose() * Tp.linear()) / (2 * h);
    }
    const Jacobian Js = psm.spatialJacobian(q), Jb = psm.bodyJacobian(q);
    worstSpatial = std::max(worstSpatial, (Js - spatialFd).norm() / Js.norm());
    worstBody = std::max(worstBody, (Jb - bodyFd).norm() / Jb.norm());
    // The two are the same twist in two coordinate systems.
    EXPECT_LT((Js.topRows<3>() - T.linear() * Jb.topRows<3>()).norm(), 1e-14 * Js.norm() + 1e-15);
  }
  // Central differences with h = 1e-6: truncation ~h^2 = 1e-12, rounding ~eps/h ~ 1e-10 relative.
  EXPECT_LT(worstSpatial, 1e-7);
  EXPECT_LT(worstBody, 1e-7);
  std::printf("worst relative Jacobian error vs finite differences: spatial %.2e, body %.2e\n", worstSpatial,
              worstBody);
}

TEST(PsmKinematics, InverseKinematicsRoundTripsRandomReachablePoses) {
  const SerialChain psm = psmLargeNeedleDriver();
  std::mt19937 rng(5);
  IkOptions options;
  options.positionTolerance = 1e-12;
  options.orientationTolerance = 1e-12;
  int worstIterations = 0;
  double worstPosition = 0, worstOrientation = 0;
  for (int k = 0; k < 100; ++k) {
    const Vec6 qTrue = randomWorkspaceQ(psm, rng);
    const Eigen::Isometry3d target = psm.tipPose(qTrue);
    // Start within 0.3 rad / 3 cm of the answer, as when following a trajectory.
    Vec6 start = qTrue;
    for (int i = 0; i < 6; ++i)
      start[i] += std::uniform_real_distribution<double>(-1, 1)(rng) * (i == 2 ? 0.03 : 0.3);
    const IkResult r = psm.inverseKinematics(target, start, options);
    ASSERT_TRUE(r.converged) << "pose " << k << ": " << r.positionError << " m, " << r.orientationError << " rad";
    EXPECT_TRUE(r.limitViolations.empty());
    EXPECT_TRUE(psm.limitViolations(r.q).empty());
    // Check against the target independently of the result's own error fields.
    const Eigen::Isometry3d reached = psm.tipPose(r.q);
    const double dp = (reached.translation() - target.translation()).norm();
    const double dr = rotationLog(reached.linear().transpose() * target.linear()).norm();
    EXPECT_LT(dp, 1e-9);
    EXPECT_LT(dr, 1e-9);
    worstIterations = std::max(worstIterations, r.iterations);
    worstPosition = std::max(worstPosition, dp);
    worstOrientation = std::max(worstOrientation, dr);
  }
  std::printf("IK: worst %d iterations, %.2e m, %.2e rad\n", worstIterations, worstPosition, worstOrientation);
}

TEST(PsmKinematics, InverseKinematicsFromTheCheckPose) {
  // Far targets from one fixed start: the step limit keeps the iteration on the linearisation.
  const SerialChain psm = psmLargeNeedleDriver();
  std::mt19937 rng(9);
  const Vec6 start = psmQ(0, 0, 0.12, 0, 0, 0);
  int converged = 0;
  for (int k = 0; k < 50; ++k) {
    Vec6 qTrue = randomWorkspaceQ(psm, rng);
    qTrue[3] = std::uniform_real_distribution<double>(-1.5, 1.5)(rng);  // one roll branch
    const IkResult r = psm.inverseKinematics(psm.tipPose(qTrue), start);
    if (r.converged) {
      ++converged;
      EXPECT_LT(r.positionError, 1e-9);
      EXPECT_LT(r.orientationError, 1e-9);
    }
  }
  std::printf("IK from the check pose: %d of 50 converged\n", converged);
  EXPECT_EQ(converged, 50);
}

TEST(PsmKinematics, InverseKinematicsReportsOrClampsLimits) {
  const SerialChain psm = psmLargeNeedleDriver();
  // A target that needs insertion 0.26 m (beyond 0.24): clamped, it stops at the limit, short by
  // 0.02 m along the shaft; unclamped, it reaches the target and reports the insertion joint.
  const Eigen::Isometry3d target = psm.tipPose(psmQ(0.2, 0.1, 0.26, 0, 0, 0));
  const Vec6 start = psmQ(0.2, 0.1, 0.2, 0, 0, 0);
  const IkResult clamped = psm.inverseKinematics(target, start);
  EXPECT_FALSE(clamped.converged);
  EXPECT_NEAR(clamped.q[2], 0.24, 1e-12);
  EXPECT_NEAR(clamped.positionError, 0.02, 1e-9);
  EXPECT_TRUE(clamped.limitViolations.empty());

  IkOptions free;
  free.clampToLimits = false;
  const IkResult unclamped = psm.inverseKinematics(target, start, free);
  EXPECT_TRUE(unclamped.converged);
  EXPECT_NEAR(unclamped.q[2], 0.26, 1e-9);
  ASSERT_EQ(unclamped.limitViolations.size(), 1u);
  EXPECT_EQ(unclamped.limitViolations[0].joint, 2);
}

TEST(PsmKinematics, JointLimitsAreReported) {
  const SerialChain psm = psmLargeNeedleDriver();
  EXPECT_TRUE(psm.limitViolations(psmQ(0, 0, 0.12, 0, 0, 0)).empty());
  EXPECT_TRUE(psm.limitViolations(psmQ(1.588, -0.925, 0, 4.538, -1.396, 1.396)).empty());  // bounds inclusive
  const Vec6 bad = psmQ(0, 1.0, 0.3, 0, 0, -1.5);
  const std::vector<LimitViolation> v = psm.limitViolations(bad);
  ASSERT_EQ(v.size(), 3u);
  EXPECT_EQ(v[0].joint, 1);
  EXPECT_EQ(v[1].joint, 2);
  EXPECT_EQ(v[1].name, "outer_insertion");
  EXPECT_DOUBLE_EQ(v[1].value, 0.3);
  EXPECT_DOUBLE_EQ(v[1].lower, 0);
  EXPECT_DOUBLE_EQ(v[1].upper, 0.24);
  EXPECT_EQ(v[2].joint, 5);
  Vec6 nan = psmQ(0, 0, 0.1, 0, 0, 0);
  nan[4] = std::nan("");
  EXPECT_EQ(psm.limitViolations(nan).size(), 1u);

  try {
    psm.requireWithinLimits(bad, SourceLoc{"joints.csv", 12, 0});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("joints.csv:12"), std::string::npos) << what;
    EXPECT_NE(what.find("joint 3 'outer_insertion' = 0.3 m is outside [0, 0.24] m"), std::string::npos) << what;
    EXPECT_NE(what.find("joint 2 'outer_pitch'"), std::string::npos) << what;
    EXPECT_NE(what.find("joint 6 'outer_wrist_yaw'"), std::string::npos) << what;
  }
  const Eigen::VectorXd clamped = psm.clampToLimits(bad);
  EXPECT_EQ(clamped[1], 0.925);
  EXPECT_EQ(clamped[2], 0.24);
  EXPECT_EQ(clamped[5], -1.396);
}

TEST(PsmKinematics, InvalidChainsAreRejected) {
  DhJoint j{"j", JointType::Revolute, 0, 0, 0, 0, 0, 1, -1};
  EXPECT_THROW(SerialChain({j}, Eigen::Isometry3d::Identity()), Error);
  j.lower = -1;
  j.upper = 1;
  j.a = std::nan("");
  EXPECT_THROW(SerialChain({j}, Eigen::Isometry3d::Identity()), Error);
}

TEST(PsmKinematics, WrenchFromJointEffortsSolvesJTransposeF) {
  const SerialChain psm = psmLargeNeedleDriver();
  std::mt19937 rng(13);
  std::normal_distribution<double> n01(0, 1);
  for (int k = 0; k < 50; ++k) {
    const Vec6 q = randomPsmQ(psm, rng);
    const Jacobian J = psm.spatialJacobian(q);
    // A known wrench (force in N, torque in N m) maps to tau = J^T F; the helper must recover it.
    Vec6 F;
    for (int i = 0; i < 6; ++i) F[i] = n01(rng);
    const Vec6 tau = J.transpose() * F;
    const Vec6 recovered = psm.wrenchFromJointEfforts(q, tau);
    // J is well conditioned within the margin (condition number below ~1e3), so 1e-9 relative
    // leaves room for the SVD's rounding.
    EXPECT_LT((recovered - F).norm(), 1e-9 * F.norm()) << k;
    // And random efforts give a wrench that reproduces them.
    Vec6 t;
    for (int i = 0; i < 6; ++i) t[i] = n01(rng);
    EXPECT_LT((J.transpose() * psm.wrenchFromJointEfforts(q, t) - t).norm(), 1e-9 * t.norm()) << k;
  }
}

TEST(PsmKinematics, WrenchOfAShortChainIsTheMinimumNormSolution) {
  // A planar two-link arm (revolute z axes, links 0.3 m and 0.2 m along x): its 2 x 6 system
  // J^T F = tau has a plane of solutions; the pseudo-inverse picks F = J (J^T J)^-1 tau.
  const std::vector<DhJoint> joints = {{"shoulder", JointType::Revolute, 0, 0, 0, 0, 0, -3, 3},
                                       {"elbow", JointType::Revolute, 0, 0.3, 0, 0, 0, -3, 3}};
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.translation() = Eigen::Vector3d(0.2, 0, 0);
  const SerialChain arm(joints, tool);
  const Eigen::Vector2d q(0.4, 0.7);
  // Hand-derived: tip = (0.3 c1 + 0.2 c12, 0.3 s1 + 0.2 s12, 0).
  const double c1 = std::cos(0.4), s1 = std::sin(0.4), c12 = std::cos(1.1), s12 = std::sin(1.1);
  Jacobian J(6, 2);
  J << -0.3 * s1 - 0.2 * s12, -0.2 * s12,  //
      0.3 * c1 + 0.2 * c12, 0.2 * c12,     //
      0, 0,                                //
      0, 0,                                //
      0, 0,                                //
      1, 1;
  EXPECT_LT((arm.spatialJacobian(q) - J).norm(), 1e-14);
  const Eigen::Vector2d tau(0.5, -0.2);
  const Vec6 expected = J * (J.transpose() * J).inverse() * tau;
  EXPECT_LT((arm.wrenchFromJointEfforts(q, tau) - expected).norm(), 1e-12);
}
