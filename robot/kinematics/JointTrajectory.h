// Joint-space trajectories: timed joint vectors (a robot's joint log), read from and written to
// CSV, sampled by linear interpolation between samples.
//
// CSV format: `t,q1,...,qn` rows (comma separated; an optional header line; blank lines and lines
// starting with '#' skipped). Time in s; joint values in the robot's units, rad for revolute and m
// for prismatic joints (the dVRK's own logs use these units).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace viscera::robot {

class JointTrajectory {
 public:
  explicit JointTrajectory(int dof = 0) : dof_(dof) {}

  int dof() const { return dof_; }
  int size() const { return static_cast<int>(t_.size()); }
  bool empty() const { return t_.empty(); }
  double start() const { return t_.front(); }
  double end() const { return t_.back(); }
  double time(int i) const { return t_[i]; }
  // Joint vector of sample i (dof values).
  Eigen::Map<const Eigen::VectorXd> joints(int i) const { return {q_.data() + static_cast<size_t>(i) * dof_, dof_}; }
  // Source line of sample i when it was read from a file (0 otherwise), for limit messages.
  int line(int i) const { return lines_.empty() ? 0 : lines_[i]; }

  // Appends a sample; throws std::invalid_argument for a wrong size, non-finite values or a time
  // that does not increase.
  void add(double time, const Eigen::Ref<const Eigen::VectorXd>& q, int sourceLine = 0);

  // Joint vector at `time` by linear interpolation in the sample interval holding it; held at the
  // first / last sample outside [start, end]. `out` must have dof() entries. No allocation.
  void sample(double time, Eigen::Ref<Eigen::VectorXd> out) const;
  Eigen::VectorXd sample(double time) const;

 private:
  int dof_ = 0;
  std::vector<double> t_;
  std::vector<double> q_;  // size() x dof, row-major
  std::vector<int> lines_;
};

// Reads `t,q1..qn` rows with n = dof. Throws viscera::Error naming `file:line:col` for a missing
// file, a wrong column count, a non-number, NaN/Inf, or a time that does not increase.
JointTrajectory readJointCsv(const std::string& path, int dof);
JointTrajectory parseJointCsv(const std::string& text, const std::string& name, int dof);

// CSV text with the header `t,q1,...,qn`, full precision (values read back exactly).
std::string formatJointCsv(const JointTrajectory& trajectory);
// Written atomically.
void writeJointCsv(const std::string& path, const JointTrajectory& trajectory);

}  // namespace viscera::robot
