// Helpers for the study tests: the small indented block of tests/data/study and datasets written
// as another tool would write them (clouds in the scene or a camera frame, at times of their own).
#pragma once

#include <Eigen/Geometry>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "io/pointcloud/CloudIo.h"
#include "io/scene/SceneReader.h"
#include "io/scene/Transform.h"
#include "tests/support/TempDir.h"

namespace viscera_test {

namespace fs = std::filesystem;

inline std::string studyData(const std::string& name) {
  return std::string(VISCERA_SOURCE_DIR) + "/tests/data/study/" + name;
}

inline void writeText(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

// Points on the block's top face (z = 20, 0 < x < 40, 0 < y < 20) lifted by `lift`: each is
// exactly `lift` from the surface (its closest point is straight below it, inside the face).
inline Eigen::Matrix3Xd liftedTopFace(double lift) {
  Eigen::Matrix3Xd p(3, 6 * 3);
  int k = 0;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 3; ++j) p.col(k++) = Eigen::Vector3d(4 + 6.4 * i, 4 + 6 * j, 20 + lift);
  return p;
}

// A dataset as another tool would write it: the instrument parked 50 mm above the block (never
// touching), frames at `times` (not on the scene's 10 ms steps) holding `cloud` (scene frame),
// written as ASCII PCD in the camera frame of `cameraToScene` when given.
// `t0` is added to every time (a clock that does not start at 0).
inline void writeParkedDataset(const fs::path& dir, const std::vector<double>& times, const Eigen::Matrix3Xd& cloud,
                               const viscera::RigidTransform* cameraToScene = nullptr, const std::string& wrench = "",
                               double t0 = 0) {
  fs::create_directories(dir / "camera");
  auto stamp = [&](double t) {
    char b[40];
    std::snprintf(b, sizeof b, "%.17g", t0 + t);
    return std::string(b);
  };
  // Sampled at 7 Hz: another rate than the frames' and the steps'.
  std::string traj = "t,x,y,z,qx,qy,qz,qw\n";
  for (int k = 0; k <= 7; ++k) traj += stamp(k / 7.0) + ",20,10,75,0,0,0,1\n";
  writeText(dir / "trajectory.csv", traj);
  std::string index = "time,file\n";
  for (size_t k = 0; k < times.size(); ++k) {
    viscera::cloud::PointCloud c;
    c.points = cameraToScene ? (cameraToScene->inverse() * cloud.colwise().homogeneous()).eval() : cloud;
    const std::string name = "f" + std::to_string(k) + ".pcd";
    viscera::cloud::writeCloud((dir / "camera" / name).string(), c, viscera::cloud::CloudEncoding::Ascii);
    index += stamp(times[k]) + "," + name + "\n";
  }
  writeText(dir / "camera" / "index.csv", index);
  if (cameraToScene) viscera::writeTransform((dir / "camera_to_scene.txt").string(), *cameraToScene);
  if (!wrench.empty()) writeText(dir / "wrench.csv", wrench);
}

// The block scene with its trajectory relative to the test data folder.
inline viscera::SceneDesc blockScene() { return viscera::io::readScene(studyData("block.xml")); }

}  // namespace viscera_test
