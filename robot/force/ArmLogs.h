// The logs of force estimation: a robot's joint states, force-sensor wrenches and Jacobians, as
// timed tables; their alignment by linear interpolation and resampling (1 kHz logs to 200 Hz).
//
// Formats (comma separated; an optional header line; blank lines and '#' lines skipped; time in s):
//  - joint state: `t,q1..qn,qd1..qn,tau1..taun`, the dVRK's order, in rad / m, rad/s / m/s and
//    N m / N. Without a header a log of 1 + 3n columns has n joints; a 22-column log is taken as
//    six joints plus the jaw (a seventh joint, dropped). Other orders: a column map (below) or a
//    header naming the columns the same way.
//  - wrench: `t,Fx,Fy,Fz,Tx,Ty,Tz` in N and N m (`t,Fx,Fy,Fz`: torques zero).
//  - Jacobian: `t,J1_1,J1_2,..,J6_n` (row-major: row 1's n entries first).
// A column map lists the file's columns in order: `t`, `qK`, `qdK`, `tauK` (K = 1-based joint) or
// `-` for a column to skip; e.g. "t,q1,q2,q3,q4,q5,q6,q7,qd1,...". Aliases accepted in headers:
// time, pos/position K, vel/velocity K, effort/torque K.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace viscera::robot {

// A timed table: strictly increasing times, one row of values per time.
struct Series {
  std::string source;              // file name in messages
  std::vector<std::string> names;  // one per column of `values`
  std::vector<double> t;
  Eigen::MatrixXd values;          // samples x columns
  std::vector<int> lines;          // 1-based source line of each sample (empty when made in memory)

  int samples() const { return static_cast<int>(t.size()); }
  double duration() const { return t.empty() ? 0 : t.back() - t.front(); }
  // "file:line" of sample i (or the file alone).
  std::string where(int i) const;
};

// Joint states of an n-joint arm: values = [q | qd | effort].
struct JointStateLog {
  int dof = 0;
  Series series;
  int samples() const { return series.samples(); }
  auto q() const { return series.values.leftCols(dof); }
  auto qd() const { return series.values.middleCols(dof, dof); }
  auto effort() const { return series.values.rightCols(dof); }
};

// Samples [begin, end) of a log.
JointStateLog sliceLog(const JointStateLog& log, int begin, int end);

JointStateLog makeJointStateLog(std::vector<double> t, const Eigen::MatrixXd& q, const Eigen::MatrixXd& qd,
                                const Eigen::MatrixXd& effort, const std::string& source = "");

// Reads a joint-state log of `dof` joints (see the top of this file). `columns`, when not empty, is
// a column map. Throws viscera::Error naming file:line(:col) for a missing file, a wrong column
// count, a non-number, NaN/Inf, a time that does not increase, or a map without every joint.
JointStateLog readJointStateLog(const std::string& path, int dof = 6, const std::string& columns = "");
JointStateLog parseJointStateLog(const std::string& text, const std::string& source, int dof = 6,
                                 const std::string& columns = "");
Series readWrenchCsv(const std::string& path);
Series readJacobianCsv(const std::string& path, int dof = 6);

// CSV text of a series with its names as the header (time column `t`); values with `digits`
// (1 to 17, an Error otherwise) significant digits (17: read back exactly), times always exactly.
std::string formatSeries(const Series& s, int digits = 17);
// Written atomically.
void writeSeries(const std::string& path, const Series& s, int digits = 17);
Series wrenchSeries(std::vector<double> t, const Eigen::MatrixXd& wrench);
Series jacobianSeries(std::vector<double> t, const Eigen::MatrixXd& jacobian, int dof);

// Values of `s` at `times` by linear interpolation. Times outside [first, last] of `s` are an
// Error naming the source (a log must cover the span it is aligned to).
Series interpolate(const Series& s, const std::vector<double>& times);
// Times from `start` to `end` (inclusive within rounding) at `rate` per second.
std::vector<double> uniformTimes(double start, double end, double rate);
// Values of `s` at `times`, each the mean of the samples within half a period of it (a box filter
// against aliasing); interpolated where no sample falls in.
Series averageAt(const Series& s, const std::vector<double>& times, double period);
// `s` resampled at `rate` over its own span; with `average` each new sample is the mean of the
// original samples within half a period of it (a box filter against aliasing) rather than the
// interpolated value.
Series resample(const Series& s, double rate, bool average = true);
JointStateLog resample(const JointStateLog& log, double rate, bool average = true);
// The span [max first, min last] two series share; an Error when they do not overlap.
std::pair<double, double> overlap(const Series& a, const Series& b);

}  // namespace viscera::robot
