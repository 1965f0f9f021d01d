// The two-encoder bench of dissertation Appendix II (Fig. II-6) in simulation: one shaft carries a
// high-resolution encoder whose full-cycle velocity is the reference ("truth", as in the
// dissertation) and a low-resolution encoder with imperfections whose velocity is estimated by
// each method; a host reads both FPGAs at a fixed rate.
#pragma once

#include <string>
#include <vector>

#include "robot/encoder/Motion.h"
#include "robot/encoder/Quadrature.h"
#include "robot/encoder/Registers.h"
#include "robot/encoder/VelocityEstimators.h"

namespace viscera::robot::encoder {

struct BenchSpec {
  // Reference: 600 lines, ideal channels.
  EncoderSpec truth{600, 1, 0.5, 0.5, 90, kFpgaClockHz};
  // Under test: 16 lines with imperfect channels, moderate for an encoder of this class: B rises
  // 70 instead of 90 electrical degrees after A and is high 47 % of a cycle (A 50 %), so the
  // quarter cycles are 19 %, 31 %, 16 % and 34 % of a cycle instead of 25 % each.
  EncoderSpec test{16, 1, 0.5, 0.47, 70, kFpgaClockHz};
  double readRate = 1000;  // host reads per second
  RegisterFormat format = RegisterFormat::Rev6;
  EstimatorOptions estimator;
  // Velocity sampling step of the edge search (s): reversals must be further apart than this.
  double maxStep = 1e-3;
};

// The default bench motion, for 4 s: two cosines starting at rest, with a speed reversal about
// every 1.3 s and speeds up to 740 deg/s: theta(t) = 200 deg (cos(2 pi 0.4 t) - 1) +
// 40 deg (cos(2 pi 1.1 t) - 1).
inline constexpr double kBenchDuration = 4;
JointMotion benchMotion();

// Estimates of the encoder under test, in the order of BenchResult::estimates.
enum class BenchEstimator { FixedTime, Quarter, Full, FullAcceleration, RunningCounter };
const char* benchEstimatorName(BenchEstimator e);  // "fixed_time", "quarter", "full", "full_acc", "full_acc_running"

struct BenchResult {
  std::vector<double> time;   // read times, s
  std::vector<double> exact;  // exact joint velocity at each read, deg/s
  std::vector<double> truth;  // reference encoder's full-cycle velocity, deg/s
  // Estimators of the encoder under test (the running-counter form only when the format has a
  // running counter, Rev 7) and their estimates at each read, deg/s.
  std::vector<BenchEstimator> estimators;
  std::vector<std::vector<double>> estimates;
  size_t truthEdges = 0, testEdges = 0;
};

// Most host reads of one bench run.
inline constexpr size_t kMaxBenchReads = 10'000'000;

// Runs the bench over [start, end] with reads at start, start + 1/rate, ... Throws
// std::invalid_argument "field: ..." for an invalid encoder (see validate), a rate or step that is
// not positive, encoders with different clocks, end < start, more than kMaxBenchReads reads
// ("readRate: ...") or more edges than QuadratureEncoder::kMaxEdges ("edges: ...").
BenchResult runBench(const JointMotion& motion, double start, double end, const BenchSpec& spec);

// Root-mean-square difference of two equally long series.
double rms(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace viscera::robot::encoder
