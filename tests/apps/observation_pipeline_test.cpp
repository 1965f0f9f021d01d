// The observation chain end to end, through the command line as a user runs it: a virtual depth
// camera captures the gel phantom standing on a table, `cloud prep` removes the table, `register
// icp` finds the camera pose from a rough guess, and `distance` compares the registered cloud with
// the simulated surface. The camera's true pose is known in closed form, so the registration and
// the distances are checked against answers that none of the commands computed.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <iostream>
#include <string>

#include "io/pointcloud/CloudIo.h"
#include "io/scene/Transform.h"
#include "tests/apps/cli_helpers.h"

namespace viscera_test {
namespace {

// A value of a flat JSON object ("key": number), for the summaries the commands write.
double jsonNumber(const std::string& json, const std::string& key) {
  const size_t k = json.find("\"" + key + "\"");
  if (k == std::string::npos) throw std::runtime_error("no key " + key + " in " + json);
  const size_t colon = json.find(':', k);
  return std::stod(json.substr(colon + 1));
}

TEST(ObservationPipeline, CameraPrepRegisterDistanceRecoverTheTruth) {
  TempDir dir("viscera_pipeline");
  const std::string scene = sourcePath("scenes/gel_phantom_coarse.xml");
  // Camera 410 mm from the phantom's centre, above and in front of it (the dissertation's camera
  // is "mounted above the workspace"), seeing the top and the front face.
  const Eigen::Vector3d position(34, -250, 330), target(34, 18, 20);

  RunResult cam = runViscera({"camera", scene, "--out", dir / "capture", "--position", "34 -250 330", "--look-at",
                              "34 18 20", "--table", "0 0 1 0", "--quiet"});
  ASSERT_EQ(cam.rc, 0) << cam;
  const std::string frame = dir / "capture/camera/frame_000000.pcd";
  ASSERT_TRUE(fs::exists(frame)) << cam;

  // The depth noise grows with z^2, so the far table is noisier than the default 2 mm plane band:
  // 6 mm (about 3 sigma at the phantom) removes the table, and the bottom 6 mm of the front face
  // with it, which the registration does not need.
  RunResult prep = runViscera({"cloud", "prep", frame, dir / "phantom.pcd", "--plane-threshold", "6", "--report",
                               dir / "prep.json", "--quiet"});
  ASSERT_EQ(prep.rc, 0) << prep;
  const viscera::cloud::PointCloud raw = viscera::cloud::readCloud(frame);
  const viscera::cloud::PointCloud kept = viscera::cloud::readCloud(dir / "phantom.pcd");
  // The table fills most of the image; what is left is the phantom's top and front faces.
  EXPECT_LT(kept.size(), raw.size() / 2);
  EXPECT_GT(kept.size(), 1000);

  RunResult rest = runViscera({"run", scene, "--steps", "0", "--out", dir / "rest", "--quiet"});
  ASSERT_EQ(rest.rc, 0) << rest;
  const std::string mesh = dir / "rest/gel_phantom_coarse_000000.vtu";
  ASSERT_TRUE(fs::exists(mesh));

  // A rough initial guess, 2 degrees and 3 mm off at the camera (about 15 mm at the phantom). The
  // block is nearly symmetric under a quarter turn about x (35.8 x 39.3 mm) and only two faces are
  // seen, so a guess 4 degrees off already converges to the turned pose: the guess matters, as the
  // dissertation notes.
  RunResult icp = runViscera({"register", "icp", "--cloud", dir / "phantom.pcd", "--mesh", mesh, "--init-rotation",
                              "-137 0 0", "--init-translation", "32 -248 332", "--out", dir / "camera_to_scene.txt"});
  ASSERT_EQ(icp.rc, 0) << icp;
  const viscera::RigidTransform found = viscera::readTransform(dir / "camera_to_scene.txt");

  // The true camera -> scene pose: z along the view, x = z x up (up = +z), y = z x x (image down).
  const Eigen::Vector3d z = (target - position).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Matrix3d R;
  R << x, z.cross(x), z;
  const double angleDeg = Eigen::AngleAxisd(found.linear() * R.transpose()).angle() * 180.0 / M_PI;
  // Position error where it matters: at the phantom's corners (in scene coordinates).
  double cornerError = 0.0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) * 68.7, ((c >> 1) & 1) * 35.8, ((c >> 2) & 1) * 39.3);
    const Eigen::Vector3d inCamera = R.transpose() * (corner - position);
    cornerError = std::max(cornerError, (found * inCamera - corner).norm());
  }
  // 0.5 degree and 0.5 mm at the corners with the camera's own noise (sigma 2.1 mm along the rays
  // at 410 mm) on about 6000 points of two faces. Measured: 0.3 degree and 0.46 mm; most of it is
  // the bias of closest-point matching near the block's edges (noisy points just inside an edge
  // are nearer the other face), which tests/registration quantifies.
  std::cout << "registration error: " << angleDeg << " deg, " << cornerError << " mm at the worst corner\n";
  EXPECT_LT(angleDeg, 0.5);
  EXPECT_LT(cornerError, 0.5);

  RunResult dist = runViscera({"distance", "--cloud", dir / "phantom.pcd", "--mesh", mesh, "--transform",
                               dir / "camera_to_scene.txt", "--method", "triangles", "--summary", dir / "distance.json",
                               "--quiet"});
  ASSERT_EQ(dist.rc, 0) << dist;
  const std::string summary = slurp(dir / "distance.json");
  // Undeformed tissue: what remains is the camera's noise. Along the ray it is N(0, sigma) with
  // sigma = 2 (z / 400)^2 mm, about 2.1 mm here; the distance to a face seen at incidence angle a
  // is |n| cos a, so its mean is below E|n| = 0.80 sigma = 1.7 mm and far above zero.
  const double mean = jsonNumber(summary, "mean");
  EXPECT_GT(mean, 0.5) << summary;
  EXPECT_LT(mean, 1.8) << summary;
}

}  // namespace
}  // namespace viscera_test
