// Velocity from quadrature encoder timing (dissertation Appendix II). All estimates are in counts
// per second (quadrature counts: four per line), signed by the direction bit; the converters at
// the end turn them into joint units.
//
//  quarter cycle       v = 1 / (T_i T)                            responsive, but every duty-cycle
//                                                                  or phase error shows
//  full cycle          v = 4 / (S_i T)                       II.2  immune to those errors, half a
//                                                                  cycle late
//  acceleration        a = 8 (T_{i-4} - T_i) / (S_i S_{i-1} T^2 (T_{i-4} + T_i))         II.6
//                      with S_{i-1} = S_i + T_{i-4} - T_i (quarters of one edge type, one cycle
//                      apart, so imperfections cancel)
//  full + acceleration v = 4 / (S_i T) + a S_i T / 2             II.7  the half-cycle delay removed
//  running counter     v = 4 / (S_i T) + a (S_i T / 2 + T_r T)   II.8  also the time since the edge
//
// with T the clock period. Rules for what the registers cannot support:
//  - overflow (encoder stopped or too slow for the counters, or not measured yet): velocity 0;
//  - a cycle spanning a reversal: 4 / S is then the mean speed over the last four edges, given the
//    direction of the latest (the shaft slowed, turned and sped up again within it), with no
//    acceleration (see next);
//  - acceleration 0 on overflow of any quarter, a direction change, an encoder error, quarters in
//    different directions, differing edge masks of T_i and T_{i-4} (Rev 7: not one edge type, so
//    imperfections would not cancel), and at high speed, when T_i is shorter than a threshold
//    (2000 ticks of the 49.152 MHz clock by default): there the difference of the quarters is a
//    few ticks and quantisation dominates;
//  - a prediction (II.7, II.8) never changes the sign of the full-cycle velocity (it stops at 0);
//  - with a running counter (Rev 7), no edge for T_r bounds the speed: the quarter in progress
//    lasts at least T_r, so the quarter-cycle estimate uses max(T_i, T_r); the cycle in progress
//    holds T_r and T_i, so the full-cycle estimates are at most 4 / ((T_r + T_i) T), a bound that
//    never cuts a constant-speed estimate whatever the imperfections, and takes the estimate to 0
//    as the encoder stops.
#pragma once

#include <cstdint>

#include "robot/encoder/Registers.h"

namespace viscera::robot::encoder {

struct EstimatorOptions {
  // Acceleration is used only while T_i lasts at least this long (s).
  double accelerationMinQuarter = 2000 / kFpgaClockHz;
};

double quarterCycleVelocity(const Measurement& m);
double fullCycleVelocity(const Measurement& m);                                       // II.2
double cycleAcceleration(const Measurement& m, const EstimatorOptions& options = {});  // II.6, counts/s^2
double fullCycleAccelerationVelocity(const Measurement& m, const EstimatorOptions& options = {});  // II.7
double runningCounterVelocity(const Measurement& m, const EstimatorOptions& options = {});         // II.8

// Position difference over the host's sample interval (s).
inline double fixedTimeVelocity(int64_t countNow, int64_t countBefore, double interval) {
  return static_cast<double>(countNow - countBefore) / interval;
}

// Counts/s (of an encoder with `spec`) to joint rad/s and deg/s: counts x 2 pi / (4 lines gear).
double countsToRadPerSecond(double countsPerSecond, const EncoderSpec& spec);
double countsToDegPerSecond(double countsPerSecond, const EncoderSpec& spec);

}  // namespace viscera::robot::encoder
