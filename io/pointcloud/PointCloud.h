// A point cloud: one depth-camera frame or a processed capture. PCL-free, so that the engine and
// the metrics can use it without PCL's headers.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace viscera::cloud {

struct PointCloud {
  Eigen::Matrix3Xd points;   // 3 x n, in the cloud's frame (camera, or scene after registration)
  Eigen::Matrix3Xd normals;  // 3 x n when the file has normals, else empty
  double time = 0.0;         // seconds (frame timestamp); 0 when unknown
  std::string source;        // the file it was read from, for messages; empty if made in memory

  int size() const { return static_cast<int>(points.cols()); }
  bool empty() const { return points.cols() == 0; }
};

}  // namespace viscera::cloud
