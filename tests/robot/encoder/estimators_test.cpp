// Velocity estimators (robot/encoder/VelocityEstimators) on simulated encoders, against motions
// with closed-form velocities: constant speed (full cycle exact, whatever the imperfections;
// quarter cycle not), constant acceleration (II.7 and II.8 remove the half-cycle delay), a stop.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "robot/encoder/EncoderFpga.h"
#include "robot/encoder/Quadrature.h"
#include "robot/encoder/Registers.h"
#include "robot/encoder/VelocityEstimators.h"

using namespace viscera::robot::encoder;

namespace {

constexpr double kPi = std::numbers::pi;

EncoderSpec encoder(double dutyA, double dutyB, double phase) {
  EncoderSpec s;
  s.lines = 16;
  s.dutyA = dutyA;
  s.dutyB = dutyB;
  s.phaseB = phase;
  return s;
}

struct Reads {
  std::vector<double> times;
  std::vector<FpgaReadout> readouts;
  std::vector<EdgeEvent> events;
};

// Reads an encoder under `motion` every `interval` seconds from `first` to `last`.
Reads readEncoder(const EncoderSpec& spec, const JointMotion& motion, double end, double first, double interval, double last) {
  const QuadratureEncoder enc(spec);
  Reads r;
  r.events = enc.simulate(motion, 0, end, 1e-3);
  std::vector<int64_t> ticks;
  for (double t = first; t <= last; t += interval) ticks.push_back(std::llround(t * spec.clockHz));
  r.readouts = readAt(r.events, enc.levels(motion.angle(0)), enc.count(motion.angle(0)), ticks);
  for (int64_t k : ticks) r.times.push_back(static_cast<double>(k) / spec.clockHz);
  return r;
}

}  // namespace

TEST(VelocityEstimators, FullCycleIsExactAtConstantSpeedWhateverTheImperfections) {
  // 131 counts/s on 16 lines: a cycle of 4 / 131 s = 1 500 824.4 ticks (not a whole number, so
  // the edges' tick rounding differs from cycle to cycle). The cycle sum spans four edges whose
  // ticks are each rounded up by less than one tick, so |S - S_exact| < 1 tick and the full-cycle
  // estimate is within v / (S_exact - 1) of v: 8.7e-5 counts/s.
  const double countsPerSecond = 131;
  const double w = countsPerSecond * 2 * kPi / 64;
  const JointMotion motion{[=](double t) { return 0.01 + w * t; }, [=](double) { return w; }};
  const double cycleTicks = 4 / countsPerSecond * kFpgaClockHz;
  const double bound = countsPerSecond / (cycleTicks - 1);
  const double T = 1 / kFpgaClockHz;

  struct Case {
    const char* name;
    EncoderSpec spec;
    double minQuarterError;  // the quarter-cycle estimate's largest error, at least (counts/s)
  };
  // Quarter cycles as fractions of a cycle: ideal 0.25 each; 40 % duty on both channels gives
  // 0.25, 0.15, 0.25, 0.35; a 70 degree phase gives 0.19, 0.31, 0.19, 0.31. The quarter-cycle
  // estimate 1 / T_i is then off by up to 0.25 / 0.15 - 1 = 67 % and 0.25 / 0.194 - 1 = 29 %
  // (measured: 87.3 and 37.4 counts/s).
  const Case cases[] = {{"ideal", encoder(0.5, 0.5, 90), 0},
                        {"40 % duty", encoder(0.4, 0.4, 90), 0.6 * countsPerSecond},
                        {"70 deg phase", encoder(0.5, 0.5, 70), 0.25 * countsPerSecond}};
  for (const Case& c : cases) {
    // Reads from 0.1 s on (after more than five edges), 97 of them, not in step with the edges.
    const Reads r = readEncoder(c.spec, motion, 1, 0.1, 0.0093, 1);
    double worstFull = 0, worstFullRev6 = 0, worstQuarter = 0;
    for (const FpgaReadout& readout : r.readouts) {
      const Measurement m = measure(readout, RegisterFormat::Rev7);
      const double full = fullCycleVelocity(m);
      worstFull = std::max(worstFull, std::abs(full - countsPerSecond));
      worstQuarter = std::max(worstQuarter, std::abs(quarterCycleVelocity(m) - countsPerSecond));
      worstFullRev6 = std::max(worstFullRev6, std::abs(fullCycleVelocity(measure(readout, RegisterFormat::Rev6)) - countsPerSecond));
      // T_i and T_{i-4} are quarters of one type, so |T5 - T1| <= 1 tick and the acceleration is at
      // most 8 / (S S' T^2 (T5 + T1)); II.7 and II.8 add it over S / 2 and S / 2 + T_r.
      const double S = m.period, S1 = S - m.quarter + m.quarterPrev, Q = m.quarter + m.quarterPrev;
      const double maxAcceleration = 8 / (S * S1 * T * T * Q);
      EXPECT_NEAR(fullCycleAccelerationVelocity(m), countsPerSecond, bound + maxAcceleration * 0.5 * S * T) << c.name;
      EXPECT_NEAR(runningCounterVelocity(m), countsPerSecond, bound + maxAcceleration * (0.5 * S + m.running) * T) << c.name;
    }
    EXPECT_LE(worstFull, bound) << c.name;  // measured 5e-5 counts/s in each case
    // Rev 6 truncates S to 16 ticks: |S - 16 S6| < 16 + 1 ticks (measured 7.4e-4 counts/s).
    EXPECT_LE(worstFullRev6, countsPerSecond * 17 / (cycleTicks - 17)) << c.name;
    if (c.minQuarterError == 0) {
      // Ideal channels: T_i (and the running counter) is S / 4 to a tick.
      EXPECT_LE(worstQuarter, countsPerSecond / (cycleTicks / 4 - 1)) << c.name;
    } else {
      EXPECT_GE(worstQuarter, c.minQuarterError) << c.name;
    }
  }
}

TEST(VelocityEstimators, AccelerationRemovesTheHalfCycleDelay) {
  // theta = 4 t + 15 t^2 (rad): the velocity 4 + 30 t rad/s grows linearly. Over a cycle the mean
  // velocity is the velocity at the cycle's midpoint, so 4 / S is half a cycle late, II.7 gives the
  // velocity at the last edge and II.8 at the read, exactly but for the quantisation of edge times
  // to ticks, which the bound below propagates. An imperfect encoder makes no difference: T_i and
  // T_{i-4} are quarters of one type.
  const double v0 = 4, acc = 30;
  const JointMotion motion{[=](double t) { return v0 * t + 0.5 * acc * t * t; }, [=](double t) { return v0 + acc * t; }};
  const EncoderSpec spec = encoder(0.45, 0.55, 80);
  const double countsPerRad = spec.countsPerRevolution() / (2 * kPi);
  const Reads r = readEncoder(spec, motion, 0.6, 0.25, 0.0071, 0.6);
  ASSERT_GT(r.readouts.size(), 40u);
  const double T = 1 / kFpgaClockHz;
  size_t edge = 0;
  for (size_t k = 0; k < r.readouts.size(); ++k) {
    const Measurement m = measure(r.readouts[k], RegisterFormat::Rev7);
    ASSERT_FALSE(m.overflow);
    while (edge + 1 < r.events.size() && r.events[edge + 1].tick <= r.readouts[k].tick) ++edge;
    const double atRead = (v0 + acc * r.times[k]) * countsPerRad;
    const double atEdge = (v0 + acc * r.events[edge].time) * countsPerRad;

    // Quantisation: S, S' and the quarters are differences of tick-rounded edge times (each off by
    // less than a tick), T_r by less than a tick; first-order propagation through II.2 and II.6.
    const double S = m.period, S1 = S - m.quarter + m.quarterPrev, Q = m.quarter + m.quarterPrev;
    const double a = cycleAcceleration(m);
    ASSERT_GT(a, 0);
    const double dv = 4 / (S * S * T);
    const double da = std::abs(a) * (1 / S + 1 / S1 + 2 / Q) + 16 / (S * S1 * T * T * Q);
    const double bound7 = dv + da * 0.5 * S * T + std::abs(a) * 0.5 * T;
    const double bound8 = dv + da * (0.5 * S + m.running) * T + std::abs(a) * 1.5 * T;

    EXPECT_NEAR(fullCycleAccelerationVelocity(m), atEdge, bound7) << "read " << k;
    EXPECT_NEAR(runningCounterVelocity(m), atRead, bound8) << "read " << k;
    // The full cycle alone lags by the acceleration over half a cycle (and the time since the edge).
    EXPECT_NEAR(fullCycleVelocity(m), atEdge - a * 0.5 * S * T, bound7) << "read " << k;
    EXPECT_GT(atRead - fullCycleVelocity(m), 20 * bound8) << "read " << k;
  }
}

TEST(VelocityEstimators, StoppingEncoderDecaysToZero) {
  // Decelerates from 10 rad/s to rest at t = 0.5 s, then stays: theta = 10 t - 10 t^2 up to 0.5 s.
  const JointMotion motion{[](double t) { return t < 0.5 ? 10 * t - 10 * t * t : 2.5; },
                           [](double t) { return t < 0.5 ? 10 - 20 * t : 0.0; }};
  const EncoderSpec spec = encoder(0.5, 0.47, 70);
  // Reads at 0.8 s, 1.2 s (encoder stopped, counters running) and 2.5 s (running counter past
  // 2^26 ticks = 1.37 s since the last edge).
  const QuadratureEncoder enc(spec);
  const auto events = enc.simulate(motion, 0, 2.5, 1e-3);
  const int64_t ticks[] = {std::llround(0.8 * kFpgaClockHz), std::llround(1.2 * kFpgaClockHz), std::llround(2.5 * kFpgaClockHz)};
  const auto reads = readAt(events, enc.levels(0), enc.count(0), ticks);
  const double T = 1 / kFpgaClockHz;
  double previous = 1e9;
  for (int k = 0; k < 2; ++k) {
    const Measurement m7 = measure(reads[k], RegisterFormat::Rev7);
    ASSERT_FALSE(m7.runningOverflow);
    // No edge for T_r: every Rev 7 full-cycle estimate is within 4 / ((T_r + T_i) T), the quarter
    // cycle within 1 / (T_r T).
    const double limit = 4 / ((static_cast<double>(m7.running) + m7.quarter) * T);
    EXPECT_LE(std::abs(fullCycleVelocity(m7)), limit * (1 + 1e-12));
    EXPECT_LE(std::abs(fullCycleAccelerationVelocity(m7)), limit * (1 + 1e-12));
    EXPECT_LE(std::abs(runningCounterVelocity(m7)), limit * (1 + 1e-12));
    EXPECT_LE(std::abs(quarterCycleVelocity(m7)), 1 / (m7.running * T) * (1 + 1e-12));
    // Rev 6: the running counter stands in for the oldest quarter, so the period keeps growing.
    const double rev6 = fullCycleVelocity(measure(reads[k], RegisterFormat::Rev6));
    EXPECT_LT(rev6, previous);
    EXPECT_LE(rev6, 4 / (reads[k].cycleSumWithRunning() * T) * 1.001);
    previous = rev6;
  }
  for (RegisterFormat f : {RegisterFormat::Rev6, RegisterFormat::Rev7}) {
    const Measurement m = measure(reads[2], f);
    EXPECT_EQ(quarterCycleVelocity(m), 0);
    EXPECT_EQ(fullCycleVelocity(m), 0);
    EXPECT_EQ(fullCycleAccelerationVelocity(m), 0);
    EXPECT_EQ(runningCounterVelocity(m), 0);
  }
}

TEST(VelocityEstimators, SignFollowsTheDirectionAndUnitsConvert) {
  // The same motion backward gives the same speeds with the other sign.
  const EncoderSpec spec = encoder(0.5, 0.5, 90);
  const JointMotion forward{[](double t) { return 0.01 + 3 * t + 4 * t * t; }, [](double t) { return 3 + 8 * t; }};
  const JointMotion backward{[](double t) { return 0.01 - 3 * t - 4 * t * t; }, [](double t) { return -3 - 8 * t; }};
  const Reads f = readEncoder(spec, forward, 1, 0.3, 0.05, 1);
  const Reads b = readEncoder(spec, backward, 1, 0.3, 0.05, 1);
  for (size_t k = 0; k < f.readouts.size(); ++k) {
    const Measurement mf = measure(f.readouts[k], RegisterFormat::Rev7), mb = measure(b.readouts[k], RegisterFormat::Rev7);
    EXPECT_GT(runningCounterVelocity(mf), 0);
    // The edge positions are mirrored about 0.01 rad only up to the channel pattern, so compare
    // each backward estimate with the exact speed rather than with the forward one.
    const double exact = (3 + 8 * b.times[k]) * spec.countsPerRevolution() / (2 * kPi);
    EXPECT_LT(runningCounterVelocity(mb), 0);
    EXPECT_NEAR(-runningCounterVelocity(mb), exact, 0.01 * exact);
  }
  // 64 counts/s on a 16-line encoder with a 2:1 gear is a quarter joint revolution per second.
  EncoderSpec geared = spec;
  geared.gearRatio = 2;
  EXPECT_DOUBLE_EQ(countsToDegPerSecond(64, geared), 180);
  EXPECT_DOUBLE_EQ(countsToRadPerSecond(64, geared), kPi);
  EXPECT_DOUBLE_EQ(fixedTimeVelocity(107, 100, 0.001), 7000);
}
