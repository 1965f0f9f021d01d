// Serial-chain kinematics in modified Denavit-Hartenberg parameters (Craig's convention) and the
// da Vinci Research Kit's Patient Side Manipulator (PSM) with the large needle driver.
//
// Conventions used throughout:
//  - Link transform of joint i: T_i = RotX(alpha) * TransX(a) * RotZ(theta) * TransZ(d). Joint i
//    moves along / about the z axis of its own frame (the frame T_1 * ... * T_i).
//  - Joint values q (n): rad for revolute joints, m for prismatic joints (the chain's length unit).
//  - Twists and wrenches are 6-vectors, LINEAR FIRST, ANGULAR SECOND: a twist is
//    (v, omega), a wrench is (force, torque).
//  - "Spatial" Jacobian follows the dVRK, not screw theory: J_s * qdot = (v_tip, omega), the linear
//    velocity of the tool-tip origin and the angular velocity of the tool frame, both expressed in
//    BASE coordinates. It is the body Jacobian with both 3-row halves rotated by R_tip
//    (J_s = blockdiag(R_tip, R_tip) * J_b). The screw-theory spatial Jacobian (velocity of the
//    point at the base origin) is not used.
//  - Body Jacobian: J_b * qdot = (v_tip, omega) expressed in TOOL-TIP coordinates.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <span>
#include <string>
#include <vector>

#include "core/Error.h"

namespace viscera::robot {

enum class JointType { Revolute, Prismatic };

// 6 x n Jacobian: rows 0-2 linear velocity, rows 3-5 angular velocity.
using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic>;
// (force, torque) or (v, omega).
using Vector6d = Eigen::Matrix<double, 6, 1>;

// One joint of a modified-DH chain. `theta` and `d` are the constant parts of the link transform;
// the joint variable plus `offset` is added to theta (revolute) or to d (prismatic). The limits
// apply to the joint variable itself (before the offset), as the robot's joint readings do.
struct DhJoint {
  std::string name;
  JointType type = JointType::Revolute;
  double alpha = 0;  // rad
  double a = 0;      // m
  double theta = 0;  // rad, constant part
  double d = 0;      // m, constant part
  double offset = 0; // rad (revolute) or m (prismatic)
  double lower = 0;  // joint limits of q, inclusive
  double upper = 0;
};

// A joint value outside its range.
struct LimitViolation {
  int joint = 0;  // 0-based index
  std::string name;
  double value = 0;
  double lower = 0;
  double upper = 0;

  // "joint 3 'insertion' = 0.3 m is outside [0, 0.24] m" (1-based joint number, as in the DH table).
  std::string describe(JointType type) const;
};

// Options of the damped least-squares inverse kinematics.
struct IkOptions {
  // Damping lambda of dq = J^T (J J^T + lambda^2 I)^-1 e. The error e mixes m (position rows) and
  // rad (orientation rows), so lambda does too; it only matters near singular configurations,
  // where it bounds the step instead of letting it blow up.
  double damping = 1e-4;
  int maxIterations = 200;
  double positionTolerance = 1e-10;     // m, |p_target - p_tip|
  double orientationTolerance = 1e-10;  // rad, angle of R_target * R_tip^T
  // The largest step per iteration (Euclidean norm of dq, rad and m mixed); a longer step is scaled
  // down to this length so that far-away targets are approached along the linearisation.
  double maxStep = 0.2;
  // true: every iterate is clamped into the joint limits (projected DLS), so the answer is always
  // within limits but a target reachable only outside them is not reached (converged = false).
  // false: the limits are ignored during the iteration and only reported in IkResult.
  bool clampToLimits = true;
};

struct IkResult {
  Eigen::VectorXd q;       // final joint values (n)
  bool converged = false;  // both tolerances met
  int iterations = 0;      // number of updates of q
  double positionError = 0;     // m, at the final q
  double orientationError = 0;  // rad, at the final q
  std::vector<LimitViolation> limitViolations;  // of the final q (empty when clamping)
};

// Forward kinematics with every frame (allocating form).
struct ChainPose {
  std::vector<Eigen::Isometry3d> frames;  // frames[i]: base -> frame of joint i (0-based), n entries
  Eigen::Isometry3d tip = Eigen::Isometry3d::Identity();  // base -> tool tip (last frame * tool offset)
};

class SerialChain {
 public:
  // Throws viscera::Error when a parameter is not finite or a joint's lower limit exceeds its upper.
  SerialChain(std::vector<DhJoint> joints, const Eigen::Isometry3d& toolOffset);

  int dof() const { return static_cast<int>(joints_.size()); }
  const std::vector<DhJoint>& joints() const { return joints_; }
  const Eigen::Isometry3d& toolOffset() const { return toolOffset_; }

  // Link transform T_i of joint i (0-based) for the joint value qi.
  Eigen::Isometry3d linkTransform(int i, double qi) const;

  // Forward kinematics into caller-owned storage (no allocation): frames[i] = base -> frame of
  // joint i, for all n joints; returns base -> tool tip. q and frames must both have n entries
  // (viscera::Error otherwise). Joint limits are not checked here.
  Eigen::Isometry3d forwardKinematics(const Eigen::Ref<const Eigen::VectorXd>& q,
                                      std::span<Eigen::Isometry3d> frames) const;
  ChainPose forwardKinematics(const Eigen::Ref<const Eigen::VectorXd>& q) const;
  Eigen::Isometry3d tipPose(const Eigen::Ref<const Eigen::VectorXd>& q) const;

  // dVRK "spatial" Jacobian (see the top of this file) from frames and tip computed by
  // forwardKinematics, into caller-owned 6 x n storage (no allocation). Column i is
  // (z_i x (p_tip - p_i), z_i) for a revolute joint and (z_i, 0) for a prismatic one, with z_i and
  // p_i the axis and origin of joint i's frame in base coordinates.
  void spatialJacobian(std::span<const Eigen::Isometry3d> frames, const Eigen::Isometry3d& tip,
                       Eigen::Ref<Jacobian> J) const;
  Jacobian spatialJacobian(const Eigen::Ref<const Eigen::VectorXd>& q) const;
  // Body Jacobian: the same twist expressed in tool-tip coordinates.
  Jacobian bodyJacobian(const Eigen::Ref<const Eigen::VectorXd>& q) const;

  // Every joint value outside its limits, in joint order (empty when all are within).
  std::vector<LimitViolation> limitViolations(const Eigen::Ref<const Eigen::VectorXd>& q) const;
  // Throws viscera::Error at `where` listing every violation ("joint 3 'insertion' = 0.3 m is
  // outside [0, 0.24] m; ..."); does nothing when q is within limits.
  void requireWithinLimits(const Eigen::Ref<const Eigen::VectorXd>& q, const SourceLoc& where = {}) const;
  Eigen::VectorXd clampToLimits(const Eigen::Ref<const Eigen::VectorXd>& q) const;

  // Damped least-squares inverse kinematics for a full tool-tip pose (position and orientation)
  // starting from qStart (n). See IkOptions for damping, limits and stopping. A local method: it
  // finds the solution nearest (along the iteration) to qStart, so start from the previous sample
  // when following a trajectory. For the PSM, poses with the wrist near the remote centre
  // (insertion near 0.0156 m, where yaw and pitch stop moving it) are singular and may not converge.
  IkResult inverseKinematics(const Eigen::Isometry3d& target, const Eigen::Ref<const Eigen::VectorXd>& qStart,
                             const IkOptions& options = {}) const;

  // Cartesian wrench at the tool tip, (force, torque about the tip origin), in BASE coordinates,
  // that the joint efforts tau (n: N m for revolute, N for prismatic) balance: the solution of
  // J_s^T F = tau ("F = J^-T tau"). When J_s^T is not invertible (n != 6, or a singular pose) F is
  // the minimum-norm least-squares solution, computed with an SVD in which singular values below
  // `relativeThreshold` times the largest are treated as zero (the pseudo-inverse).
  Vector6d wrenchFromJointEfforts(const Eigen::Ref<const Eigen::VectorXd>& q,
                                  const Eigen::Ref<const Eigen::VectorXd>& tau,
                                  double relativeThreshold = 1e-10) const;

 private:
  void requireSize(const Eigen::Ref<const Eigen::VectorXd>& v, const char* what) const;

  std::vector<DhJoint> joints_;
  std::vector<double> cosAlpha_, sinAlpha_;  // per joint, precomputed for the link transforms
  Eigen::Isometry3d toolOffset_;
};

// Rotation vector (axis * angle, |angle| <= pi) of a rotation matrix: the matrix logarithm.
Eigen::Vector3d rotationLog(const Eigen::Matrix3d& R);

// The PSM with the large needle driver (modified DH table of the dVRK, base frame at the remote
// centre of motion): yaw, pitch, insertion (prismatic, m), roll, wrist pitch, wrist yaw; tool-tip
// offset rotation [[0,-1,0],[0,0,1],[-1,0,0]] with no translation. At q = (0, 0, 0.12, 0, 0, 0)
// the tool tip is at (0, 0, -0.1135) m.
SerialChain psmLargeNeedleDriver();
inline constexpr int kPsmDof = 6;

}  // namespace viscera::robot
