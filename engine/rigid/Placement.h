// Where a recorded motion sits in the scene: a rigid transform file (robot -> scene, e.g. from
// `viscera register points`), then a rotation, then a translation. Shared by every driver that
// replays a log recorded in another frame (Cartesian trajectories, joint logs, ESPM captures).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>

#include "core/Error.h"

namespace viscera {

class Component;
struct ComponentSpec;

struct Placement {
  Eigen::Quaterniond R = Eigen::Quaterniond::Identity();
  Eigen::Vector3d T = Eigen::Vector3d::Zero();

  Eigen::Vector3d point(const Eigen::Vector3d& p) const { return R * p + T; }
  Eigen::Vector3d vector(const Eigen::Vector3d& v) const { return R * v; }
  Eigen::Quaterniond rotation(const Eigen::Quaterniond& q) const { return R * q; }
};

// Declares `transform` (file), `rotation` (3 angles, degrees) and `translation` (3 lengths) on `s`.
// `what` names the motion in the help texts ("the trajectory").
void addPlacementAttributes(ComponentSpec& s, const std::string& what);

// The placement of component `c` from those attributes: x_scene = R_rot (R_file x + t_file) + t.
// A bad transform file is reported with the file's own location first, then the component's
// `transform` attribute.
Placement readPlacement(const Component& c);

// An error from reading the file named by attribute `attr` of `c`: the file's own location first
// (file:line), then "(read for <scene:line>: Component.attr)".
Error fileErrorFor(const Error& e, const Component& c, const std::string& attr);

// Rotation vector (world frame, axis x angle, shortest arc) of the rotation taking `from` to
// `to`: to = exp(v) from. Drivers divide it by the step to get the angular velocity.
Eigen::Vector3d rotationVector(const Eigen::Quaterniond& from, const Eigen::Quaterniond& to);

}  // namespace viscera
