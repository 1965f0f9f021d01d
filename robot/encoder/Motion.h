// Joint motions to drive simulated encoders: sums of sinusoids (closed form) and sampled angles
// read from a `t,theta` CSV (C1 cubic Hermite interpolation, so the velocity is continuous).
#pragma once

#include <string>
#include <vector>

#include "robot/encoder/Quadrature.h"

namespace viscera::robot::encoder {

// theta(t) = sum_k A_k (sin(2 pi f_k t + phi_k) - sin(phi_k)), so theta(0) = 0.
struct SinusoidTerm {
  double amplitude = 0;  // rad
  double frequency = 0;  // Hz
  double phase = 0;      // rad
};
JointMotion sinusoidMotion(const std::vector<SinusoidTerm>& terms);

// A motion through samples (time in s, strictly increasing; angle in rad). Between samples a
// cubic Hermite curve with three-point slopes (one-sided at the ends); before the first and after
// the last sample the angle holds and the velocity is 0. Throws std::invalid_argument for fewer
// than two samples, sizes that differ, or times that do not increase.
JointMotion sampledMotion(std::vector<double> times, std::vector<double> angles);

struct MotionFile {
  JointMotion motion;
  double start = 0, end = 0;  // first and last sample time
};
// Reads `t,theta` rows (s, rad; optional header, '#' comments) through io::readNumericCsv. Throws
// viscera::Error "file:line: ..." for a time that does not increase, and "file: ..." for fewer
// than two rows (and whatever the CSV reader rejects).
MotionFile readMotionCsv(const std::string& path);

}  // namespace viscera::robot::encoder
