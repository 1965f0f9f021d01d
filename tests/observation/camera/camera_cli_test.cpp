// `viscera camera`: the rest frame of a scene given a camera on the command line, frames at the
// rate over a run, a scene's own camera, and option errors (exit code 2, nothing written).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

#include "io/pointcloud/CloudIo.h"
#include "tests/apps/cli_helpers.h"

using namespace viscera_test;

namespace {

const std::string kPhantom = sourcePath("scenes/gel_phantom_coarse.xml");
const std::vector<std::string> kAbove = {"--position", "34 -300 300", "--look-at", "34,18,20"};

std::vector<std::string> cameraArgs(const std::string& scene, const std::string& out, std::vector<std::string> more) {
  std::vector<std::string> a = {"camera", scene, "--out", out};
  a.insert(a.end(), more.begin(), more.end());
  return a;
}

TEST(CameraCli, RestFrameWithACameraFromTheOptions) {
  TempDir tmp;
  const std::string out = tmp / "out";
  RunResult r = runViscera(cameraArgs(kPhantom, out, kAbove));
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.err.find("camera 'camera': wrote 1 frame to " + out + "/camera (points per frame: min "), std::string::npos) << r;
  const auto frames = viscera::cloud::listCloudSequence(out + "/camera");
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].time, 0.0);
  EXPECT_GT(viscera::cloud::readCloud(frames[0].path).size(), 2000);
  // Only the camera writes: the scene's VTKExporter is not run.
  EXPECT_FALSE(fs::exists(out + "/gel_phantom_coarse.pvd"));
}

TEST(CameraCli, FramesAtTheRateOverARun) {
  TempDir tmp;
  const std::string out = tmp / "out";
  auto args = kAbove;
  args.insert(args.end(), {"--time", "0.1", "--rate", "30", "--format", "ply", "--ascii", "--stride", "2", "--tissue-only"});
  RunResult r = runViscera(cameraArgs(kPhantom, out, args));
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.err.find("wrote 4 frames"), std::string::npos) << r;
  const auto frames = viscera::cloud::listCloudSequence(out + "/camera");
  ASSERT_EQ(frames.size(), 4u);
  // Steps of 1/150 s: the frames due at k / 30 s fall on every fifth step.
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(frames[static_cast<size_t>(k)].time, k / 30.0, 1e-9);
  EXPECT_EQ(slurp(frames[0].path).rfind("ply\nformat ascii", 0), 0u);
}

TEST(CameraCli, SceneWithItsOwnCamera) {
  TempDir tmp;
  std::ofstream(tmp / "scene.xml")
      << "<Node name=\"root\" units=\"mm g s\" dt=\"10 ms\" gravity=\"0 0 0\">\n"
         "  <RegularGridTopology name=\"grid\" n=\"5 3 3\" min=\"0 0 0\" max=\"40 20 20\"/>\n"
         "  <MechanicalObject name=\"dofs\"/>\n"
         "  <TetrahedronSetTopologyContainer name=\"tetra\"/>\n"
         "  <Hexa2TetraTopologicalMapping input=\"@grid\" output=\"@tetra\"/>\n"
         "  <DepthCamera name=\"top\" position=\"20 -150 200\" lookAt=\"20 10 10\" width=\"64\" height=\"48\"/>\n"
         "</Node>\n";
  RunResult r = runViscera(cameraArgs(tmp / "scene.xml", tmp / "out", {"--steps", "10"}));
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_EQ(viscera::cloud::listCloudSequence(tmp / "out/top").size(), 4u);  // 30 Hz over 0.1 s
  // Camera options are for scenes without a camera.
  r = runViscera(cameraArgs(tmp / "scene.xml", tmp / "out2", {"--fov", "50"}));
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("has its own DepthCamera"), std::string::npos) << r;
  EXPECT_TRUE(absentOrEmpty(tmp / "out2"));
}

TEST(CameraCli, OptionErrorsWriteNothing) {
  TempDir tmp;
  auto with = [](std::vector<std::string> more) {
    auto a = kAbove;
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {std::vector<std::string>{}, "the scene has no DepthCamera; place one with --position and --look-at"},
      {with({"--fov", "200"}), "--fov: DepthCamera.fov: value 200 is out of range"},
      {with({"--dropout", "1.5"}), "--dropout: DepthCamera.dropout: value 1.5 is out of range"},
      {with({"--up", "0 -318 280"}), "--up: DepthCamera.up: is parallel"},
      {{"--position", "34 18 20", "--look-at", "100 18 20"}, "--position: DepthCamera.position: the camera at (34, 18, 20) is inside"},
      {with({"--far", "300 mm"}), "--position: DepthCamera.position: nothing is in view"},
      {with({"--near", "500", "--far", "400"}), "--far: DepthCamera.far: 400 must be beyond near (500)"},
      {with({"--transform", tmp / "missing.txt"}), "--transform: DepthCamera.transform: give either"},
  };
  int k = 0;
  for (const auto& [args, message] : cases) {
    const std::string out = tmp / ("out" + std::to_string(k++));
    RunResult r = runViscera(cameraArgs(kPhantom, out, args));
    EXPECT_EQ(r.rc, 2) << r;
    EXPECT_NE(r.err.find(message), std::string::npos) << r;
    EXPECT_TRUE(absentOrEmpty(out)) << r;
  }
}

}  // namespace
