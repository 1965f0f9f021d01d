// Simulated arm data with known truth: the arm's dynamics (ArmDynamics) under a joint PID
// controller following a teleoperation-like reference, with switchable environment effects
// (trocar body wall, cannula seal, a compliant phantom under the tool tip) and a measurement model
// (transmission backlash, noise), sampled like a dVRK joint log.
//
// Sign convention of the efforts (Eq. 2.4): the motor effort balances everything,
//   tau = M qdd + c + g + k + f(qd) + tau_trocar + J^T F_ext,
// where F_ext is the wrench the tool applies TO the environment at its tip, in base coordinates
// (what a force sensor under the phantom reads); tau_ext = J^T F_ext is the external joint effort.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "robot/dynamics/ArmDynamics.h"

namespace viscera::robot {

// The body wall around a trocar: it holds the shaft laterally at an anchor point, which sits off
// the remote centre of motion (an arm is never docked exactly at the incision), with a stiffening
// spring and damping. The force acts on the shaft at its point nearest the anchor.
struct TrocarWall {
  bool enabled = false;
  Eigen::Vector3d anchor{0.003, 0.0, -0.025};  // m, base frame (below the remote centre)
  double stiffness = 800;                      // N/m
  double cubic = 2e6;                          // N/m^3, stiffening of soft tissue
  double damping = 20;                         // N s/m
};

// The cannula seal's friction on the instrument shaft: along it (insertion) and about it (roll).
struct CannulaSeal {
  bool enabled = false;
  JointFriction axial{1.0, 0.5, 0.005, 3.0, 1e-4};   // N, on the insertion joint
  JointFriction roll{0.01, 0.005, 0.05, 0.005, 1e-3};  // N m, on the roll joint
};

// A compliant phantom below the tool tip: a half-space with a linear spring, damping and
// regularised Coulomb friction. Its stiffness is the truth of stiffness identification. With an
// external environment (ArmSimulationOptions::environment) its plane only places the palpations.
struct Phantom {
  bool enabled = false;
  Eigen::Vector3d point{0.0, 0.0, -0.15};  // m, on the surface (base frame)
  Eigen::Vector3d normal{0.0, -0.766044443118978, 0.642787609686539};  // outward, unit (up at 40 deg)
  double stiffness = 600;  // N/m
  double damping = 5;      // N s/m
  double friction = 0.3;   // Coulomb coefficient
  double radius = 0;       // m: palpations press within this distance of `point` (0: anywhere)
};

// What the robot's sensors do to the truth.
struct MeasurementModel {
  std::vector<double> backlash;        // full width of the dead band of each joint's reading (play operator)
  std::vector<double> positionNoise;   // standard deviations, per joint
  std::vector<double> velocityNoise;
  std::vector<double> effortNoise;

  // Perfect sensors: no backlash, no noise.
  void makePerfect();
};

// Joint PID gains: tau = kp (q_ref - q) + kd (qd_ref - qd) + ki * integral(q_ref - q).
struct JointGains {
  std::vector<double> kp, kd, ki;
};

// The teleoperation-like reference: a random walk of joint-space waypoints (each step at most
// `step` of the joint's range, within [lower, upper]) joined by minimum-jerk segments of random
// duration, plus a slow wander (sums of sines). With a phantom, a share of the moves are
// palpations: above a point, into the surface along the shaft by a random depth, held, and back;
// free moves keep above the surface (retracting first when the path would dip into it).
struct Excitation {
  std::vector<double> lower, upper;  // joint ranges of the waypoints
  double step = 0.2;                 // largest step between waypoints, share of the range (large: a
                                     // calibration recording that reaches across the workspace in minutes)
  double minSegment = 1.5, maxSegment = 5.0;  // s
  double wander = 0.004;       // relative amplitude of the sines (share of each joint's range)
  double palpationShare = 0.5; // with a phantom: share of moves that press it
  double minDepth = 0.004, maxDepth = 0.018;  // m, commanded depth below the surface
};

// The tool's wrench on an environment the simulator does not model itself (a Viscera scene), for
// the tip's pose and twist (v, omega; base frame, m, rad) at time t: (force, torque about the tip),
// base frame, N and N m. Called once per sample; the wrench is held over the sample's steps.
using ArmEnvironment = std::function<Vector6d(double t, const Eigen::Isometry3d& tip, const Vector6d& twist)>;

struct ArmSimulationOptions {
  double duration = 60;  // s
  double rate = 1000;    // samples per second
  int substeps = 5;      // integration steps per sample
  std::uint64_t seed = 1;
  TrocarWall trocar;
  CannulaSeal seal;
  Phantom phantom;
  MeasurementModel measurement;
  JointGains gains;
  Excitation excitation;
  ArmEnvironment environment;  // none: the analytic phantom (when enabled) is the environment
};

// Everything sampled: one row per sample in each matrix.
struct ArmRecording {
  int dof = 0;
  std::vector<double> t;
  // Measured, as a robot logs them.
  Eigen::MatrixXd q, qd, effort;  // samples x dof
  // Truth.
  Eigen::MatrixXd qTrue, qdTrue;
  Eigen::MatrixXd freeEffort;      // M qdd + c + g + k + f at the sample: what a free-space model predicts
  Eigen::MatrixXd trocarEffort;    // the body wall's and the seal's share of the motor effort
  Eigen::MatrixXd externalEffort;  // J^T F_ext
  Eigen::MatrixXd wrench;          // samples x 6: F_ext (force, torque about the tip), base frame
  Eigen::MatrixXd jacobian;        // samples x 6n: J_s at the measured q, row-major
  Eigen::MatrixXd tip;             // samples x 3: tool-tip position (true), m
  int samples() const { return static_cast<int>(t.size()); }
};

// The dVRK PSM's defaults: gains, measurement, excitation ranges (within the joint limits).
ArmSimulationOptions psmSimulationDefaults();

// Integrates with a linearly implicit Euler step (the controller's gains and the friction's slope
// taken implicitly, so the stiff friction at rest does not need tiny steps). `progress` (when set)
// is called with the share done. Throws viscera::Error for options that do not fit the arm.
ArmRecording simulateArm(const ArmDynamics& arm, const ArmSimulationOptions& options,
                         const std::function<void(double)>& progress = {});

}  // namespace viscera::robot
