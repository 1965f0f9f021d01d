#include "robot/encoder/VelocityEstimators.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace viscera::robot::encoder {
namespace {

double signedBy(bool forward, double magnitude) { return forward ? magnitude : -magnitude; }

// The running counter's bound on a full-cycle estimate (counts/s): the cycle in progress holds
// the quarter in progress (at least T_r) and T_i.
double limitByRunning(const Measurement& m, double v) {
  if (!m.hasRunning) return v;
  const double limit = 4 / ((static_cast<double>(m.running) + m.quarter) * m.clockPeriod);
  return std::clamp(v, -limit, limit);
}

// 4 / (S T) with its sign, or 0 when the cycle is unusable.
double unboundedFullCycle(const Measurement& m) {
  if (m.overflow || (m.hasRunning && m.runningOverflow)) return 0;
  return signedBy(m.forward, 4 / (std::max<uint32_t>(m.period, 1) * m.clockPeriod));
}

// Full-cycle velocity plus acceleration over `leadTicks` clock counts, not past zero, bounded as
// above.
double predicted(const Measurement& m, const EstimatorOptions& options, double leadTicks) {
  const double v = unboundedFullCycle(m);
  if (v == 0) return 0;
  const double p = v + cycleAcceleration(m, options) * leadTicks * m.clockPeriod;
  if ((p > 0) != (v > 0)) return 0;
  return limitByRunning(m, p);
}

}  // namespace

double quarterCycleVelocity(const Measurement& m) {
  // Without a running counter (Rev 6) the period's overflow bit is what says the encoder stopped.
  if (m.quarterOverflow || (m.hasRunning ? m.runningOverflow : m.overflow)) return 0;
  uint32_t ticks = std::max<uint32_t>(m.quarter, 1);
  if (m.hasRunning) ticks = std::max(ticks, m.running);
  return signedBy(m.quarterForward, 1 / (ticks * m.clockPeriod));
}

double fullCycleVelocity(const Measurement& m) { return limitByRunning(m, unboundedFullCycle(m)); }

double cycleAcceleration(const Measurement& m, const EstimatorOptions& options) {
  if (m.overflow || m.quarterOverflow || m.quarterPrevOverflow || m.directionChanged || m.encoderError) return 0;
  if (m.quarterForward != m.forward || m.quarterPrevForward != m.forward) return 0;
  if (m.hasEdgeMasks && m.quarterEdges != m.quarterPrevEdges) return 0;
  if (m.quarter * m.clockPeriod < options.accelerationMinQuarter) return 0;
  const double s = m.period, t1 = m.quarter, t5 = m.quarterPrev;
  const double sPrev = s - t1 + t5;  // S_{i-1}
  if (s <= 0 || sPrev <= 0 || t1 + t5 <= 0) return 0;
  const double T = m.clockPeriod;
  return signedBy(m.forward, 8 * (t5 - t1) / (s * sPrev * T * T * (t5 + t1)));
}

double fullCycleAccelerationVelocity(const Measurement& m, const EstimatorOptions& options) {
  return predicted(m, options, 0.5 * m.period);
}

double runningCounterVelocity(const Measurement& m, const EstimatorOptions& options) {
  return predicted(m, options, 0.5 * m.period + (m.hasRunning ? static_cast<double>(m.running) : 0.0));
}

double countsToRadPerSecond(double countsPerSecond, const EncoderSpec& spec) {
  return countsPerSecond * 2 * std::numbers::pi / spec.countsPerRevolution();
}

double countsToDegPerSecond(double countsPerSecond, const EncoderSpec& spec) {
  return countsPerSecond * 360 / spec.countsPerRevolution();
}

}  // namespace viscera::robot::encoder
