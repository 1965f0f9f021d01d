// The DepthCamera component in a scene: frames at the requested rate whatever the time step,
// frames of the current positions, the instrument sphere and tissueOnly, and input errors that
// name the scene file, line and attribute.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <stdexcept>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/pointcloud/CloudIo.h"
#include "io/scene/SceneReader.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using viscera::test_support::TempDir;

namespace {

// A 40 x 20 x 20 mm block (5 x 3 x 3 nodes) without solver, so that it stays where it is put, and
// optionally an instrument sphere; `camera` is the DepthCamera element's attributes.
std::string sceneText(const std::string& camera, bool block = true, const std::string& instrument = "") {
  std::string s =
      "<?xml version=\"1.0\"?>\n"
      "<Node name=\"root\" units=\"mm g s\" dt=\"10 ms\" gravity=\"0 0 0\">\n";
  if (block)
    s += "  <Node name=\"block\">\n"
         "    <RegularGridTopology name=\"grid\" n=\"5 3 3\" min=\"0 0 0\" max=\"40 20 20\"/>\n"
         "    <MechanicalObject name=\"dofs\"/>\n"
         "    <TetrahedronSetTopologyContainer name=\"tetra\"/>\n"
         "    <Hexa2TetraTopologicalMapping input=\"@grid\" output=\"@tetra\"/>\n"
         "  </Node>\n";
  if (!instrument.empty())
    s += "  <Node name=\"instrument\">\n"
         "    <MechanicalObject name=\"tool\" template=\"Rigid3d\" position=\"" + instrument + " 0 0 0 1\"/>\n"
         "    <SphereCollisionModel name=\"tip\" radius=\"5\"/>\n"
         "  </Node>\n";
  s += "  <DepthCamera " + camera + "/>\n</Node>\n";
  return s;
}

// A noise-free 64 x 48 camera 250 mm from the block, looking at it from the front and above.
const std::string kCamera =
    "name=\"cam\" position=\"20 -150 200\" lookAt=\"20 10 10\" width=\"64\" height=\"48\" fov=\"40\" near=\"10\" "
    "sigma0=\"0\" dropout=\"0\" depthUnit=\"0\" grazingAngle=\"90\" frame=\"scene\"";

struct SceneRun {
  TempDir dir{"camera_scene"};
  std::unique_ptr<Scene> scene;
  std::unique_ptr<Simulation> sim;
  explicit SceneRun(const std::string& text) {
    std::ofstream(dir / "scene.xml") << text;
    scene = buildScene(io::readScene(dir / "scene.xml"));
    scene->setOutputDirectory(dir / "out");
    sim = std::make_unique<Simulation>(*scene);
  }
  void steps(int n) {
    sim->begin();
    for (int i = 0; i < n; ++i) ASSERT_FALSE(sim->step());
  }
  Component& camera() const {
    for (Component* c : scene->all<Component>())
      if (c->typeName() == "DepthCamera") return *c;
    throw std::logic_error("the scene has no DepthCamera");
  }
  std::vector<cloud::CloudFrame> frames(const std::string& camera = "cam") const {
    return cloud::listCloudSequence(dir / ("out/" + camera));
  }
};

// Distance from p to the surface of the box [lo, hi].
double boxSurfaceDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const Eigen::Vector3d outside = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
  if (outside.norm() > 0) return outside.norm();
  return std::min((p - lo).minCoeff(), (hi - p).minCoeff());
}

std::vector<double> times(const std::vector<cloud::CloudFrame>& frames) {
  std::vector<double> t;
  for (const auto& f : frames) t.push_back(f.time);
  return t;
}

TEST(DepthCameraComponent, FramesAtTheRateNotTheStep) {
  {
    // 30 Hz with 10 ms steps: frame k is due at k / 30 s and taken at the first step time that
    // reaches it: 0, 0.04, 0.07, 0.10 over ten steps.
    SceneRun run(sceneText(kCamera + " rate=\"30\""));
    run.steps(10);
    const auto t = times(run.frames());
    ASSERT_EQ(t.size(), 4u);
    const double expected[] = {0, 0.04, 0.07, 0.10};
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(t[k], expected[k], 1e-12);
  }
  {
    // 25 Hz divides the step: every fourth step (0, 0.04, 0.08); the rate carries a unit.
    SceneRun run(sceneText(kCamera + " rate=\"25 Hz\""));
    run.steps(10);
    const auto t = times(run.frames());
    ASSERT_EQ(t.size(), 3u);
    EXPECT_NEAR(t[1], 0.04, 1e-12);
    EXPECT_NEAR(t[2], 0.08, 1e-12);
  }
}

TEST(DepthCameraComponent, FramesShowTheCurrentPositions) {
  SceneRun run(sceneText(kCamera + " rate=\"25\""));
  run.sim->begin();  // frame 0: the block at rest
  MechanicalObject* block = run.scene->all<MechanicalObject>().front();
  block->x(run.sim->state()).row(2).array() += 5;  // lift it by 5 mm
  for (int i = 0; i < 4; ++i) ASSERT_FALSE(run.sim->step());  // frame 1 at 0.04 s
  run.sim->end();
  const auto frames = run.frames();
  ASSERT_EQ(frames.size(), 2u);
  FieldValue counts;
  ASSERT_TRUE(run.camera().field("points", counts));
  ASSERT_EQ(counts.values.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const cloud::PointCloud c = cloud::readCloud(frames[static_cast<size_t>(k)].path);
    EXPECT_EQ(c.size(), static_cast<int>(counts.values[static_cast<size_t>(k)]));
    EXPECT_GT(c.size(), 100);
    const Eigen::Vector3d lift(0, 0, 5.0 * k);
    double worst = 0;
    for (int q = 0; q < c.size(); ++q)
      worst = std::max(worst, boxSurfaceDistance(c.points.col(q), Eigen::Vector3d(0, 0, 0) + lift,
                                                 Eigen::Vector3d(40, 20, 20) + lift));
    // Noise-free points on the block's surface, to the float32 precision of the file (~1e-5 mm here).
    EXPECT_LT(worst, 1e-3) << "frame " << k;
  }
}

TEST(DepthCameraComponent, InstrumentHidesTissueAndTissueOnlyDropsIt) {
  // The sphere sits 8 mm above the top face, between it and the camera.
  const std::string tool = "20 10 33";
  SceneRun all(sceneText(kCamera, true, tool));
  all.steps(0);
  SceneRun tissue(sceneText(kCamera + " tissueOnly=\"true\"", true, tool));
  tissue.steps(0);
  SceneRun without(sceneText(kCamera));
  without.steps(0);
  const cloud::PointCloud a = cloud::readCloud(all.frames()[0].path);
  const cloud::PointCloud t = cloud::readCloud(tissue.frames()[0].path);
  const cloud::PointCloud w = cloud::readCloud(without.frames()[0].path);
  int onSphere = 0;
  for (int q = 0; q < a.size(); ++q) onSphere += std::abs((a.points.col(q) - Eigen::Vector3d(20, 10, 33)).norm() - 5) < 1e-3;
  EXPECT_GT(onSphere, 5);  // the sphere covers a few pixels of this small image
  for (int q = 0; q < t.size(); ++q)
    EXPECT_LT(boxSurfaceDistance(t.points.col(q), Eigen::Vector3d::Zero(), Eigen::Vector3d(40, 20, 20)), 1e-3);
  // Every point is on the sphere or the block; the sphere hides some of the block.
  EXPECT_EQ(a.size(), t.size() + onSphere);
  EXPECT_LT(t.size(), w.size());
}

// The message of the error that building and initialising `text` throws ("" if none).
std::string sceneError(const std::string& text, TempDir& dir) {
  std::ofstream(dir / "scene.xml") << text;
  try {
    auto scene = buildScene(io::readScene(dir / "scene.xml"));
    scene->setOutputDirectory(dir / "out");
    scene->init();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// Whether `message` starts with "<dir>/scene.xml:<line of the DepthCamera element>:" and names
// `what` (e.g. "DepthCamera.fov").
::testing::AssertionResult namesCameraLine(const std::string& message, const TempDir& dir, const std::string& what) {
  const std::string prefix = (dir / "scene.xml") + ":";
  if (message.rfind(prefix, 0) != 0) return ::testing::AssertionFailure() << "does not start with " << prefix << ": " << message;
  static const std::regex lineCol(R"(^(\d+):\d+: )");
  const std::string rest = message.substr(prefix.size());
  std::smatch m;
  if (!std::regex_search(rest, m, lineCol)) return ::testing::AssertionFailure() << "no line:col after the file in: " << message;
  const int line = std::stoi(m[1]);
  std::ifstream in(dir / "scene.xml");
  std::string l;
  for (int n = 1; std::getline(in, l); ++n)
    if (l.find("<DepthCamera") != std::string::npos && n != line)
      return ::testing::AssertionFailure() << "line " << line << " is not the camera's (" << n << "): " << message;
  if (message.find(what) == std::string::npos) return ::testing::AssertionFailure() << "no '" << what << "' in: " << message;
  return ::testing::AssertionSuccess();
}

TEST(DepthCameraComponent, BadAttributesNameFileLineAndAttribute) {
  TempDir dir("camera_errors");
  const std::string place = "position=\"20 -150 200\" lookAt=\"20 10 10\" ";
  struct Case {
    std::string attrs;
    std::string what;  // attribute and a word of the message
    bool block = true;
  };
  {
    std::ofstream(dir / "bad.txt") << "1 0 0 0\n0 1 0 0\n0 0 1\n";
  }
  const Case cases[] = {
      {"position=\"1 2 3\" lookAt=\"1 2 3\"", "DepthCamera.lookAt: is the camera position"},
      {"position=\"20 10 300\" lookAt=\"20 10 10\" up=\"0 0 1\"", "DepthCamera.up: is parallel"},
      {"position=\"20 10 10\" lookAt=\"300 10 10\"", "DepthCamera.position: the camera at (20, 10, 10) is inside"},
      {place, "DepthCamera 'DepthCamera': has nothing to see", false},
      {place + "fov=\"0\"", "DepthCamera.fov: value 0 is out of range"},
      {place + "fov=\"180\"", "DepthCamera.fov: value 180 is out of range"},
      {place + "cx=\"1000\"", "DepthCamera.cx: 1000 is outside the image"},
      {place + "fx=\"500\" fov=\"50\"", "DepthCamera.fov: give either"},
      {place + "near=\"500\" far=\"400\"", "DepthCamera.far:"},
      {place + "width=\"0\"", "DepthCamera.width: value 0 is out of range"},
      {place + "dropout=\"1\"", "DepthCamera.dropout: value 1 is out of range"},
      {place + "grazingAngle=\"95\"", "DepthCamera.grazingAngle: value 95 is out of range"},
      {place + "sigma0=\"-1 mm\"", "DepthCamera.sigma0: value -1 is out of range"},
      {place + "table=\"0 0 0 1\"", "DepthCamera.table: the plane's normal"},
      {place + "transform=\"bad.txt\"", "DepthCamera.transform: give either"},
      {"lookAt=\"20 10 10\"", "needs `position` and `lookAt`"},
      {"position=\"20 -150 200\" lookAt=\"20 -300 400\"", "DepthCamera.position: nothing is in view"},
      {place + "far=\"220\"", "DepthCamera.position: nothing is in view"},
      {place + "frame=\"world\"", "DepthCamera.frame: 'world' is not one of"},
  };
  for (const Case& c : cases) {
    const std::string msg = sceneError(sceneText(c.attrs, c.block), dir);
    EXPECT_TRUE(namesCameraLine(msg, dir, c.what)) << "attributes: " << c.attrs;
  }
  // A bad transform file: its own file and line first, then the scene element that read it.
  const std::string msg = sceneError(sceneText("transform=\"bad.txt\""), dir);
  EXPECT_NE(msg.find(dir / "bad.txt"), std::string::npos) << msg;
  EXPECT_NE(msg.find("DepthCamera.transform"), std::string::npos) << msg;
  // Two cameras writing into the same folder.
  std::string two = sceneText(place + "filename=\"frames\"");
  two.insert(two.find("</Node>\n", two.rfind("<DepthCamera")), "  <DepthCamera name=\"second\" " + place + "filename=\"frames\"/>\n");
  const std::string dup = sceneError(two, dir);
  EXPECT_NE(dup.find("DepthCamera.filename: 'frames' is also the folder"), std::string::npos) << dup;
}

}  // namespace
