// dVRK PSM kinematics on the hot path of a joint-log driver: forward kinematics (all six frames
// and the tool tip) into caller-owned storage, then the dVRK "spatial" Jacobian from those frames,
// for joint values drawn at random within the limits. Target: under 2 us per call on one core.
#include <benchmark/benchmark.h>

#include <array>
#include <random>
#include <vector>

#include "robot/kinematics/PsmKinematics.h"

using namespace viscera::robot;

namespace {

void BM_PsmForwardKinematicsAndJacobian(benchmark::State& state) {
  const SerialChain psm = psmLargeNeedleDriver();
  // A pool of random configurations (fixed seed), cycled through so that the branch pattern and
  // the trigonometric arguments change from call to call as they would along a log.
  std::mt19937 rng(1);
  std::vector<Eigen::Matrix<double, 6, 1>> pool(1024);
  for (auto& q : pool)
    for (int i = 0; i < kPsmDof; ++i)
      q[i] = std::uniform_real_distribution<double>(psm.joints()[i].lower, psm.joints()[i].upper)(rng);
  std::array<Eigen::Isometry3d, kPsmDof> frames;
  Jacobian J(6, kPsmDof);
  std::size_t next = 0;
  for (auto _ : state) {
    const Eigen::Isometry3d tip = psm.forwardKinematics(pool[next], frames);
    psm.spatialJacobian(frames, tip, J);
    benchmark::DoNotOptimize(J.data());
    benchmark::ClobberMemory();
    next = (next + 1) % pool.size();
  }
}
BENCHMARK(BM_PsmForwardKinematicsAndJacobian)->Repetitions(9)->ReportAggregatesOnly(true);

}  // namespace
