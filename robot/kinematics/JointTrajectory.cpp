#include "robot/kinematics/JointTrajectory.h"
#include "core/Files.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/scene/CsvTable.h"
#include "core/Text.h"

namespace viscera::robot {

void JointTrajectory::add(double time, const Eigen::Ref<const Eigen::VectorXd>& q, int sourceLine) {
  if (q.size() != dof_)
    throw std::invalid_argument("JointTrajectory::add: " + std::to_string(q.size()) + " joint values for a " +
                                std::to_string(dof_) + "-joint trajectory");
  if (!std::isfinite(time) || !q.allFinite()) throw std::invalid_argument("JointTrajectory::add: non-finite time or joint value");
  if (!t_.empty() && !(time > t_.back()))
    throw std::invalid_argument("JointTrajectory::add: time " + formatNumber(time) + " does not increase (previous " +
                                formatNumber(t_.back()) + ")");
  t_.push_back(time);
  q_.insert(q_.end(), q.data(), q.data() + dof_);
  if (sourceLine > 0 || !lines_.empty()) {
    lines_.resize(t_.size() - 1, 0);
    lines_.push_back(sourceLine);
  }
}

void JointTrajectory::sample(double time, Eigen::Ref<Eigen::VectorXd> out) const {
  if (out.size() != dof_) throw std::invalid_argument("JointTrajectory::sample: output has the wrong size");
  if (t_.empty()) {
    out.setZero();
    return;
  }
  if (!(time > t_.front())) {  // also NaN: the first sample
    out = joints(0);
    return;
  }
  if (time >= t_.back()) {
    out = joints(size() - 1);
    return;
  }
  const int i = static_cast<int>(std::upper_bound(t_.begin(), t_.end(), time) - t_.begin()) - 1;
  const double s = (time - t_[i]) / (t_[i + 1] - t_[i]);
  out = joints(i) + s * (joints(i + 1) - joints(i));
}

Eigen::VectorXd JointTrajectory::sample(double time) const {
  Eigen::VectorXd q(dof_);
  sample(time, q);
  return q;
}

namespace {
std::vector<std::string> columnNames(int dof) {
  std::vector<std::string> names{"t"};
  for (int j = 1; j <= dof; ++j) names.push_back(std::string("q").append(std::to_string(j)));
  return names;
}

JointTrajectory fromTable(const io::NumericCsv& table, int dof) {
  JointTrajectory tr(dof);
  for (int r = 0; r < table.rows(); ++r) {
    const double* row = table.row(r);
    if (r > 0 && !(row[0] > tr.end()))
      throw Error(SourceLoc{table.source, table.lines[r]},
                  "time " + formatNumber(row[0]) + " does not increase (previous " + formatNumber(tr.end()) +
                      " at line " + std::to_string(table.lines[r - 1]) + ")");
    tr.add(row[0], Eigen::Map<const Eigen::VectorXd>(row + 1, dof), table.lines[r]);
  }
  return tr;
}
}  // namespace

JointTrajectory parseJointCsv(const std::string& text, const std::string& name, int dof) {
  return fromTable(io::parseNumericCsv(text, name, columnNames(dof)), dof);
}

JointTrajectory readJointCsv(const std::string& path, int dof) {
  return fromTable(io::readNumericCsv(path, columnNames(dof)), dof);
}

std::string formatJointCsv(const JointTrajectory& trajectory) {
  std::string out;
  for (const std::string& n : columnNames(trajectory.dof())) {
    if (!out.empty()) out += ',';
    out += n;
  }
  out += '\n';
  for (int i = 0; i < trajectory.size(); ++i) {
    out += formatNumber(trajectory.time(i));
    for (int j = 0; j < trajectory.dof(); ++j) {
      out += ',';
      out += formatNumber(trajectory.joints(i)[j]);
    }
    out += '\n';
  }
  return out;
}

void writeJointCsv(const std::string& path, const JointTrajectory& trajectory) {
  writeFileAtomic(path, formatJointCsv(trajectory));
}

}  // namespace viscera::robot
