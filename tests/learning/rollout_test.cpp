// Rollouts for a learned stepper: the binary formats read back what was written and refuse what
// is not theirs, and a recording holds exactly the states of the simulations it ran.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "learning/Record.h"
#include "learning/data/Rollout.h"
#include "study/Replay.h"
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

RestMesh smallMesh() {
  RestMesh m;
  m.points = Eigen::Matrix3Xd::Random(3, 5);
  m.tets.resize(4, 2);
  m.tets << 0, 1, 1, 2, 2, 3, 3, 4;
  m.fixed = {0, 4};
  return m;
}

RolloutFrame frame(double t, int nodes) {
  RolloutFrame f;
  f.t = t;
  f.x = Eigen::Matrix3Xf::Random(3, nodes);
  f.tip = Eigen::Vector3d::Random();
  f.orientation = Eigen::Quaterniond(Eigen::Vector4d::Random().normalized());
  f.velocity = Eigen::Vector3d::Random();
  f.angularVelocity = Eigen::Vector3d::Random();
  f.force = Eigen::Vector3d::Random();
  f.contacts = 3;
  return f;
}

TEST(Rollout, FilesReadBackWhatWasWritten) {
  TempDir dir;
  const RestMesh m = smallMesh();
  writeRestMesh(dir / "mesh.bin", m);
  const RestMesh back = readRestMesh(dir / "mesh.bin");
  EXPECT_TRUE(back.points == m.points);
  EXPECT_TRUE(back.tets == m.tets);
  EXPECT_EQ(back.fixed, m.fixed);

  std::vector<RolloutFrame> frames = {frame(0, 5), frame(0.5, 5), frame(1, 5)};
  {
    RolloutWriter w(dir / "r.bin", 5);
    for (const auto& f : frames) w.add(f);
    EXPECT_FALSE(fs::exists(dir / "r.bin"));  // only once complete
    w.close();
  }
  const auto read = readRollout(dir / "r.bin", 5);
  ASSERT_EQ(read.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(read[i].t, frames[i].t);
    EXPECT_TRUE(read[i].x == frames[i].x);
    EXPECT_TRUE(read[i].tip == frames[i].tip);
    EXPECT_TRUE(read[i].orientation.coeffs() == frames[i].orientation.coeffs());
    EXPECT_TRUE(read[i].velocity == frames[i].velocity);
    EXPECT_TRUE(read[i].angularVelocity == frames[i].angularVelocity);
    EXPECT_TRUE(read[i].force == frames[i].force);
    EXPECT_EQ(read[i].contacts, 3);
  }
  // A writer dropped before close leaves nothing.
  { RolloutWriter w(dir / "dropped.bin", 5); w.add(frames[0]); }
  EXPECT_FALSE(fs::exists(dir / "dropped.bin"));
  EXPECT_FALSE(fs::exists(dir / "dropped.bin.partial"));
}

TEST(Rollout, FilesThatAreNotRolloutsAreErrorsNamingTheFile) {
  TempDir dir;
  writeRestMesh(dir / "mesh.bin", smallMesh());
  {
    RolloutWriter w(dir / "r.bin", 5);
    w.add(frame(0, 5));
    w.add(frame(1, 5));
    w.close();
  }
  const std::string mesh = slurp(dir / "mesh.bin"), roll = slurp(dir / "r.bin");
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"empty.bin", ""},
      {"text.bin", "hello, not a rollout at all"},
      {"cut.bin", roll.substr(0, roll.size() - 7)},
      {"long.bin", roll + "x"},
      {"mesh_as_rollout.bin", mesh},
  };
  for (const auto& entry : bad) {
    const std::string& name = entry.first;  // (a structured binding cannot be captured in C++17)
    spit(dir / name, entry.second);
    const std::string e = errorOf([&] { readRollout(dir / name); });
    EXPECT_NE(e.find(name), std::string::npos) << name << ": " << e;
  }
  EXPECT_NE(errorOf([&] { readRollout(dir / "r.bin", 6); }).find("has 5 nodes a frame; its mesh has 6"), std::string::npos);
  // A frame count that the file cannot hold is refused before anything is allocated.
  std::string huge = roll;
  huge[16] = huge[17] = huge[18] = huge[19] = '\xff';
  spit(dir / "huge.bin", huge);
  EXPECT_NE(errorOf([&] { readRollout(dir / "huge.bin"); }).find("4294967295 frames"), std::string::npos);
  std::string badNode = mesh;
  badNode[8 + 4 + 12 + 24 * 5] = 9;  // the first tetrahedron's first node: 9 of 5
  spit(dir / "bad_node.bin", badNode);
  EXPECT_NE(errorOf([&] { readRestMesh(dir / "bad_node.bin"); }).find("refers to node 9 of 5"), std::string::npos);
  spit(dir / "cut_mesh.bin", mesh.substr(0, mesh.size() - 1));
  EXPECT_NE(errorOf([&] { readRestMesh(dir / "cut_mesh.bin"); }).find("cut_mesh.bin"), std::string::npos);
}

const std::string kCoarse = std::string(VISCERA_SOURCE_DIR) + "/scenes/gel_phantom_coarse.xml";

RecordOptions shortRecording(const fs::path& out, int jobs) {
  RecordOptions o;
  o.scene = kCoarse;
  o.out = out.string();
  o.rollouts = 2;
  o.time = 6.0;  // long enough for a poke
  o.speedMin = 10;
  o.speedMax = 20;
  o.rate = 30;
  o.seed = 7;
  o.jobs = jobs;
  return o;
}

TEST(Record, RolloutsHoldTheStatesOfTheSimulationsTheyRan) {
  TempDir dir;
  const fs::path rec = dir / "rec", rec1 = dir / "rec1";
  const RecordResult r = record(shortRecording(rec, 2));
  EXPECT_EQ(r.rollouts, 2);
  EXPECT_EQ(r.diverged, 0);
  const auto index = nlohmann::json::parse(slurp(rec / "rollouts.json"));
  EXPECT_EQ(index["format"], "viscera rollouts");
  EXPECT_EQ(index["stepsPerFrame"], 5);  // dt = 1/150 s, 30 frames per second
  const RestMesh mesh = readRestMesh(rec / "mesh.bin");
  EXPECT_EQ(mesh.points.cols(), 13 * 5 * 5);
  EXPECT_FALSE(mesh.fixed.empty());  // the bottom is clamped

  for (int k = 0; k < 2; ++k) {
    SCOPED_TRACE(k);
    const auto& entry = index["rollouts"][k];
    EXPECT_EQ(entry["status"], "ok");
    EXPECT_EQ(entry["seed"], 7 + k);
    const auto frames = readRollout(rec / entry["file"].get<std::string>(), static_cast<int>(mesh.points.cols()));
    ASSERT_EQ(frames.size(), 181u);  // 0 .. 6 s at 30 Hz
    EXPECT_EQ(entry["frames"], 181);
    // Replayed independently from the trajectory the recording wrote: frame i is the state after
    // 5 i steps, bit for bit (in single precision).
    SceneDesc desc = study::withTrajectory(io::readScene(kCoarse), (rec / entry["trajectory"].get<std::string>()).string(),
                                           0, "the test follows the rollout's palpation");
    auto scene = buildScene(desc);
    Simulation sim(*scene);
    const MechanicalObject& body = *scene->all<MechanicalObject>().at(0);
    const RigidObject& tool = *scene->all<RigidObject>().at(0);
    int touching = 0;
    for (const auto& f : frames) touching += f.contacts > 0 && f.force.norm() > 0;
    EXPECT_GT(touching, 0);  // the palpation reaches the tissue
    for (size_t i = 0; i < frames.size(); ++i) {
      while (sim.steps() < static_cast<int>(5 * i)) ASSERT_FALSE(sim.step());
      ASSERT_EQ(frames[i].t, sim.time());
      ASSERT_TRUE(frames[i].x == body.x(sim.state()).cast<float>()) << "frame " << i;
      ASSERT_TRUE(frames[i].tip == tool.live(sim.state()).p) << "frame " << i;
      ASSERT_TRUE(frames[i].force == tool.live(sim.state()).force) << "frame " << i;
    }
  }
  // The two rollouts differ (their own palpations), and one job gives the same files as two.
  EXPECT_NE(slurp(rec / "rollout_0000.bin"), slurp(rec / "rollout_0001.bin"));
  record(shortRecording(rec1, 1));
  for (const char* f : {"mesh.bin", "rollout_0000.bin", "rollout_0001.bin"})
    EXPECT_EQ(slurp(rec / f), slurp(rec1 / f)) << f;
}

TEST(Record, BadInputIsAnErrorAndWritesNothing) {
  TempDir dir;
  fs::create_directories(dir / "exists");
  EXPECT_NE(errorOf([&] { record(shortRecording(dir / "exists", 1)); }).find("already exists"), std::string::npos);
  RecordOptions o = shortRecording(dir / "out", 1);
  o.depthMin = 5;
  o.depthMax = 1;
  EXPECT_NE(errorOf([&] { record(o); }).find("--depth"), std::string::npos);
  o = shortRecording(dir / "out", 1);
  o.rollouts = 0;
  EXPECT_NE(errorOf([&] { record(o); }).find("--rollouts"), std::string::npos);
  o = shortRecording(dir / "out", 1);
  o.time = 0.5;
  EXPECT_NE(errorOf([&] { record(o); }).find("--time: 0.5 is too short for one poke"), std::string::npos);
  // A scene whose instrument no TrajectoryDriver moves.
  spit(dir / "beam.xml", slurp(std::string(VISCERA_SOURCE_DIR) + "/scenes/beam.xml"));
  o = shortRecording(dir / "out", 1);
  o.scene = dir / "beam.xml";
  EXPECT_FALSE(errorOf([&] { record(o); }).empty());
  EXPECT_FALSE(fs::exists(dir / "out"));
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

}  // namespace
