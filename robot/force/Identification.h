// The physically identified free-space model: the arm's dynamic parameters estimated by linear
// least squares from free-space joint logs (the baseline the networks must beat, and a prior whose
// residual they can learn).
//
//   tau_j = Y_rb(q, qd, qdd) pi + a_j qdd_j + v_j qd_j + c_j tanh(qd_j / w) + k_j q_j + o_j
//
// Y_rb is the rigid-body regressor of the kinematic chain (10 parameters per link, ArmDynamics),
// a_j the armature, v_j and c_j viscous and Coulomb friction, k_j and o_j a counterbalance spring.
// The chain's kinematics and gravity's direction are known (the arm's mounting); the parameters are
// not. Parameters the data cannot tell apart (combinations with no effect on any effort) are
// resolved to the minimum-norm solution.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "robot/dynamics/ArmDynamics.h"
#include "robot/force/ArmLogs.h"

namespace viscera::robot {

struct IdentificationOptions {
  double coulombVelocity = 0.01;  // w of tanh(qd / w), rad/s (m/s for the insertion)
  double accelerationWindow = 0.01;  // s: accelerations by central differences over this span
  double relativeCutoff = 1e-8;      // singular values (of the scaled normal equations) below this share are dropped
};

class PhysicalModel {
 public:
  PhysicalModel() = default;
  PhysicalModel(const ArmDynamics& structure, IdentificationOptions options, Eigen::VectorXd parameters);

  int dof() const { return structure_.dof(); }
  const Eigen::VectorXd& parameters() const { return parameters_; }
  const IdentificationOptions& options() const { return options_; }
  static int parameterCount(int dof) { return dof * (ArmDynamics::kLinkParameters + 5); }
  // Column names: "link3.mcz", "joint2.viscous", ...
  static std::vector<std::string> parameterNames(int dof);

  // The regressor at one state: dof x parameterCount.
  Eigen::MatrixXd regressor(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd) const;
  Eigen::VectorXd predict(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd) const;
  // Free-space efforts along a log (samples x dof), accelerations from its velocities.
  Eigen::MatrixXd predict(const JointStateLog& log) const;

  // Identified from free-space logs (their measured efforts are all free-space dynamics).
  static PhysicalModel identify(const ArmDynamics& structure, const std::vector<JointStateLog>& logs,
                                const IdentificationOptions& options = {});

  // JSON: kind "physical", the options, named parameters and gravity (the structure is the PSM's).
  std::string toJson() const;
  static PhysicalModel fromJson(const std::string& text, const std::string& source, const ArmDynamics& structure);

 private:
  ArmDynamics structure_ = psmDynamics();
  IdentificationOptions options_;
  Eigen::VectorXd parameters_;
};

// Joint accelerations of a log (samples x dof) by central differences of its velocities over
// `window` seconds (one-sided at the ends).
Eigen::MatrixXd jointAccelerations(const JointStateLog& log, double window);

// The Cartesian wrench at the tip (base frame) that external joint efforts balance, F = J^-T tau,
// through the damped pseudo-inverse (J J^T + lambda^2 I)^-1 J tau: near singular poses it stays
// bounded instead of blowing up. lambda mixes units like J does (m for the force rows).
Vector6d wrenchFromExternalEfforts(const Jacobian& J, const Eigen::VectorXd& tau, double damping = 1e-3);

}  // namespace viscera::robot
