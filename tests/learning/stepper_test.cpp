// The learned stepper through its public interface: model folders read back what was written and
// refuse another mesh or architecture, the LearnedStepper component steps a scene as the model does,
// training writes resumable checkpoints, and the evaluation reports per segment.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "learning/Record.h"
#include "learning/nn/Stepper.h"
#include "tests/support/ErrorOf.h"
#include "tests/support/FileText.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using namespace viscera::learning;
using viscera::test_support::errorOf;
using viscera::test_support::slurp;
using viscera::test_support::spit;
using viscera::test_support::TempDir;
namespace fs = std::filesystem;

namespace {

const std::string kCoarse = std::string(VISCERA_SOURCE_DIR) + "/scenes/gel_phantom_coarse.xml";
const std::string kPalpation = std::string(VISCERA_SOURCE_DIR) + "/scenes/palpation_80s.csv";

StepperNormalisers normalisersOf(const RestMesh& mesh) {
  StepperNormalisers n;
  n.cell = Eigen::Vector3d(5.725, 9.825, 8.95);
  n.boxMin = mesh.points.rowwise().minCoeff();
  n.boxMax = mesh.points.rowwise().maxCoeff();
  n.reach = 15;
  n.velocityScale = 20;
  return n;
}

// The coarse phantom with the learned stepper in place of its FEM solve, at the model's 30 Hz.
std::string learnedScene(const std::string& model, const std::string& dt = "0.033333333333333333", const std::string& grid = "13 5 5") {
  return R"(<Node name="root" units="mm g s" dt=")" + dt + R"(" gravity="0 0 0">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d"/>
    <TrajectoryDriver name="replay" filename=")" + kPalpation + R"("/>
    <SphereCollisionModel name="tip" radius="5"/>
  </Node>
  <Node name="phantom">
    <LearnedStepper name="stepper" model=")" + model + R"("/>
    <RegularGridTopology name="grid" n=")" + grid + R"(" min="0 0 0" max="68.7 39.3 35.8"/>
    <MechanicalObject name="dofs" template="Vec3d"/>
    <TetrahedronSetTopologyContainer name="tetra"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tetra" swapping="true"/>
    <BoxROI name="bottom" box="-1 -1 -1 70 41 0.1"/>
    <FixedConstraint indices="@bottom.indices"/>
  </Node>
</Node>
)";
}

// Records `rollouts` quick palpations of the coarse phantom into dir/rec and returns options that
// train a tiny network on them into dir/model, one epoch on one thread.
StepperTrainOptions tinyTraining(const fs::path& dir, int rollouts, double time, std::uint64_t seed) {
  RecordOptions rec;
  rec.scene = kCoarse;
  rec.out = dir / "rec";
  rec.rollouts = rollouts;
  rec.time = time;
  rec.speedMin = 15;
  rec.speedMax = 20;
  rec.seed = seed;
  record(rec);
  StepperTrainOptions o;
  o.data = {dir / "rec"};
  o.out = dir / "model";
  o.architecture = StepperArchitecture{8, 2, 2, 1.0};
  o.epochs = 1;
  o.warmup = 0;
  o.threads = 1;
  return o;
}

class StepperTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!torchAvailable()) GTEST_SKIP() << "built without LibTorch";
  }
};

}  // namespace

TEST_F(StepperTest, SavedModelsLoadWithIdenticalOutputs) {
  TempDir dir;
  const RestMesh mesh = sceneRestMesh(kCoarse);
  const Stepper model(mesh, StepperArchitecture{16, 2, 2, 1.0}, normalisersOf(mesh), 1.0 / 30, "mm g s", 3);
  model.save(dir / "m", R"({"command": "test"})");
  const Stepper back = Stepper::load(dir / "m");
  EXPECT_EQ(back.parameters(), model.parameters());
  EXPECT_EQ(back.architecture().width, 16);
  EXPECT_EQ(back.units(), "mm g s");
  EXPECT_DOUBLE_EQ(back.framePeriod(), 1.0 / 30);
  EXPECT_EQ(nlohmann::json::parse(back.training())["command"], "test");
  Eigen::Matrix3Xd x = mesh.points;
  x.row(2).array() -= 0.5 * (x.row(2).array() / 35.8);
  const InstrumentInput tool{Eigen::Vector3d(30, 20, 38), Eigen::Vector3d(0, 0, -8)};
  const Eigen::Matrix3Xd a = model.step(x, tool), b = back.step(x, tool);
  EXPECT_TRUE(a == b);
  EXPECT_GT((a - x).norm(), 0);  // an untrained network moves the nodes: the comparison means something
  for (int f : mesh.fixed) EXPECT_TRUE(a.col(f) == x.col(f)) << "fixed node " << f;
  EXPECT_LE(((a - x).cwiseAbs().rowwise().maxCoeff() - Eigen::Vector3d(5.725, 9.825, 8.95)).maxCoeff(), 1e-5);
  // Without the instrument within reach the features differ: so does the step.
  const InstrumentInput away{Eigen::Vector3d(300, 20, 38), Eigen::Vector3d::Zero()};
  EXPECT_FALSE(model.step(x, away) == a);
  // Anchored at rest: the rest shape left alone stays exactly at rest; not so with the instrument in
  // reach, nor for a network without the anchor.
  EXPECT_TRUE(model.step(mesh.points, away) == mesh.points);
  EXPECT_FALSE(model.step(mesh.points, tool) == mesh.points);
  const Stepper free(mesh, StepperArchitecture{16, 2, 2, 1.0, false}, normalisersOf(mesh), 1.0 / 30, "mm g s", 3);
  EXPECT_FALSE(free.step(mesh.points, away) == mesh.points);

  // A network that predicts offsets reads back as one and steps as before saving.
  StepperArchitecture offsets{16, 2, 2, 1.0};
  offsets.output = StepperArchitecture::Output::NextOffset;
  const Stepper o(mesh, offsets, normalisersOf(mesh), 1.0 / 30, "mm g s", 3);
  o.save(dir / "o", "");
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "o/config.json"))["architecture"]["output"], "next offset");
  const Stepper oBack = Stepper::load(dir / "o");
  EXPECT_EQ(oBack.architecture().output, StepperArchitecture::Output::NextOffset);
  EXPECT_TRUE(oBack.step(x, tool) == o.step(x, tool));
  EXPECT_FALSE(o.step(x, tool) == model.step(x, tool));
  EXPECT_TRUE(o.step(mesh.points, away) == mesh.points);  // still anchored at rest
  EXPECT_EQ(Stepper::load(dir / "m").architecture().output, StepperArchitecture::Output::Update);
}

TEST_F(StepperTest, AModelForAnotherMeshOrArchitectureIsRefused) {
  TempDir dir;
  const RestMesh mesh = sceneRestMesh(kCoarse);
  const Stepper model(mesh, StepperArchitecture{16, 2, 2, 1.0}, normalisersOf(mesh), 1.0 / 30, "mm g s", 3);
  model.save(dir / "m", "");
  RestMesh other = mesh;
  other.points(0, 7) += 0.01;
  std::string e = errorOf([&] { model.checkMesh(other, "the body 'dofs'"); });
  EXPECT_NE(e.find("325 nodes, 1152 tetrahedra and 65 fixed nodes"), std::string::npos) << e;
  EXPECT_NE(e.find("the body 'dofs' has 325 nodes"), std::string::npos) << e;
  EXPECT_NE(e.find("other rest positions"), std::string::npos) << e;
  EXPECT_NO_THROW(model.checkMesh(mesh, "same"));

  // config.json says width 32 while the weights are of width 16.
  auto config = nlohmann::json::parse(slurp(dir / "m/config.json"));
  config["architecture"]["width"] = 32;
  spit(dir / "m/config.json", config.dump());
  e = errorOf([&] { Stepper::load(dir / "m"); });
  EXPECT_NE(e.find("weights.pt"), std::string::npos) << e;
  EXPECT_NE(e.find("16x"), std::string::npos) << e;
  EXPECT_NE(e.find("another architecture"), std::string::npos) << e;
  // A mesh file that is not the one the configuration names.
  config["architecture"]["width"] = 16;
  config["mesh"]["hash"] = "0123456789abcdef";
  spit(dir / "m/config.json", config.dump());
  e = errorOf([&] { Stepper::load(dir / "m"); });
  EXPECT_NE(e.find("not the mesh the model was trained on"), std::string::npos) << e;
  EXPECT_NE(errorOf([&] { Stepper::load(dir / "nothing"); }).find("not a model folder"), std::string::npos);
  // A format version this build does not know.
  config["version"] = 3;
  spit(dir / "m/config.json", config.dump());
  e = errorOf([&] { Stepper::load(dir / "m"); });
  EXPECT_NE(e.find("version 3 of a stepper model"), std::string::npos) << e;
}

TEST_F(StepperTest, LearnedStepperStepsTheSceneAsTheModelDoes) {
  TempDir dir;
  const RestMesh mesh = sceneRestMesh(kCoarse);
  const Stepper model(mesh, StepperArchitecture{16, 2, 2, 0.05}, normalisersOf(mesh), 1.0 / 30, "mm g s", 4);
  model.save(dir / "model", "");
  spit(dir / "learned.xml", learnedScene("model"));
  auto scene = buildScene(io::readScene(dir / "learned.xml"));
  Simulation sim(*scene);
  const MechanicalObject& body = *scene->all<MechanicalObject>().at(0);
  const RigidObject& tool = *scene->all<RigidObject>().at(0);
  Eigen::Matrix3Xd x = mesh.points;
  for (int k = 0; k < 20; ++k) {
    ASSERT_FALSE(sim.step());
    const RigidObject::Live& t = tool.live(sim.state());
    x = model.step(x, {t.p, t.v});
    ASSERT_TRUE(body.x(sim.state()) == x) << "step " << k;
  }
  EXPECT_GT((x - mesh.points).norm(), 0);

  // The scene's dt must be the model's frame period; the body must be the model's mesh.
  spit(dir / "fast.xml", learnedScene("model", "0.01"));
  std::string e = errorOf([&] { buildScene(io::readScene(dir / "fast.xml"))->init(); });
  EXPECT_NE(e.find("LearnedStepper.model"), std::string::npos) << e;
  EXPECT_NE(e.find("dt"), std::string::npos) << e;
  spit(dir / "finer.xml", learnedScene("model", "0.033333333333333333", "14 5 5"));
  e = errorOf([&] { buildScene(io::readScene(dir / "finer.xml"))->init(); });
  EXPECT_NE(e.find("trained on a mesh of 325 nodes"), std::string::npos) << e;
  EXPECT_NE(e.find("350 nodes"), std::string::npos) << e;
  spit(dir / "missing.xml", learnedScene("no_such_model"));
  e = errorOf([&] { buildScene(io::readScene(dir / "missing.xml"))->init(); });
  EXPECT_NE(e.find("no_such_model"), std::string::npos) << e;
}

TEST_F(StepperTest, TrainingWritesAModelAndResumesFromItsCheckpoint) {
  TempDir dir;
  StepperTrainOptions o = tinyTraining(dir.path(), 3, 6, 11);
  o.batch = 16;
  o.validationTime = 1;
  std::vector<EpochReport> reports;
  trainStepper(o, [&](const EpochReport& r) { reports.push_back(r); });
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_TRUE(reports[0].best);
  EXPECT_TRUE(std::isfinite(reports[0].trainLoss));
  EXPECT_GT(reports[0].baselineError, 0);
  const Stepper first = Stepper::load(dir / "model");
  const auto training = nlohmann::json::parse(first.training());
  EXPECT_EQ(training["trainingRollouts"], 2);
  EXPECT_EQ(training["heldOutRollouts"].size(), 1u);
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "model/checkpoint/state.json"))["epoch"], 1);

  // The folder exists: a second training into it is refused unless resumed.
  EXPECT_NE(errorOf([&] { trainStepper(o, {}); }).find("already exists"), std::string::npos);
  o.resume = true;
  o.epochs = 2;
  reports.clear();
  trainStepper(o, [&](const EpochReport& r) { reports.push_back(r); });
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].epoch, 2);
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "model/checkpoint/state.json"))["epoch"], 2);
  o.out = dir / "fresh";
  EXPECT_NE(errorOf([&] { trainStepper(o, {}); }).find("no checkpoint"), std::string::npos);

  // Evaluation: the first frame is shared, segments cover the rollout.
  const RolloutSet data = readRolloutSet(dir / "rec");
  const auto evals = evaluateStepper(Stepper::load(dir / "model"), data, 1.0);
  ASSERT_EQ(evals.size(), 3u);
  for (const auto& ev : evals) {
    EXPECT_EQ(ev.error.front(), 0.0);  // both start at the first frame
    EXPECT_LT(ev.baseline.front(), 1e-5);  // which is at rest (to single precision)
    ASSERT_EQ(ev.segments.size(), 6u);
    int frames = 0;
    for (const auto& s : ev.segments) frames += s.frames;
    EXPECT_EQ(frames, static_cast<int>(ev.time.size()) - 1);
    EXPECT_EQ(ev.segments[0].frames, 30);
    EXPECT_DOUBLE_EQ(ev.segments[5].t1, 6.0);
  }
}

TEST_F(StepperTest, CosineScheduleLowersTheRateAlongAHalfCosine) {
  TempDir dir;
  StepperTrainOptions o = tinyTraining(dir.path(), 2, 5, 12);
  o.epochs = 3;
  o.validationTime = 0.5;
  o.learningRate = 1e-3;
  o.schedule = RateSchedule::Cosine;
  o.patience = 1;  // the plateau schedule would halve the rate after any epoch that is not the best
  std::vector<double> rates;
  trainStepper(o, [&](const EpochReport& r) { rates.push_back(r.learningRate); });
  // 0.5 (1 + cos(pi k / 3)) for k = 0, 1, 2: 1, 3/4, 1/4 of the initial rate.
  ASSERT_EQ(rates.size(), 3u);
  EXPECT_NEAR(rates[0], 1e-3, 1e-12);
  EXPECT_NEAR(rates[1], 7.5e-4, 1e-12);
  EXPECT_NEAR(rates[2], 2.5e-4, 1e-12);
  EXPECT_EQ(nlohmann::json::parse(Stepper::load(dir / "model").training())["rateSchedule"], "cosine");
  // The checkpoint holds the rate in use, not one halved for patience.
  const auto state = nlohmann::json::parse(slurp(dir / "model/checkpoint/state.json"));
  EXPECT_NEAR(state["learningRate"].get<double>(), 2.5e-4, 1e-12);
  // Resuming goes on with the checkpoint's schedule, or not at all.
  o.resume = true;
  o.epochs = 6;
  std::string e = errorOf([&] { trainStepper(o, {}); });
  EXPECT_NE(e.find("runs over 3 epochs; resume with --epochs 3"), std::string::npos) << e;
  o.epochs = 3;
  o.schedule = RateSchedule::Plateau;
  e = errorOf([&] { trainStepper(o, {}); });
  EXPECT_NE(e.find("resume with --schedule cosine"), std::string::npos) << e;
}
