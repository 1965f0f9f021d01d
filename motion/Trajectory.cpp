// Trajectory sampling (lerp + shortest-arc slerp), its piecewise-constant velocity, and the
// `t,x,y,z,qx,qy,qz,qw` CSV format with strict, line-numbered error messages.
#include "motion/Trajectory.h"
#include "core/Files.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string_view>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "core/Text.h"

namespace viscera::motion {
namespace {

constexpr const char* kHeader = "t,x,y,z,qx,qy,qz,qw";
constexpr const char* kColumns[8] = {"t", "x", "y", "z", "qx", "qy", "qz", "qw"};

// Unit quaternion. Quaternions that are already unit to within rounding are left bit for bit
// as they are, so that writing and reading a trajectory gives back exactly the same numbers.
Eigen::Quaterniond normalised(const Eigen::Quaterniond& q) {
  const double n2 = q.squaredNorm();
  if (std::abs(n2 - 1.0) <= 8 * std::numeric_limits<double>::epsilon()) return q;
  return Eigen::Quaterniond(q.coeffs().stableNormalized());  // no overflow for huge components
}

// `b` on the same half of the quaternion sphere as `a`, so that a and b are joined by the
// shortest arc (q and -q are the same rotation).
Eigen::Quaterniond sameHemisphere(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.dot(b) < 0 ? Eigen::Quaterniond(-b.coeffs()) : b;
}

// Index i of the interval [t_i, t_{i+1}) holding `time`; the caller ensures t_0 <= time < t_last.
size_t intervalOf(const std::vector<double>& t, double time) {
  return static_cast<size_t>(std::upper_bound(t.begin(), t.end(), time) - t.begin()) - 1;
}

bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && isBlank(s.front())) s.remove_prefix(1);
  while (!s.empty() && isBlank(s.back())) s.remove_suffix(1);
  return s;
}

// Whole-field parse. NaN, Inf and out-of-range values are numbers here (Number with a
// non-finite value) so that they get their own message.
enum class Parsed { Number, NotANumber };

Parsed parseField(std::string_view s, double& out) { return parseNumber(s, out) ? Parsed::Number : Parsed::NotANumber; }

// The first content line is a header when its first field is not a number and does not even
// start like one ("t", "time"); "0 0 0 ..." (wrong separator) is a row with a bad column count.
bool isHeader(std::string_view first) {
  double ignored;
  if (parseField(first, ignored) == Parsed::Number) return false;
  const char c = first.empty() ? '\0' : first.front();
  return !(std::isdigit(static_cast<unsigned char>(c)) || c == '+' || c == '-' || c == '.');
}

// Splits a line at commas; each field trimmed, with its 1-based column in the line.
struct Field {
  std::string_view text;
  int col;
};

std::vector<Field> splitFields(std::string_view line) {
  std::vector<Field> fields;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    const size_t stop = comma == std::string_view::npos ? line.size() : comma;
    std::string_view raw = line.substr(start, stop - start);
    size_t lead = 0;
    while (lead < raw.size() && isBlank(raw[lead])) ++lead;
    fields.push_back({trim(raw), static_cast<int>(start + lead) + 1});
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return fields;
}

[[noreturn]] void fail(const std::string& name, int line, int col, const std::string& what) {
  throw Error(SourceLoc{name, line, col}, what);
}

}  // namespace

void Trajectory::add(double time, const Eigen::Vector3d& pos, const Eigen::Quaterniond& rot) {
  if (!std::isfinite(time) || !pos.allFinite() || !rot.coeffs().allFinite())
    throw std::invalid_argument("Trajectory::add: non-finite time, position or orientation");
  if (!t.empty() && !(time > t.back()))
    throw std::invalid_argument("Trajectory::add: time " + formatNumber(time) + " does not increase (previous " +
                                formatNumber(t.back()) + ")");
  if (rot.coeffs().stableNorm() == 0.0) throw std::invalid_argument("Trajectory::add: zero quaternion");
  t.push_back(time);
  p.push_back(pos);
  q.push_back(normalised(rot));
}

Pose Trajectory::sample(double time) const {
  if (t.empty()) return {};
  if (!(time > t.front())) return {p.front(), q.front()};  // also for NaN: the first pose
  if (time >= t.back()) return {p.back(), q.back()};
  const size_t i = intervalOf(t, time);
  const double s = (time - t[i]) / (t[i + 1] - t[i]);

  Pose pose;
  pose.p = p[i] + s * (p[i + 1] - p[i]);  // exactly p[i] while the pose holds still

  const Eigen::Quaterniond& a = q[i];
  const Eigen::Quaterniond b = sameHemisphere(a, q[i + 1]);
  const double d = std::min(1.0, a.dot(b));
  if (d > 1 - 1e-12) {  // (nearly) the same rotation: lerp and normalise (exactly a for a == b)
    pose.q = normalised(Eigen::Quaterniond(a.coeffs() + s * (b.coeffs() - a.coeffs())));
  } else {
    const double theta = std::acos(d);
    const double sinTheta = std::sin(theta);
    const double wa = std::sin((1 - s) * theta) / sinTheta;
    const double wb = std::sin(s * theta) / sinTheta;
    pose.q = Eigen::Quaterniond((wa * a.coeffs() + wb * b.coeffs()).normalized());
  }
  return pose;
}

Twist Trajectory::twist(double time) const {
  if (t.size() < 2 || !(time >= t.front()) || time >= t.back()) return {};
  const size_t i = intervalOf(t, time);
  const double dt = t[i + 1] - t[i];

  Twist tw;
  tw.v = (p[i + 1] - p[i]) / dt;
  // World-frame rotation taking q_i to q_{i+1}: q_{i+1} = dq * q_i. With both on one hemisphere
  // dq.w >= 0, so its angle is in [0, pi] (the shortest arc).
  const Eigen::Quaterniond dq = sameHemisphere(q[i], q[i + 1]) * q[i].conjugate();
  const double s = dq.vec().norm();
  const double angle = 2 * std::atan2(s, dq.w());
  // angle * axis; for tiny angles vec/s is ill-conditioned, and angle/s -> 2/w.
  const Eigen::Vector3d rotation = s > 1e-12 ? Eigen::Vector3d(dq.vec() * (angle / s)) : Eigen::Vector3d(dq.vec() * (2 / dq.w()));
  tw.w = rotation / dt;
  return tw;
}

Trajectory parseTrajectoryCsv(const std::string& raw, const std::string& name) {
  const std::string text = plainText(raw);
  Trajectory tr;
  std::string previousTime;  // as written, for messages
  int previousLine = 0;
  bool firstContent = true;
  size_t pos = 0;
  for (int lineNo = 1; pos < text.size(); ++lineNo) {
    size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    const std::string_view line = trim(std::string_view(text).substr(pos, eol - pos));  // also drops a CR
    pos = eol + 1;
    if (line.empty() || line.front() == '#') continue;

    const std::vector<Field> fields = splitFields(line);
    double values[8];
    if (firstContent) {
      firstContent = false;
      if (isHeader(fields[0].text)) continue;
    }
    if (fields.size() != 8)
      fail(name, lineNo, 0, "expected 8 columns (t,x,y,z,qx,qy,qz,qw), got " + std::to_string(fields.size()));
    for (int c = 0; c < 8; ++c) {
      const std::string column = std::string("column '") + kColumns[c] + "'";
      if (parseField(fields[c].text, values[c]) == Parsed::NotANumber)
        fail(name, lineNo, fields[c].col, column + ": " + quoted(fields[c].text) + " is not a number");
      if (!std::isfinite(values[c]))
        fail(name, lineNo, fields[c].col, column + " is not finite (" + quoted(fields[c].text) + ")");
    }

    const Eigen::Quaterniond q(values[7], values[4], values[5], values[6]);  // Eigen's order is w, x, y, z
    if (!(q.coeffs().stableNorm() > 1e-12)) fail(name, lineNo, fields[4].col, "the quaternion (qx,qy,qz,qw) has zero length");
    if (!tr.empty() && !(values[0] > tr.end()))
      fail(name, lineNo, fields[0].col, "time " + std::string(fields[0].text) + " does not increase (previous " + previousTime +
                                      " at line " + std::to_string(previousLine) + ")");
    tr.add(values[0], Eigen::Vector3d(values[1], values[2], values[3]), q);
    previousTime = std::string(fields[0].text);
    previousLine = lineNo;
  }
  if (tr.empty()) throw Error(SourceLoc{name}, "no samples (expected rows t,x,y,z,qx,qy,qz,qw)");
  return tr;
}

Trajectory readTrajectoryCsv(const std::string& path) {
  return parseTrajectoryCsv(readInputFile(path, "trajectory"), path);
}

std::string formatTrajectoryCsv(const Trajectory& tr) {
  std::string out = std::string(kHeader) + "\n";
  for (int i = 0; i < tr.size(); ++i) {
    const double row[8] = {tr.t[i], tr.p[i].x(), tr.p[i].y(), tr.p[i].z(), tr.q[i].x(), tr.q[i].y(), tr.q[i].z(), tr.q[i].w()};
    for (int c = 0; c < 8; ++c) {
      if (c) out += ',';
      out += formatNumber(row[c]);
    }
    out += '\n';
  }
  return out;
}

void writeTrajectoryCsv(const std::string& path, const Trajectory& tr) { writeFileAtomic(path, formatTrajectoryCsv(tr)); }

}  // namespace viscera::motion
