// Encoder velocity on the host's hot path: one update is decoding an encoder's velocity registers
// and the full-cycle-with-acceleration estimate (II.7 from Rev 6 registers, II.8 with the running
// counter from Rev 7), over register samples of the 16-line bench
// encoder read at 1 kHz (the reads hold every state the bench goes through: starting, constant
// and changing speed, reversals). Target: 10 million updates per second on one core. And the
// edge simulator, edges per second (informational).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "robot/encoder/EncoderFpga.h"
#include "robot/encoder/Quadrature.h"
#include "robot/encoder/Registers.h"
#include "robot/encoder/VelocityBench.h"
#include "robot/encoder/VelocityEstimators.h"

using namespace viscera::robot::encoder;

namespace {

// The bench encoder's readouts at 1 kHz over the built-in motion.
std::vector<FpgaReadout> benchReadouts() {
  const BenchSpec spec;
  const QuadratureEncoder enc(spec.test);
  const JointMotion motion = benchMotion();
  const auto events = enc.simulate(motion, 0, kBenchDuration, spec.maxStep);
  std::vector<int64_t> ticks;
  for (int k = 0; k <= 4000; ++k) ticks.push_back(std::llround(k * 1e-3 * kFpgaClockHz));
  return readAt(events, enc.levels(motion.angle(0)), enc.count(motion.angle(0)), ticks);
}

void BM_VelocityUpdateRev6(benchmark::State& state) {
  std::vector<Rev6Registers> samples;
  for (const FpgaReadout& r : benchReadouts()) samples.push_back(encodeRev6(r));
  const EstimatorOptions options;
  for (auto _ : state) {
    double sum = 0;
    for (const Rev6Registers& q : samples) sum += fullCycleAccelerationVelocity(decodeRev6(q.period, q.acceleration), options);
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(samples.size()));
}
BENCHMARK(BM_VelocityUpdateRev6);

void BM_VelocityUpdateRev7(benchmark::State& state) {
  std::vector<Rev7Registers> samples;
  for (const FpgaReadout& r : benchReadouts()) samples.push_back(encodeRev7(r));
  const EstimatorOptions options;
  for (auto _ : state) {
    double sum = 0;
    for (const Rev7Registers& q : samples)
      sum += runningCounterVelocity(decodeRev7(q.period, q.quarter, q.quarterPrev, q.running), options);
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(samples.size()));
}
BENCHMARK(BM_VelocityUpdateRev7);

// The 600-line reference encoder over the built-in motion: 9021 edges.
void BM_EncoderSimulate(benchmark::State& state) {
  const BenchSpec spec;
  const QuadratureEncoder enc(spec.truth);
  const JointMotion motion = benchMotion();
  int64_t edges = 0;
  for (auto _ : state) {
    const auto events = enc.simulate(motion, 0, kBenchDuration, spec.maxStep);
    edges += static_cast<int64_t>(events.size());
    benchmark::DoNotOptimize(events.data());
  }
  state.SetItemsProcessed(edges);
}
BENCHMARK(BM_EncoderSimulate)->Unit(benchmark::kMillisecond);

}  // namespace
