// The learned correction: what it may move, its model folders, its scene component (seen by the
// observers, not by the mechanics unless persistent), and training on recorded pairs.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "learning/Record.h"
#include "learning/nn/Corrector.h"
#include "learning/nn/torch/GridUNet.h"
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
const GridShape kGrid{13, 5, 5};

// A corrector whose output layer is no longer zero (a new one corrects nothing).
Corrector perturbed(const RestMesh& mesh, bool threeD, std::uint64_t seed = 3, double limit = 0.5) {
  Corrector c(mesh, kGrid, Eigen::Vector3d(0, 0.5, -1), CorrectorArchitecture{threeD, 8, limit}, "mm g s", seed);
  torch::NoGradGuard noGrad;
  torch::manual_seed(seed);
  for (auto& p : static_cast<TorchCorrector&>(c.impl()).net->parameters()) p.add_(0.3 * torch::randn_like(p));
  return c;
}

// The coarse phantom without outputs, its trajectory absolute, with `extra` in the phantom's node.
std::string coarseWith(const std::string& extra) {
  std::string s = slurp(kCoarse);
  s = std::regex_replace(s, std::regex("<VTKExporter[^>]*/>"), extra);
  s = std::regex_replace(s, std::regex("filename=\"palpation_80s.csv\""), "filename=\"" + kPalpation + "\"");
  return s;
}

}  // namespace

TEST(Corrector, MovesOnlyWhatItMayWithinItsLimit) {
  const RestMesh mesh = sceneRestMesh(kCoarse);
  Eigen::Matrix3Xd x = mesh.points;
  x.row(2).array() *= 0.98;
  const InstrumentInput tool{Eigen::Vector3d(30, 20, 38), Eigen::Vector3d(0, 0, -5)};
  // New: zero correction.
  const Corrector fresh(mesh, kGrid, Eigen::Vector3d(0, 0.5, -1), CorrectorArchitecture{}, "mm g s", 1);
  EXPECT_TRUE(fresh.correct(x, tool) == x);
  std::vector<char> fixed(mesh.points.cols(), 0);
  for (int f : mesh.fixed) fixed[f] = 1;
  const Eigen::Vector3d cell(68.7 / 12, 39.3 / 4, 35.8 / 4);
  for (bool threeD : {false, true}) {
    SCOPED_TRACE(threeD ? "3D" : "2D");
    const Corrector c = perturbed(mesh, threeD);
    const Eigen::Matrix3Xd y = c.correct(x, tool);
    int moved = 0;
    for (int i = 0; i < x.cols(); ++i) {
      const Eigen::Vector3d d = y.col(i) - x.col(i);
      const bool top = std::abs(mesh.points(2, i) - 35.8) < 1e-9;  // the camera looks down: the top is observed
      if (fixed[i] || (!threeD && !top)) {
        EXPECT_TRUE(d.isZero(0)) << "node " << i;
      } else {
        moved += !d.isZero(0);
        EXPECT_TRUE((d.cwiseAbs().array() <= 0.5 * cell.array() * (1 + 1e-6)).all()) << "node " << i << ": " << d.transpose();
      }
    }
    EXPECT_EQ(moved, static_cast<int>(c.movableNodes().size()));
    EXPECT_EQ(static_cast<int>(c.movableNodes().size()), threeD ? 325 - 65 : 13 * 5);
  }
}

TEST(Corrector, SavedModelsLoadWithIdenticalOutputsAndRefuseAnotherMesh) {
  TempDir dir;
  const RestMesh mesh = sceneRestMesh(kCoarse);
  const Corrector c = perturbed(mesh, true);
  c.save(dir / "m", R"({"command": "test"})");
  const Corrector back = Corrector::load(dir / "m");
  const InstrumentInput tool{Eigen::Vector3d(30, 20, 38), Eigen::Vector3d(0, 0, -5)};
  EXPECT_TRUE(back.correct(mesh.points, tool) == c.correct(mesh.points, tool));
  EXPECT_TRUE(back.architecture().threeD);
  RestMesh other = mesh;
  other.fixed.pop_back();
  const std::string e = errorOf([&] { back.checkMesh(other, "the body 'dofs'"); });
  EXPECT_NE(e.find("13 x 5 x 5"), std::string::npos) << e;
  EXPECT_NE(e.find("64 fixed nodes"), std::string::npos) << e;
  // A stepper's folder is not a corrector's.
  auto config = nlohmann::json::parse(slurp(dir / "m/config.json"));
  config["kind"] = "stepper";
  spit(dir / "m/config.json", config.dump());
  EXPECT_NE(errorOf([&] { Corrector::load(dir / "m"); }).find("not a corrector"), std::string::npos);
}

// The refined surface: every boundary face's grid refined three times, each point once.
TEST(Corrector, RefinedSurfaceCoversTheBoundaryThreeTimesFiner) {
  const RestMesh mesh = sceneRestMesh(kCoarse);
  const Corrector c(mesh, kGrid, Eigen::Vector3d(0, 0, -1), CorrectorArchitecture{}, "mm g s", 1);
  const Eigen::Matrix3Xd s = c.refinedSurface(mesh.points);
  const int nx = 37, ny = 13, nz = 13;  // refined nodes per axis
  EXPECT_EQ(s.cols(), nx * ny * nz - (nx - 2) * (ny - 2) * (nz - 2));
  for (int k = 0; k < s.cols(); ++k) {
    const Eigen::Vector3d p = s.col(k);
    const bool onFace = std::abs(p.x()) < 1e-4 || std::abs(p.x() - 68.7) < 1e-4 || std::abs(p.y()) < 1e-4 ||
                        std::abs(p.y() - 39.3) < 1e-4 || std::abs(p.z()) < 1e-4 || std::abs(p.z() - 35.8) < 1e-4;
    ASSERT_TRUE(onFace) << p.transpose();
  }
  // cloudToPoints against the refined vertices: a point on a refined vertex is at distance 0.
  Eigen::Matrix3Xf cloud(3, 2);
  cloud.col(0) = s.col(5).cast<float>();
  cloud.col(1) = (s.col(9) + Eigen::Vector3d(0, 0, 1)).cast<float>();
  const CloudDistance d = cloudToPoints(cloud, s);
  EXPECT_LE(d.mean, 0.5 + 1e-6);
  EXPECT_GT(d.mean, 0);
}

TEST(LearnedCorrection, ObserversSeeItAndTheMechanicsDoNot) {
  TempDir dir;
  const RestMesh mesh = sceneRestMesh(kCoarse);
  const Corrector c = perturbed(mesh, false);
  c.save(dir / "corrector", "");
  perturbed(mesh, false, 3, 0.01).save(dir / "small", "");
  spit(dir / "plain.xml", coarseWith(""));
  spit(dir / "corrected.xml", coarseWith("<LearnedCorrection name=\"correction\" model=\"corrector\"/>"));
  spit(dir / "persistent.xml", coarseWith("<LearnedCorrection model=\"small\" persistent=\"true\"/>"));
  auto plain = buildScene(io::readScene(dir / "plain.xml"));
  auto corrected = buildScene(io::readScene(dir / "corrected.xml"));
  auto persistent = buildScene(io::readScene(dir / "persistent.xml"));
  Simulation a(*plain), b(*corrected), p(*persistent);
  const MechanicalObject& bodyA = *plain->all<MechanicalObject>().at(0);
  const MechanicalObject& bodyB = *corrected->all<MechanicalObject>().at(0);
  const MechanicalObject& bodyP = *persistent->all<MechanicalObject>().at(0);
  const RigidObject& tool = *plain->all<RigidObject>().at(0);
  const Corrector small = Corrector::load(dir / "small");
  double apart = 0;
  for (int k = 0; k < 40; ++k) {
    ASSERT_FALSE(a.step());
    ASSERT_FALSE(b.step());
    ASSERT_FALSE(p.step());
    const RigidObject::Live& t = tool.live(a.state());
    // The corrected scene shows the correction of the plain scene's state, step after step.
    ASSERT_TRUE(bodyB.x(b.state()) == c.correct(bodyA.x(a.state()), {t.p, t.v})) << "step " << k;
    apart = std::max(apart, (bodyP.x(p.state()) - small.correct(bodyA.x(a.state()), {t.p, t.v})).norm());
  }
  EXPECT_GT((bodyB.x(b.state()) - bodyA.x(a.state())).norm(), 0);
  EXPECT_GT(apart, 0);  // a persistent correction changes the mechanics

  spit(dir / "wrong.xml", std::regex_replace(coarseWith("<LearnedCorrection model=\"corrector\"/>"), std::regex("n=\"13 5 5\""), "n=\"13 5 6\""));
  const std::string e = errorOf([&] { buildScene(io::readScene(dir / "wrong.xml"))->init(); });
  EXPECT_NE(e.find("LearnedCorrection.model"), std::string::npos) << e;
  EXPECT_NE(e.find("13 x 5 x 5"), std::string::npos) << e;
}

TEST(LearnedCorrection, TrainsOnPairsAndResumes) {
  TempDir dir;
  // A measured dataset (gravity on, 5 kPa) and pairs from a scene 4x too stiff.
  const std::string cmd = std::string("'") + VISCERA_BINARY + "' dataset make '" + kCoarse + "' --out '" + (dir / "data") +
                          "' --time 3 --set '/root.gravity=0 0 -9810' --position '34.35 -150 330' --look-at '34.35 19.65 30'"
                          " --rate 10 --tissue-only --no-wrench --quiet";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  PairOptions po;
  po.scene = kCoarse;
  po.data = dir / "data";
  po.out = dir / "pairs";
  po.sets = {"/root.gravity=0 0 -9810", "phantom/fem.youngModulus=20 kPa"};
  po.maxPoints = 500;
  const PairResult pr = recordPairs(po);
  EXPECT_EQ(pr.frames, 31);
  const PairSet pairs = readPairSet(dir / "pairs");
  EXPECT_EQ(pairs.grid.nx, 13);
  EXPECT_LT(pairs.viewDirection.z(), -0.8);  // the camera looks down
  EXPECT_EQ(pairs.clouds.size(), 31u);
  EXPECT_LE(pairs.clouds[10].cols(), 500);
  EXPECT_GT(pairs.clouds[10].cols(), 100);
  EXPECT_NE(errorOf([&] { recordPairs(po); }).find("already exists"), std::string::npos);

  CorrectorTrainOptions o;
  o.data = {dir / "pairs"};
  o.out = dir / "model";
  o.architecture = CorrectorArchitecture{false, 4, 0.5};
  o.epochs = 2;
  o.threads = 1;
  o.maxPoints = 200;
  std::vector<CorrectorEpochReport> reports;
  trainCorrector(o, [&](const CorrectorEpochReport& r) { reports.push_back(r); });
  ASSERT_EQ(reports.size(), 2u);
  EXPECT_TRUE(reports[0].best);
  EXPECT_TRUE(std::isfinite(reports[1].trainLoss));
  EXPECT_GT(reports[0].heldOutBefore, 0);
  o.resume = true;
  o.epochs = 3;
  reports.clear();
  trainCorrector(o, [&](const CorrectorEpochReport& r) { reports.push_back(r); });
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].epoch, 3);
  const CorrectionEvaluation ev = evaluateCorrector(Corrector::load(dir / "model"), pairs);
  EXPECT_EQ(ev.time.size(), 31u);
  EXPECT_GT(ev.meanBefore, 0);
  ASSERT_EQ(ev.surfaceBefore.size(), 31u);
  // The exact surface is nearer than its refined vertices.
  EXPECT_LT(ev.meanSurfaceBefore, ev.meanBefore);
  EXPECT_GT(ev.meanSurfaceBefore, 0);
}
