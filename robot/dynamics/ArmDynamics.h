// Joint-space rigid-body dynamics of a serial chain in modified DH (robot/kinematics), with the
// effects a cable-driven surgical arm adds: reflected motor inertia (armature), counterbalance
// springs and joint friction (Coulomb, viscous, Stribeck).
//
//   tau = M(q) qdd + c(q, qd) + g(q) + k(q) + f(qd)
//
// tau: joint efforts (N m, or N for a prismatic joint); M: link inertia plus armature; c: Coriolis
// and centrifugal terms; g: gravity; k: counterbalance; f: friction. The rigid-body part comes from
// the recursive Newton-Euler algorithm (Craig, ch. 6) on the link parameters written linearly
// (mass, first moment m*c, inertia about the link frame's origin), so the same code gives the
// regressor Y(q, qd, qdd) of least-squares identification: tau_rb = Y * pi.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "robot/kinematics/PsmKinematics.h"

namespace viscera::robot {

// Inertial parameters of one link, in the frame of its joint (the frame that moves with it).
struct LinkInertia {
  double mass = 0;                                     // kg
  Eigen::Vector3d com = Eigen::Vector3d::Zero();       // m, centre of mass
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();   // kg m^2, about the centre of mass
};

// Joint friction: (coulomb + stribeck * exp(-(v / stribeckVelocity)^2)) * tanh(v / smoothing) +
// viscous * v. The tanh stands in for sign(v): a true discontinuity has no derivative to integrate
// implicitly and no value at rest.
struct JointFriction {
  double coulomb = 0;            // N m (or N)
  double stribeck = 0;           // extra breakaway effort at rest, N m (or N)
  double stribeckVelocity = 0.02;  // rad/s (or m/s)
  double viscous = 0;            // N m s/rad (or N s/m)
  double smoothing = 1e-3;       // rad/s (or m/s)

  double effort(double v) const;
  double slope(double v) const;  // d effort / d v
};

// The counterbalance of a joint as a linear spring plus a constant effort:
// effort = stiffness * (q - rest) + offset.
struct JointSpring {
  double stiffness = 0;  // N m/rad (or N/m)
  double rest = 0;       // rad (or m)
  double offset = 0;     // N m (or N), constant part
  double effort(double q) const { return stiffness * (q - rest) + offset; }
};

class ArmDynamics {
 public:
  // One entry of links, armature, friction and springs per joint (viscera::Error otherwise).
  // gravity: acceleration of gravity in the base frame (m/s^2).
  ArmDynamics(SerialChain chain, std::vector<LinkInertia> links, Eigen::Vector3d gravity,
              std::vector<double> armature, std::vector<JointFriction> friction, std::vector<JointSpring> springs);

  int dof() const { return chain_.dof(); }
  const SerialChain& chain() const { return chain_; }
  const std::vector<LinkInertia>& links() const { return links_; }
  const Eigen::Vector3d& gravity() const { return gravity_; }
  const std::vector<double>& armature() const { return armature_; }
  const std::vector<JointFriction>& friction() const { return friction_; }
  const std::vector<JointSpring>& springs() const { return springs_; }

  // Rigid-body efforts M qdd + c + g (no armature, springs or friction).
  Eigen::VectorXd rigidBody(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd) const;
  // The whole model: rigid body + armature * qdd + springs + friction.
  Eigen::VectorXd inverseDynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd) const;
  // M(q) with the armature on its diagonal.
  Eigen::MatrixXd massMatrix(const Eigen::VectorXd& q) const;
  // Everything but the inertial term: c + g + springs (friction apart, see frictionEfforts).
  Eigen::VectorXd bias(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const;
  Eigen::VectorXd frictionEfforts(const Eigen::VectorXd& qd) const;

  // Energies of the rigid body plus armature (kinetic) and of gravity plus springs (potential), J.
  double kineticEnergy(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const;
  double potentialEnergy(const Eigen::VectorXd& q) const;

  // Link parameters written linearly: per link (m, m cx, m cy, m cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz),
  // the inertia about the link frame's origin.
  static constexpr int kLinkParameters = 10;
  Eigen::VectorXd linkParameters() const;
  // Rigid-body efforts for any link parameters (10 per link, as above).
  Eigen::VectorXd rigidBody(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd,
                            const Eigen::VectorXd& parameters, bool withGravity = true) const;

 private:
  SerialChain chain_;
  std::vector<LinkInertia> links_;
  Eigen::Vector3d gravity_;
  std::vector<double> armature_;
  std::vector<JointFriction> friction_;
  std::vector<JointSpring> springs_;
  Eigen::VectorXd parameters_;
};

// The PSM with the large needle driver (psmLargeNeedleDriver) with masses and inertias of the
// order of the dVRK PSM's (its yaw body, parallelogram, insertion stage and instrument), motor
// inertias reflected through the transmissions, friction and the pitch counterbalance of the same
// order as those identified on dVRK arms. Gravity: 9.81 m/s^2 with the yaw axis tilted 40 degrees
// from vertical and the shaft pointing down at the zero pose.
ArmDynamics psmDynamics();

}  // namespace viscera::robot
