#include "robot/encoder/Quadrature.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>

namespace viscera::robot::encoder {
namespace {

// Edge times are found to this many seconds: well below one tick (20 ns at 49.152 MHz), so that
// the quantisation to ticks is decided by the motion, not by the solver.
constexpr double kTimeTolerance = 1e-12;

void require(bool ok, const char* field, const std::string& what) {
  if (!ok) throw std::invalid_argument(std::string(field) + ": " + what);
}

int sign(double v) { return (v > 0) - (v < 0); }

// A's edges are the mask bits 0x8 (rise) and 0x2 (fall); B's 0x4 and 0x1.
bool isChannelA(Edge e) { return (static_cast<uint8_t>(e) & 0xA) != 0; }

// Root of c(t) = target in [lo, hi], where c moves monotonically from one side of the target to
// the other: Newton steps from a regula falsi start, kept inside the shrinking bracket, with a
// bisection whenever a step would leave it or is not at most half the step before last (the
// safeguard of Numerical Recipes' rtsafe).
double crossingTime(const JointMotion& motion, double cyclesPerRadian, double target, double lo, double hi) {
  auto f = [&](double t) { return motion.angle(t) * cyclesPerRadian - target; };
  const double flo = f(lo);
  if (flo == 0) return lo;
  const double fhi = f(hi);
  if (fhi == 0) return hi;
  const bool loNegative = flo < 0;
  double t = lo - flo * (hi - lo) / (fhi - flo);
  double step = hi - lo, stepBefore = hi - lo;
  for (int iter = 0; iter < 200; ++iter) {
    const double ft = f(t);
    if (ft == 0) return t;
    if ((ft < 0) == loNegative) lo = t;
    else hi = t;
    const double slope = motion.velocity(t) * cyclesPerRadian;
    const double next = slope != 0 ? t - ft / slope : lo - 1;
    stepBefore = step;
    if (!(next > lo && next < hi) || std::abs(next - t) > 0.5 * std::abs(stepBefore)) {
      step = 0.5 * (hi - lo);
      t = lo + step;
    } else {
      step = next - t;
      t = next;
    }
    if (std::abs(step) <= 0.5 * kTimeTolerance || hi - lo <= kTimeTolerance) return t;
  }
  return t;
}

// Time in [lo, hi] where the velocity changes sign (velocity signs at the ends differ), by bisection.
double reversalTime(const JointMotion& motion, double lo, double hi) {
  const int slo = sign(motion.velocity(lo));
  while (hi - lo > kTimeTolerance) {
    const double mid = 0.5 * (lo + hi);
    const int s = sign(motion.velocity(mid));
    if (s == 0) return mid;
    if (s == slo) lo = mid;
    else hi = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

Edge edgeCrossed(int k, bool forward) {
  // Forward: A rise, B rise, A fall, B fall. Backward the same position flips its transition.
  static constexpr Edge kForward[4] = {Edge::ARise, Edge::BRise, Edge::AFall, Edge::BFall};
  static constexpr Edge kBackward[4] = {Edge::AFall, Edge::BFall, Edge::ARise, Edge::BRise};
  return forward ? kForward[k] : kBackward[k];
}

void validate(const EncoderSpec& s) {
  require(std::isfinite(s.lines) && s.lines > 0, "lines", "must be a positive number");
  require(std::isfinite(s.gearRatio) && s.gearRatio > 0, "gearRatio", "must be a positive number");
  require(std::isfinite(s.clockHz) && s.clockHz > 0, "clockHz", "must be a positive number");
  require(std::isfinite(s.dutyA) && s.dutyA > 0 && s.dutyA < 1, "dutyA", "must be in (0, 1)");
  require(std::isfinite(s.dutyB) && s.dutyB > 0 && s.dutyB < 1, "dutyB", "must be in (0, 1)");
  require(std::isfinite(s.phaseB) && s.phaseB > 0 && s.phaseB < 360, "phaseB", "must be in (0, 360) electrical degrees");
  const double p = s.phaseB / 360;
  std::ostringstream phase;
  phase << s.phaseB;
  require(p < s.dutyA, "phaseB", "B must rise while A is high: phase " + phase.str() + " deg is not below 360 x dutyA");
  require(p + s.dutyB > s.dutyA && p + s.dutyB < 1, "dutyB",
          "B must fall while A is low: phase/360 + dutyB must be in (dutyA, 1)");
}

QuadratureEncoder::QuadratureEncoder(const EncoderSpec& spec) : spec_(spec) {
  validate(spec_);
  cyclesPerRadian_ = spec_.lines * spec_.gearRatio / (2 * std::numbers::pi);
  const double p = spec_.phaseB / 360;
  edgeAt_[0] = 0;
  edgeAt_[1] = p;
  edgeAt_[2] = spec_.dutyA;
  edgeAt_[3] = p + spec_.dutyB;
}

int64_t QuadratureEncoder::count(double angle) const {
  const double c = cycles(angle);
  const double whole = std::floor(c);
  const double frac = c - whole;
  int within = 0;
  for (double e : edgeAt_) within += e <= frac;
  // Edge 0 of cycle 0 sits at angle 0 and counts, so the count at angle 0 is 1; shift to make it 0
  // there and keep one count per edge.
  return 4 * static_cast<int64_t>(whole) + within - 1;
}

ChannelLevels QuadratureEncoder::levels(double angle) const {
  const double c = cycles(angle);
  const double frac = c - std::floor(c);
  // A is high on [0, dutyA); B on [p, p + dutyB), which lies inside [0, 1) by validate().
  return {frac < edgeAt_[2], frac >= edgeAt_[1] && frac < edgeAt_[3]};
}

void QuadratureEncoder::monotonePiece(const JointMotion& motion, double ta, double tb, std::vector<EdgeEvent>& out) const {
  const double ca = cycles(motion.angle(ta));
  const double cb = cycles(motion.angle(tb));
  if (ca == cb) return;
  const bool forward = cb > ca;
  // Forward the edges e with ca < e <= cb are crossed, increasing; backward those with
  // cb < e <= ca, decreasing (the count drops when the angle leaves an edge downward).
  const double lo = std::min(ca, cb), hi = std::max(ca, cb);
  if ((hi - lo) * 4 + out.size() > static_cast<double>(kMaxEdges))
    throw std::invalid_argument("edges: the motion crosses more than " + std::to_string(kMaxEdges) + " edges");
  const int64_t nLo = static_cast<int64_t>(std::floor(lo)), nHi = static_cast<int64_t>(std::floor(hi));
  const size_t first = out.size();
  for (int64_t n = nLo; n <= nHi; ++n) {
    for (int k = 0; k < 4; ++k) {
      const double e = static_cast<double>(n) + edgeAt_[k];
      if (!(e > lo && e <= hi)) continue;
      EdgeEvent ev;
      ev.time = crossingTime(motion, cyclesPerRadian_, e, ta, tb);
      ev.tick = static_cast<int64_t>(std::ceil(ev.time * spec_.clockHz));
      ev.type = edgeCrossed(k, forward);
      ev.forward = forward;
      out.push_back(ev);
    }
  }
  if (!forward) std::reverse(out.begin() + static_cast<std::ptrdiff_t>(first), out.end());
}

std::vector<EdgeEvent> QuadratureEncoder::simulate(const JointMotion& motion, double t0, double t1, double maxStep) const {
  if (!(t1 >= t0)) throw std::invalid_argument("simulate: the end time is before the start time");
  if (!(maxStep > 0)) throw std::invalid_argument("simulate: the step must be positive");
  std::vector<EdgeEvent> raw;
  const int64_t steps = std::max<int64_t>(1, static_cast<int64_t>(std::ceil((t1 - t0) / maxStep)));
  double ta = t0;
  int sa = sign(motion.velocity(ta));
  for (int64_t i = 1; i <= steps; ++i) {
    const double tb = i == steps ? t1 : t0 + (t1 - t0) * static_cast<double>(i) / static_cast<double>(steps);
    const int sb = sign(motion.velocity(tb));
    if (sa * sb < 0) {
      const double tm = reversalTime(motion, ta, tb);
      monotonePiece(motion, ta, tm, raw);
      monotonePiece(motion, tm, tb, raw);
    } else {
      monotonePiece(motion, ta, tb, raw);
    }
    ta = tb;
    sa = sb;
  }

  // What the FPGA samples: within one tick only the net change of each channel is seen, so an
  // even number of crossings of one channel in a tick vanishes and an odd number leaves its last.
  std::vector<EdgeEvent> seen;
  seen.reserve(raw.size());
  for (size_t i = 0; i < raw.size();) {
    size_t j = i;
    int nA = 0, nB = 0;
    for (; j < raw.size() && raw[j].tick == raw[i].tick; ++j) (isChannelA(raw[j].type) ? nA : nB)++;
    if (nA + nB == 1) {
      seen.push_back(raw[i]);
    } else {
      // Keep the last crossing of each channel with an odd count, in time order.
      size_t lastA = j, lastB = j;
      for (size_t k = i; k < j; ++k) (isChannelA(raw[k].type) ? lastA : lastB) = k;
      std::vector<size_t> keep;
      if (nA % 2 == 1) keep.push_back(lastA);
      if (nB % 2 == 1) keep.push_back(lastB);
      std::sort(keep.begin(), keep.end());
      for (size_t k : keep) seen.push_back(raw[k]);
    }
    i = j;
  }
  return seen;
}

}  // namespace viscera::robot::encoder
