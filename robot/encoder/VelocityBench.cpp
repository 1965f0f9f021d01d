#include "robot/encoder/VelocityBench.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "robot/encoder/EncoderFpga.h"

namespace viscera::robot::encoder {

JointMotion benchMotion() {
  constexpr double deg = std::numbers::pi / 180;
  // Phase pi/2: each term is A (cos(2 pi f t) - 1), at rest at t = 0.
  return sinusoidMotion({{200 * deg, 0.4, std::numbers::pi / 2}, {40 * deg, 1.1, std::numbers::pi / 2}});
}

const char* benchEstimatorName(BenchEstimator e) {
  switch (e) {
    case BenchEstimator::FixedTime: return "fixed_time";
    case BenchEstimator::Quarter: return "quarter";
    case BenchEstimator::Full: return "full";
    case BenchEstimator::FullAcceleration: return "full_acc";
    case BenchEstimator::RunningCounter: return "full_acc_running";
  }
  return "";
}

BenchResult runBench(const JointMotion& motion, double start, double end, const BenchSpec& spec) {
  if (!(spec.readRate > 0) || !std::isfinite(spec.readRate)) throw std::invalid_argument("readRate: must be a positive number");
  if (spec.truth.clockHz != spec.test.clockHz) throw std::invalid_argument("clockHz: both encoders are read by one FPGA clock");
  if (!(end >= start)) throw std::invalid_argument("duration: the motion ends before it starts");
  if ((end - start) * spec.readRate >= static_cast<double>(kMaxBenchReads))
    throw std::invalid_argument("readRate: the motion would take more than " + std::to_string(kMaxBenchReads) + " reads");
  const QuadratureEncoder truthEncoder(spec.truth), testEncoder(spec.test);
  const double clockHz = spec.test.clockHz;

  // Host reads on the FPGA clock's ticks.
  std::vector<int64_t> ticks;
  for (int64_t k = 0;; ++k) {
    const double t = start + static_cast<double>(k) / spec.readRate;
    if (t > end) break;
    ticks.push_back(std::llround(t * clockHz));
  }

  auto readEncoder = [&](const QuadratureEncoder& enc, size_t& edgeCount) {
    const std::vector<EdgeEvent> events = enc.simulate(motion, start, end, spec.maxStep);
    edgeCount = events.size();
    const double angle0 = motion.angle(start);
    return readAt(events, enc.levels(angle0), enc.count(angle0), ticks);
  };
  BenchResult out;
  const std::vector<FpgaReadout> truthReads = readEncoder(truthEncoder, out.truthEdges);
  const std::vector<FpgaReadout> testReads = readEncoder(testEncoder, out.testEdges);

  out.estimators = {BenchEstimator::FixedTime, BenchEstimator::Quarter, BenchEstimator::Full,
                    BenchEstimator::FullAcceleration};
  if (spec.format == RegisterFormat::Rev7) out.estimators.push_back(BenchEstimator::RunningCounter);
  out.estimates.assign(out.estimators.size(), std::vector<double>(ticks.size()));
  out.time.resize(ticks.size());
  out.exact.resize(ticks.size());
  out.truth.resize(ticks.size());

  constexpr double degPerRad = 180 / std::numbers::pi;
  for (size_t k = 0; k < ticks.size(); ++k) {
    const double t = static_cast<double>(ticks[k]) / clockHz;
    out.time[k] = t;
    out.exact[k] = motion.velocity(t) * degPerRad;
    out.truth[k] = countsToDegPerSecond(fullCycleVelocity(measure(truthReads[k], spec.format)), spec.truth);
    const Measurement m = measure(testReads[k], spec.format);
    for (size_t e = 0; e < out.estimators.size(); ++e) {
      double countsPerSecond = 0;
      switch (out.estimators[e]) {
        case BenchEstimator::FixedTime:
          // The first read has no earlier one: no velocity yet.
          countsPerSecond = k == 0 ? 0 : fixedTimeVelocity(testReads[k].position, testReads[k - 1].position, t - out.time[k - 1]);
          break;
        case BenchEstimator::Quarter: countsPerSecond = quarterCycleVelocity(m); break;
        case BenchEstimator::Full: countsPerSecond = fullCycleVelocity(m); break;
        case BenchEstimator::FullAcceleration: countsPerSecond = fullCycleAccelerationVelocity(m, spec.estimator); break;
        case BenchEstimator::RunningCounter: countsPerSecond = runningCounterVelocity(m, spec.estimator); break;
      }
      out.estimates[e][k] = countsToDegPerSecond(countsPerSecond, spec.test);
    }
  }
  return out;
}

double rms(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) throw std::invalid_argument("rms: series of different lengths");
  if (a.empty()) return 0;
  double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(sum / static_cast<double>(a.size()));
}

}  // namespace viscera::robot::encoder
