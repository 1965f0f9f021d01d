// Rigid-body trajectories: timed poses (position + orientation) read from and written to CSV,
// sampled with linear interpolation of position and slerp of orientation between samples.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace viscera::motion {

struct Pose {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
};

// Linear and angular velocity (world frame) of a pose.
struct Twist {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
};

class Trajectory {
 public:
  // Samples: strictly increasing times, finite positions, unit quaternions (normalised on input).
  std::vector<double> t;
  std::vector<Eigen::Vector3d> p;
  std::vector<Eigen::Quaterniond> q;

  int size() const { return static_cast<int>(t.size()); }
  bool empty() const { return t.empty(); }
  double start() const { return t.front(); }
  double end() const { return t.back(); }
  void add(double time, const Eigen::Vector3d& pos, const Eigen::Quaterniond& rot = Eigen::Quaterniond::Identity());

  // Pose at `time`: linear interpolation of position and slerp (shortest arc) of orientation in
  // the sample interval holding `time`; held at the first/last pose outside [start, end].
  Pose sample(double time) const;
  // Velocity at `time`, constant on each interval (the derivative of the interpolation); at a
  // sample time the interval that starts there; zero outside [start, end).
  Twist twist(double time) const;
};

// Reads `t,x,y,z,qx,qy,qz,qw` rows (comma separated; an optional header line; blank lines and
// lines starting with '#' skipped). Values are in the scene's units. Throws viscera::Error naming
// `file:line:` for a missing file, a wrong column count, a non-number, NaN/Inf, a zero
// quaternion, or a time that does not increase.
Trajectory readTrajectoryCsv(const std::string& path);
// Same, from text; `name` is used in error messages.
Trajectory parseTrajectoryCsv(const std::string& text, const std::string& name);

// The CSV text (header `t,x,y,z,qx,qy,qz,qw`, full precision).
std::string formatTrajectoryCsv(const Trajectory& tr);
// Written atomically: a reader never sees half a file.
void writeTrajectoryCsv(const std::string& path, const Trajectory& tr);

}  // namespace viscera::motion
