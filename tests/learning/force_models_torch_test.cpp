// The force estimators' networks: they learn functions known in closed form (a per-output MLP a
// static map, an LSTM a difference that needs its window), keep their predictions through a model
// folder, and a trained force model composes with its base (the trocar correction's form).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/Error.h"
#include "learning/force/ForceTraining.h"
#include "learning/nn/Regressor.h"
#include "learning/nn/Stepper.h"
#include "robot/dynamics/ArmSimulator.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using namespace viscera::learning;
using viscera::test_support::TempDir;

namespace {

RegressorData staticMap(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  RegressorData d{Eigen::MatrixXf(n, 3), Eigen::MatrixXf(n, 2)};
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) d.x(i, c) = u(rng);
    d.y(i, 0) = std::sin(2 * d.x(i, 0)) + d.x(i, 1) * d.x(i, 2);
    d.y(i, 1) = 100 * d.x(i, 2);  // another scale
  }
  return d;
}

double rmsError(const Eigen::MatrixXf& a, const Eigen::MatrixXf& b, int col) {
  return std::sqrt((a.col(col) - b.col(col)).squaredNorm() / static_cast<double>(a.rows()));
}

TEST(Regressor, PerOutputMlpLearnsAStaticMapAndKeepsItThroughItsFolder) {
  setTorchThreads(1);
  RegressorArchitecture a;
  a.window = 1;
  a.features = 3;
  a.outputs = 2;
  a.hidden = 32;
  RegressorTrainOptions o;
  o.epochs = 60;
  o.batch = 64;
  o.learningRate = 3e-3;
  const RegressorData train = staticMap(3000, 1), test = staticMap(500, 2);
  const Regressor r = Regressor::train(a, o, train, test);
  const Eigen::MatrixXf p = r.predict(test.x);
  // The first output spans about +-2, the second +-100: both within 3 % of their spread.
  EXPECT_LT(rmsError(p, test.y, 0), 0.06);
  EXPECT_LT(rmsError(p, test.y, 1), 3.0);
  TempDir dir;
  r.save(dir / "m", "{\"note\": 1}");
  const Regressor back = Regressor::load(dir / "m");
  EXPECT_EQ(back.predict(test.x), p);
  EXPECT_EQ(back.parameters(), r.parameters());
}

TEST(Regressor, LstmLearnsWhatOnlyItsWindowShows) {
  setTorchThreads(1);
  // y = x_t - x_{t-1} over a window of 2 steps of one feature.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  auto make = [&](int n) {
    RegressorData d{Eigen::MatrixXf(n, 2), Eigen::MatrixXf(n, 1)};
    for (int i = 0; i < n; ++i) {
      d.x(i, 0) = u(rng);
      d.x(i, 1) = u(rng);
      d.y(i, 0) = d.x(i, 1) - d.x(i, 0);
    }
    return d;
  };
  RegressorArchitecture a;
  a.kind = "lstm";
  a.window = 2;
  a.features = 1;
  a.outputs = 1;
  a.hidden = 16;
  RegressorTrainOptions o;
  o.epochs = 40;
  o.batch = 64;
  o.learningRate = 3e-3;
  const RegressorData train = make(3000), test = make(500);
  const Regressor r = Regressor::train(a, o, train, test);
  // The spread of y is about 0.8 (rms); a network without the window could do no better than that.
  EXPECT_LT(rmsError(r.predict(test.x), test.y, 0), 0.08);
}

TEST(Regressor, RefusesArchitecturesAndDataThatDoNotFit) {
  RegressorArchitecture a;
  a.features = 3;
  a.outputs = 2;
  const RegressorData d = staticMap(10, 1);
  a.kind = "transformer";
  EXPECT_THROW(Regressor::train(a, {}, d, {}), Error);
  a.kind = "mlp";
  a.features = 4;
  EXPECT_THROW(Regressor::train(a, {}, d, {}), Error);
}

// The confined workspace of an arm docked at a patient, with or without the body wall; perfect
// sensors, so that what the base misses is the wall's push alone, a function of the joint states.
robot::JointStateLog simulated(std::uint64_t seed, double duration, bool wall) {
  robot::ArmSimulationOptions o = robot::psmSimulationDefaults();
  o.measurement.makePerfect();
  o.duration = duration;
  o.rate = 200;
  o.seed = seed;
  o.excitation.lower = {-0.3, -0.2, 0.10, -1.0, -0.5, -0.5};
  o.excitation.upper = {0.3, 0.2, 0.18, 1.0, 0.5, 0.5};
  o.trocar.enabled = wall;
  const robot::ArmRecording r = robot::simulateArm(robot::psmDynamics(), o);
  return robot::makeJointStateLog(r.t, r.q, r.qd, r.effort, "seed " + std::to_string(seed));
}

TEST(ForceModel, CorrectionLearnsTheTrocarsShareOnTopOfItsBase) {
  setTorchThreads(1);
  TempDir dir;
  ForceTrainSpec base;
  base.kind = "physical";
  const ForceModel physical = trainForceModel(base, {{"free", simulated(1, 120, false), {}, {}}});
  physical.save(dir / "base");
  const ForceRecording trocarTrain{"trocar", simulated(2, 60, true), {}, {}};
  const robot::JointStateLog trocarTest = simulated(3, 20, true);
  ForceTrainSpec spec;
  spec.kind = "correction";
  spec.base = dir / "base";
  spec.window = 5;
  spec.hidden = 32;
  spec.epochs = 15;
  const ForceModel corrected = trainForceModel(spec, {trocarTrain});
  corrected.save(dir / "corrected");
  const ForceModel loaded = ForceModel::load(dir / "corrected");
  ASSERT_TRUE(loaded.base);
  EXPECT_EQ(loaded.freeSpaceEfforts(trocarTest), corrected.freeSpaceEfforts(trocarTest));
  EXPECT_NE(loaded.freeSpaceEfforts(trocarTest), physical.freeSpaceEfforts(trocarTest));
  // The online estimate at the last sample is the batch estimate's last row.
  const Eigen::VectorXd last = loaded.freeSpaceEfforts(trocarTest).bottomRows(1).transpose();
  EXPECT_LT((loaded.lastFreeSpaceEffort(trocarTest) - last).norm(), 1e-6 * (1 + last.norm()));
  // Yaw and pitch carry the body wall's push, which the base never saw: base plus correction must
  // meet the efforts it was trained on much better than the base alone (how well a correction
  // carries over to other motion is measured on minutes of data, not in a unit test).
  const Eigen::MatrixXd effort = trocarTrain.joints.effort();
  const Eigen::MatrixXd before = physical.freeSpaceEfforts(trocarTrain.joints) - effort;
  const Eigen::MatrixXd after = loaded.freeSpaceEfforts(trocarTrain.joints) - effort;
  for (int j : {0, 1}) EXPECT_LT(after.col(j).norm(), 0.7 * before.col(j).norm()) << "joint " << j + 1;
}

TEST(ForceModel, WindowsRepeatTheFirstSampleBeforeTheStart) {
  Eigen::MatrixXd f(3, 2);
  f << 1, 2, 3, 4, 5, 6;
  const Eigen::MatrixXf w = windowed(f, 2);
  Eigen::MatrixXf expected(3, 4);
  expected << 1, 2, 1, 2, 1, 2, 3, 4, 3, 4, 5, 6;
  EXPECT_EQ(w, expected);
}

}  // namespace
