#include "robot/kinematics/PsmKinematics.h"

#include <Eigen/Cholesky>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

namespace viscera::robot {

namespace {

const char* unitOf(JointType type) { return type == JointType::Revolute ? "rad" : "m"; }

}  // namespace

std::string LimitViolation::describe(JointType type) const {
  std::ostringstream s;
  s << "joint " << joint + 1 << " '" << name << "' = " << value << ' ' << unitOf(type) << " is outside ["
    << lower << ", " << upper << "] " << unitOf(type);
  return s.str();
}

SerialChain::SerialChain(std::vector<DhJoint> joints, const Eigen::Isometry3d& toolOffset)
    : joints_(std::move(joints)), toolOffset_(toolOffset) {
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const DhJoint& j = joints_[i];
    const std::string which = "SerialChain: joint " + std::to_string(i + 1) + " '" + j.name + "'";
    for (double v : {j.alpha, j.a, j.theta, j.d, j.offset, j.lower, j.upper})
      if (!std::isfinite(v)) throw Error(which + ": DH parameters and limits must be finite");
    if (j.lower > j.upper)
      throw Error(which + ": lower limit " + std::to_string(j.lower) + " exceeds upper limit " +
                  std::to_string(j.upper));
    cosAlpha_.push_back(std::cos(j.alpha));
    sinAlpha_.push_back(std::sin(j.alpha));
  }
  if (!toolOffset_.matrix().allFinite()) throw Error("SerialChain: the tool offset must be finite");
}

void SerialChain::requireSize(const Eigen::Ref<const Eigen::VectorXd>& v, const char* what) const {
  if (v.size() != dof())
    throw Error(std::string("SerialChain: expected ") + std::to_string(dof()) + " " + what + ", got " +
                std::to_string(v.size()));
}

Eigen::Isometry3d SerialChain::linkTransform(int i, double qi) const {
  const DhJoint& j = joints_[i];
  const bool revolute = j.type == JointType::Revolute;
  const double theta = j.theta + (revolute ? qi + j.offset : 0.0);
  const double d = j.d + (revolute ? 0.0 : qi + j.offset);
  const double ct = std::cos(theta), st = std::sin(theta);
  const double ca = cosAlpha_[i], sa = sinAlpha_[i];
  // RotX(alpha) * TransX(a) * RotZ(theta) * TransZ(d), multiplied out (Craig, eq. 3.6).
  Eigen::Isometry3d T;
  T.matrix() << ct, -st, 0, j.a,       //
      st * ca, ct * ca, -sa, -sa * d,  //
      st * sa, ct * sa, ca, ca * d,    //
      0, 0, 0, 1;
  return T;
}

Eigen::Isometry3d SerialChain::forwardKinematics(const Eigen::Ref<const Eigen::VectorXd>& q,
                                                 std::span<Eigen::Isometry3d> frames) const {
  requireSize(q, "joint values");
  if (static_cast<int>(frames.size()) != dof())
    throw Error("SerialChain: frame storage holds " + std::to_string(frames.size()) + " frames, expected " +
                std::to_string(dof()));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < dof(); ++i) {
    T = T * linkTransform(i, q[i]);
    frames[i] = T;
  }
  return T * toolOffset_;
}

ChainPose SerialChain::forwardKinematics(const Eigen::Ref<const Eigen::VectorXd>& q) const {
  ChainPose pose;
  pose.frames.resize(joints_.size());
  pose.tip = forwardKinematics(q, pose.frames);
  return pose;
}

Eigen::Isometry3d SerialChain::tipPose(const Eigen::Ref<const Eigen::VectorXd>& q) const {
  return forwardKinematics(q).tip;
}

void SerialChain::spatialJacobian(std::span<const Eigen::Isometry3d> frames, const Eigen::Isometry3d& tip,
                                  Eigen::Ref<Jacobian> J) const {
  if (static_cast<int>(frames.size()) != dof() || J.cols() != dof())
    throw Error("SerialChain: spatialJacobian needs " + std::to_string(dof()) + " frames and columns");
  const Eigen::Vector3d pTip = tip.translation();
  for (int i = 0; i < dof(); ++i) {
    const Eigen::Vector3d z = frames[i].linear().col(2);
    if (joints_[i].type == JointType::Revolute) {
      J.col(i).head<3>() = z.cross(pTip - frames[i].translation());
      J.col(i).tail<3>() = z;
    } else {
      J.col(i).head<3>() = z;
      J.col(i).tail<3>().setZero();
    }
  }
}

Jacobian SerialChain::spatialJacobian(const Eigen::Ref<const Eigen::VectorXd>& q) const {
  const ChainPose pose = forwardKinematics(q);
  Jacobian J(6, dof());
  spatialJacobian(pose.frames, pose.tip, J);
  return J;
}

Jacobian SerialChain::bodyJacobian(const Eigen::Ref<const Eigen::VectorXd>& q) const {
  const ChainPose pose = forwardKinematics(q);
  Jacobian J(6, dof());
  spatialJacobian(pose.frames, pose.tip, J);
  // Both halves are base-frame vectors; R_tip^T expresses them in tool-tip coordinates.
  const Eigen::Matrix3d Rt = pose.tip.linear().transpose();
  J.topRows<3>() = Rt * J.topRows<3>();
  J.bottomRows<3>() = Rt * J.bottomRows<3>();
  return J;
}

std::vector<LimitViolation> SerialChain::limitViolations(const Eigen::Ref<const Eigen::VectorXd>& q) const {
  requireSize(q, "joint values");
  std::vector<LimitViolation> out;
  for (int i = 0; i < dof(); ++i) {
    const DhJoint& j = joints_[i];
    // A NaN is outside every range: neither comparison below would catch it.
    if (!(q[i] >= j.lower && q[i] <= j.upper)) out.push_back({i, j.name, q[i], j.lower, j.upper});
  }
  return out;
}

void SerialChain::requireWithinLimits(const Eigen::Ref<const Eigen::VectorXd>& q, const SourceLoc& where) const {
  const std::vector<LimitViolation> violations = limitViolations(q);
  if (violations.empty()) return;
  std::string message;
  for (const LimitViolation& v : violations) {
    if (!message.empty()) message += "; ";
    message += v.describe(joints_[v.joint].type);
  }
  throw Error(where, message);
}

Eigen::VectorXd SerialChain::clampToLimits(const Eigen::Ref<const Eigen::VectorXd>& q) const {
  requireSize(q, "joint values");
  Eigen::VectorXd out(q);
  for (int i = 0; i < dof(); ++i) out[i] = std::clamp(out[i], joints_[i].lower, joints_[i].upper);
  return out;
}

Eigen::Vector3d rotationLog(const Eigen::Matrix3d& R) {
  // Eigen goes through a quaternion and takes the angle with atan2, which stays accurate both for
  // tiny angles (finite differences) and near pi.
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

IkResult SerialChain::inverseKinematics(const Eigen::Isometry3d& target,
                                        const Eigen::Ref<const Eigen::VectorXd>& qStart,
                                        const IkOptions& options) const {
  requireSize(qStart, "joint values");
  if (!(options.damping >= 0) || options.maxIterations < 0 || !(options.maxStep > 0))
    throw Error("SerialChain: inverse kinematics needs damping >= 0, maxIterations >= 0 and maxStep > 0");
  IkResult result;
  result.q = options.clampToLimits ? clampToLimits(qStart) : Eigen::VectorXd(qStart);
  std::vector<Eigen::Isometry3d> frames(joints_.size());
  Jacobian J(6, dof());
  const double lambda2 = options.damping * options.damping;
  Vector6d e;
  for (;;) {
    const Eigen::Isometry3d tip = forwardKinematics(result.q, frames);
    // Error twist in base coordinates: translation, and the rotation that takes the current
    // orientation to the target one (R_target = Exp(e_o) * R_tip), matching J_s's rows.
    e.head<3>() = target.translation() - tip.translation();
    e.tail<3>() = rotationLog(target.linear() * tip.linear().transpose());
    result.positionError = e.head<3>().norm();
    result.orientationError = e.tail<3>().norm();
    result.converged = result.positionError <= options.positionTolerance &&
                       result.orientationError <= options.orientationTolerance;
    if (result.converged || result.iterations >= options.maxIterations) break;
    spatialJacobian(frames, tip, J);
    const Eigen::Matrix<double, 6, 6> A = J * J.transpose() + lambda2 * Eigen::Matrix<double, 6, 6>::Identity();
    Eigen::VectorXd dq = J.transpose() * A.ldlt().solve(e);
    const double stepNorm = dq.norm();
    if (stepNorm > options.maxStep) dq *= options.maxStep / stepNorm;
    result.q += dq;
    if (options.clampToLimits) result.q = clampToLimits(result.q);
    ++result.iterations;
  }
  if (!options.clampToLimits) result.limitViolations = limitViolations(result.q);
  return result;
}

Vector6d SerialChain::wrenchFromJointEfforts(const Eigen::Ref<const Eigen::VectorXd>& q,
                                             const Eigen::Ref<const Eigen::VectorXd>& tau,
                                             double relativeThreshold) const {
  requireSize(tau, "joint efforts");
  const Jacobian J = spatialJacobian(q);
  // J_s^T (n x 6) F = tau: power balance tau . qdot = F . (J_s qdot) with F = (force, torque about
  // the tip) in base coordinates.
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(J.transpose(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  svd.setThreshold(relativeThreshold);
  return svd.solve(tau);
}

SerialChain psmLargeNeedleDriver() {
  constexpr double pi = std::numbers::pi;
  std::vector<DhJoint> joints = {
      // name, type, alpha, a, theta, d, offset, lower, upper
      {"outer_yaw", JointType::Revolute, pi / 2, 0, 0, 0, pi / 2, -1.588, 1.588},
      {"outer_pitch", JointType::Revolute, -pi / 2, 0, 0, 0, -pi / 2, -0.925, 0.925},
      {"outer_insertion", JointType::Prismatic, pi / 2, 0, 0, 0, -0.4318, 0, 0.24},
      {"outer_roll", JointType::Revolute, 0, 0, 0, 0.4162, 0, -4.538, 4.538},
      {"outer_wrist_pitch", JointType::Revolute, -pi / 2, 0, 0, 0, -pi / 2, -1.396, 1.396},
      {"outer_wrist_yaw", JointType::Revolute, -pi / 2, 0.0091, 0, 0, -pi / 2, -1.396, 1.396},
  };
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.linear() << 0, -1, 0,  //
      0, 0, 1,                //
      -1, 0, 0;
  return SerialChain(std::move(joints), tool);
}

}  // namespace viscera::robot
