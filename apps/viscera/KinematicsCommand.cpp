// `viscera kinematics fk` writes the tool-tip trajectory of a joint log; `viscera kinematics ik`
// writes the joint log that reaches each pose of a Cartesian trajectory (damped least squares,
// started from the previous sample's solution). Poses are in the scene frame and length unit when a
// transform (robot -> scene) and a unit are given, in the robot base frame and m otherwise.
#include "apps/viscera/KinematicsCommand.h"
#include "apps/viscera/CliText.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>

#include "core/Error.h"
#include "core/Units.h"
#include "io/scene/Transform.h"
#include "motion/Trajectory.h"
#include "robot/kinematics/JointTrajectory.h"
#include "robot/kinematics/PsmKinematics.h"

namespace viscera {
namespace {

struct KinematicsOptions {
  std::string joints, poses, out, transform, unit = "m", orientation = "poses", start = "0 0 0.12 0 0 0";
  bool allowLimits = false;
};

// Metres per unit of the poses (any length unit the scenes accept: m, cm, mm, um, ...).
double metresPer(const std::string& unit) {
  try {
    const Unit u = parseUnit(unit);
    if (u.dim == Dimension::length()) return u.si;
  } catch (const std::invalid_argument&) {
    // reported below, as for a unit of another dimension
  }
  throw Error("--unit: " + viscera::quoted(unit) + " is not a length unit (m, cm, mm, ...)");
}

// Robot base (m) -> pose frame (the transform's frame, in `unit`): x = T (x_robot / metresPer).
struct Frames {
  RigidTransform robotToPoses = RigidTransform::Identity();
  double scale = 1;  // pose units per metre
};

Frames frames(const KinematicsOptions& o) {
  Frames f;
  f.scale = 1 / metresPer(o.unit);
  if (!o.transform.empty()) f.robotToPoses = readTransform(o.transform);
  return f;
}

int runFk(const KinematicsOptions& o) {
  const robot::SerialChain psm = robot::psmLargeNeedleDriver();
  const Frames f = frames(o);
  const robot::JointTrajectory joints = robot::readJointCsv(o.joints, psm.dof());
  if (!o.allowLimits)
    for (int i = 0; i < joints.size(); ++i) psm.requireWithinLimits(joints.joints(i), SourceLoc{o.joints, joints.line(i)});
  motion::Trajectory tr;
  for (int i = 0; i < joints.size(); ++i) {
    const Eigen::Isometry3d tip = psm.tipPose(joints.joints(i));
    tr.add(joints.time(i), f.robotToPoses * (tip.translation() * f.scale),
           Eigen::Quaterniond(f.robotToPoses.linear() * tip.linear()));
  }
  motion::writeTrajectoryCsv(o.out, tr);
  std::cerr << "wrote " << tr.size() << " tool-tip poses over " << tr.end() - tr.start() << " s to " << o.out << "\n";
  return kExitOk;
}

int runIk(const KinematicsOptions& o) {
  const robot::SerialChain psm = robot::psmLargeNeedleDriver();
  const Frames f = frames(o);
  const RigidTransform posesToRobot = f.robotToPoses.inverse();
  if (o.orientation != "poses" && o.orientation != "fixed")
    throw Error("--orientation: " + viscera::quoted(o.orientation) + " is neither 'poses' nor 'fixed'");
  const auto s = cli::finiteNumbers(o.start, "--start", psm.dof(), "q1 q2 q3 q4 q5 q6");
  Eigen::VectorXd q = Eigen::Map<const Eigen::VectorXd>(s.data(), psm.dof());
  psm.requireWithinLimits(q, SourceLoc{"--start"});
  const Eigen::Matrix3d fixedR = psm.tipPose(q).linear();
  const motion::Trajectory poses = motion::readTrajectoryCsv(o.poses);

  robot::JointTrajectory joints(psm.dof());
  robot::IkOptions options;
  options.clampToLimits = !o.allowLimits;
  double worstPosition = 0, worstAngle = 0;
  for (int i = 0; i < poses.size(); ++i) {
    Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
    target.translation() = posesToRobot * poses.p[i] / f.scale;
    target.linear() = o.orientation == "fixed" ? fixedR : Eigen::Matrix3d(posesToRobot.linear() * poses.q[i].toRotationMatrix());
    const robot::IkResult r = psm.inverseKinematics(target, q, options);
    if (!r.converged) {
      std::ostringstream m;
      m << "pose " << i + 1 << " (t = " << poses.t[i] << ") is not reached: " << r.positionError * 1e3 << " mm and "
        << r.orientationError * 180 / M_PI << " deg off after " << r.iterations << " iterations"
        << (o.allowLimits ? "" : " within the joint limits") << " (a pose outside the workspace, or a singular one)";
      throw Error(SourceLoc{o.poses}, m.str());
    }
    worstPosition = std::max(worstPosition, r.positionError);
    worstAngle = std::max(worstAngle, r.orientationError);
    q = r.q;
    joints.add(poses.t[i], q);
  }
  robot::writeJointCsv(o.out, joints);
  std::cerr << "wrote " << joints.size() << " joint samples to " << o.out << " (worst residual " << worstPosition * 1e3
            << " mm, " << worstAngle * 180 / M_PI << " deg)\n";
  return kExitOk;
}

void addFrameOptions(CLI::App* cmd, KinematicsOptions& o) {
  cmd->add_option("--transform", o.transform, "rigid transform file robot -> pose frame (4 x 4, translation in --unit)");
  cmd->add_option("--unit", o.unit, "length unit of the poses and the transform (m, cm, mm, ...)")->capture_default_str();
  cmd->add_flag("--allow-limits", o.allowLimits, "accept joint values outside the PSM's limits");
}

}  // namespace

void addKinematicsCommand(CLI::App& app, std::function<int()>& action) {
  auto o = std::make_shared<KinematicsOptions>();
  auto* cmd = app.add_subcommand("kinematics", "convert between PSM joint logs and tool-tip trajectories");
  cmd->require_subcommand(1);
  cmd->footer(
      "Joint logs are CSV rows t,q1,...,q6 (s; rad, and m for the insertion q3). Trajectories are rows\n"
      "t,x,y,z,qx,qy,qz,qw of the tool tip (the PSM with the large needle driver), in the robot base frame and m,\n"
      "or in the frame of --transform (robot -> that frame) and --unit.");
  auto* fk = cmd->add_subcommand("fk", "tool-tip trajectory of a joint log (forward kinematics)");
  fk->add_option("--joints", o->joints, "joint log CSV")->required();
  fk->add_option("--out", o->out, "trajectory CSV to write")->required();
  addFrameOptions(fk, *o);
  fk->callback([o, &action] { action = [o] { return runFk(*o); }; });

  auto* ik = cmd->add_subcommand("ik", "joint log reaching a tool-tip trajectory (damped least-squares inverse kinematics)");
  ik->add_option("--poses", o->poses, "trajectory CSV (t,x,y,z,qx,qy,qz,qw)")->required();
  ik->add_option("--out", o->out, "joint log CSV to write")->required();
  ik->add_option("--orientation", o->orientation,
                 "'poses': reach each pose's orientation; 'fixed': keep the tool orientation of --start and reach the "
                 "positions only")
      ->capture_default_str();
  ik->add_option("--start", o->start, "joint values the first solve starts from (each later one starts from the previous "
                                      "solution)")
      ->capture_default_str();
  addFrameOptions(ik, *o);
  ik->callback([o, &action] { action = [o] { return runIk(*o); }; });
}

}  // namespace viscera
