#include "robot/encoder/Motion.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <stdexcept>

#include "core/Error.h"
#include "io/scene/CsvTable.h"
#include "core/Text.h"

namespace viscera::robot::encoder {
namespace {

// Samples and the Hermite slopes at them.
struct HermiteCurve {
  std::vector<double> t, y, slope;

  // Index of the interval [t[i], t[i+1]] holding `time` (inside the sample range).
  size_t interval(double time) const {
    const auto it = std::upper_bound(t.begin(), t.end(), time);
    return std::min<size_t>(static_cast<size_t>(it - t.begin()), t.size() - 1) - 1;
  }
  double value(double time) const {
    if (time <= t.front()) return y.front();
    if (time >= t.back()) return y.back();
    const size_t i = interval(time);
    const double h = t[i + 1] - t[i], s = (time - t[i]) / h;
    const double s2 = s * s, s3 = s2 * s;
    return (2 * s3 - 3 * s2 + 1) * y[i] + (s3 - 2 * s2 + s) * h * slope[i] + (-2 * s3 + 3 * s2) * y[i + 1] +
           (s3 - s2) * h * slope[i + 1];
  }
  double derivative(double time) const {
    if (time <= t.front() || time >= t.back()) return 0;
    const size_t i = interval(time);
    const double h = t[i + 1] - t[i], s = (time - t[i]) / h;
    const double s2 = s * s;
    return ((6 * s2 - 6 * s) * y[i] + (-6 * s2 + 6 * s) * y[i + 1]) / h + (3 * s2 - 4 * s + 1) * slope[i] +
           (3 * s2 - 2 * s) * slope[i + 1];
  }
};

}  // namespace

JointMotion sinusoidMotion(const std::vector<SinusoidTerm>& terms) {
  JointMotion m;
  m.angle = [terms](double t) {
    double a = 0;
    for (const auto& k : terms) a += k.amplitude * (std::sin(2 * std::numbers::pi * k.frequency * t + k.phase) - std::sin(k.phase));
    return a;
  };
  m.velocity = [terms](double t) {
    double v = 0;
    for (const auto& k : terms) {
      const double w = 2 * std::numbers::pi * k.frequency;
      v += k.amplitude * w * std::cos(w * t + k.phase);
    }
    return v;
  };
  return m;
}

JointMotion sampledMotion(std::vector<double> times, std::vector<double> angles) {
  if (times.size() != angles.size()) throw std::invalid_argument("sampled motion: times and angles differ in number");
  if (times.size() < 2) throw std::invalid_argument("sampled motion: needs at least two samples");
  for (size_t i = 0; i < times.size(); ++i) {
    if (!std::isfinite(times[i]) || !std::isfinite(angles[i]))
      throw std::invalid_argument("sampled motion: sample " + std::to_string(i) + " is not finite");
    if (i > 0 && !(times[i] > times[i - 1]))
      throw std::invalid_argument("sampled motion: time of sample " + std::to_string(i) + " does not increase");
  }
  auto c = std::make_shared<HermiteCurve>();
  c->t = std::move(times);
  c->y = std::move(angles);
  const size_t n = c->t.size();
  c->slope.resize(n);
  // Three-point slopes: each interval's secant weighted by the other interval's length.
  auto secant = [&](size_t i) { return (c->y[i + 1] - c->y[i]) / (c->t[i + 1] - c->t[i]); };
  c->slope[0] = secant(0);
  c->slope[n - 1] = secant(n - 2);
  for (size_t i = 1; i + 1 < n; ++i) {
    const double hl = c->t[i] - c->t[i - 1], hr = c->t[i + 1] - c->t[i];
    c->slope[i] = (hr * secant(i - 1) + hl * secant(i)) / (hl + hr);
  }
  JointMotion m;
  m.angle = [c](double t) { return c->value(t); };
  m.velocity = [c](double t) { return c->derivative(t); };
  return m;
}

MotionFile readMotionCsv(const std::string& path) {
  const io::NumericCsv table = io::readNumericCsv(path, {"t", "theta"});
  if (table.rows() < 2) throw Error(SourceLoc{path}, "a motion needs at least two rows t,theta");
  std::vector<double> t(table.rows()), theta(table.rows());
  for (int r = 0; r < table.rows(); ++r) {
    t[r] = table.at(r, 0);
    theta[r] = table.at(r, 1);
    if (r > 0 && !(t[r] > t[r - 1]))
      throw Error(SourceLoc{path, table.lines[r], 1}, "t must increase (" + formatNumber(t[r]) + " after " +
                                                          formatNumber(t[r - 1]) + ")");
  }
  MotionFile out;
  out.start = t.front();
  out.end = t.back();
  out.motion = sampledMotion(std::move(t), std::move(theta));
  return out;
}

}  // namespace viscera::robot::encoder
