// Force estimation from robot signals (dissertation §2.3-2.5): models that predict an arm's
// free-space joint efforts from its joint states (indirect estimation: tau_ext = tau - tau_free,
// F = J^-T tau_ext), or the tip wrench directly from joint velocities and efforts.
//
// Kinds:
//  - "physical": the least-squares identified dynamic model (robot/force/Identification.h);
//  - "network": a Regressor over a window of joint positions and velocities, predicting each joint's
//    free-space effort. With a base model it learns the base's residual (the base's prediction also
//    among its inputs when `baseInputs`): the trocar correction is a window-30 network on a
//    free-space base; a network on a physical base learns what the physics leaves out;
//  - "direct": a Regressor from a window of joint velocities and efforts to the tip force (3) or
//    wrench (6).
// A model is a folder: force.json (kind, rate, window, inputs) and its parts (physical.json, a
// network/ regressor folder, the base model in base/).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>

#include "learning/nn/Regressor.h"
#include "robot/dynamics/ArmDynamics.h"
#include "robot/force/ArmLogs.h"
#include "robot/force/Identification.h"

namespace viscera::learning {

class ForceModel {
 public:
  std::string kind;       // "physical", "network" or "direct"
  double rate = 200;      // samples per second the model works at (logs are resampled to it)
  int dof = 6;
  int window = 1;
  bool baseInputs = false;
  int wrenchOutputs = 3;  // direct: 3 (force) or 6 (force and torque)
  std::optional<robot::PhysicalModel> physical;
  std::optional<Regressor> network;
  std::shared_ptr<ForceModel> base;
  std::string description;  // what it is, for reports
  std::string training;     // JSON: how it was trained (data, epochs, ...)

  // Free-space efforts along a log already at the model's rate (samples x dof). Not for "direct".
  Eigen::MatrixXd freeSpaceEfforts(const robot::JointStateLog& log) const;
  // Tip wrenches along a log at the model's rate (samples x 6, base frame; a direct model of forces
  // only gives zero torques). Indirect models use the Jacobian of the PSM at the logged q, or
  // `jacobian` (samples x 6 dof, row-major rows) when given.
  Eigen::MatrixXd wrenches(const robot::JointStateLog& log, const Eigen::MatrixXd* jacobian = nullptr,
                           double damping = 1e-3) const;

  // The estimate at the log's last sample only (what an online estimator computes each sample):
  // the network sees one input row, a base model the rows that row's window needs.
  Eigen::VectorXd lastFreeSpaceEffort(const robot::JointStateLog& log) const;
  robot::Vector6d lastWrench(const robot::JointStateLog& log, double damping = 1e-3) const;

  // The network's input rows for a log (samples x window * features): the window ends at each
  // sample, padded with the first sample at the log's start.
  Eigen::MatrixXf networkInputs(const robot::JointStateLog& log) const;

  void save(const std::string& folder) const;
  static ForceModel load(const std::string& folder);
};

// Windows of per-sample features: row i holds rows i-window+1..i of `features` (the first row
// repeated before the start), oldest first.
Eigen::MatrixXf windowed(const Eigen::MatrixXd& features, int window);

}  // namespace viscera::learning
