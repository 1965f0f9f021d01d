// A virtual depth camera: a pinhole camera that renders triangle surfaces, spheres and an optional
// plane into a depth image, and a RealSense-like noise model that turns the image into a point
// cloud. It knows nothing of scenes: the DepthCamera component (ObservationComponents.cpp) feeds
// it the tissue's boundary surfaces and the instrument spheres at each frame.
//
// Rendering is a z-buffer rasteriser whose per-pixel depth is the exact intersection of the
// pixel's ray with the primitive: for each triangle, the pixels of its projected bounding box are
// tested with the ray (edge functions of the ray against the triangle, either orientation, so
// inside-out surfaces are seen too) and take the depth of the ray's intersection with the
// triangle's plane; each sphere is intersected exactly over its projected bounding rectangle. The
// result is what ray casting the primary rays would give, at rasteriser cost.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "observation/SurfaceIndex.h"
#include "io/pointcloud/PointCloud.h"
#include "io/scene/Transform.h"

namespace viscera::obs {

// Pinhole intrinsics in pixels, OpenCV's convention: a camera-frame point (x, y, z) projects to
// u = fx x / z + cx, v = fy y / z + cy, and pixel (column i, row j) is centred on (u, v) = (i, j).
struct CameraIntrinsics {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;

  // Square pixels, principal point at the image centre ((width - 1) / 2, (height - 1) / 2) and
  // the horizontal field of view across the whole width: fx = fy = (width / 2) / tan(fov / 2).
  static CameraIntrinsics fromFov(int width, int height, double horizontalFovDegrees);
  // Throws std::invalid_argument "field: what is wrong" for a size below one pixel, a focal length
  // that is not positive or a principal point outside the image.
  void validate() const;
};

// The pose of a camera at `position` looking at `target`, with `up` (scene frame) pointing up in
// the image: camera -> scene, x_scene = R x_camera + position. The camera looks along its +z axis,
// x to the right of the image, y down (OpenCV, RealSense). Throws std::invalid_argument when the
// target is the position or `up` is parallel to the viewing direction.
RigidTransform lookAtPose(const Eigen::Vector3d& position, const Eigen::Vector3d& target, const Eigen::Vector3d& up);

// What the camera may see, in the scene frame. A label names the object in the image (>= 0).
struct SurfaceInput {
  const Eigen::Matrix3Xd* points = nullptr;  // 3 x #points, not owned
  const TriangleList* triangles = nullptr;   // 3 x #triangles, indices into points; either orientation
  int label = 0;
};
struct SphereInput {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0;
  int label = 0;
};
// The infinite plane normal . x = offset (a table under the specimen).
struct PlaneInput {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double offset = 0;
  int label = 0;
};
struct RenderInput {
  std::vector<SurfaceInput> surfaces;
  std::vector<SphereInput> spheres;
  std::optional<PlaneInput> plane;
};

// One rendered frame: per pixel, row-major (index = row * width + column).
struct DepthImage {
  int width = 0, height = 0;
  std::vector<double> depth;        // z (camera frame) of the first surface along the pixel's ray; +inf if none
  std::vector<int> label;           // label of that surface; -1 if none or if its depth is out of range
  std::vector<float> cosIncidence;  // |cos| of the angle between the ray and the surface normal there

  int index(int column, int row) const { return row * width + column; }
  bool hit(int pixel) const { return label[static_cast<size_t>(pixel)] >= 0; }
  // Pixels showing the object `l`.
  int count(int l) const;
};

// The measurement model applied to a rendered image, pixel by pixel (lengths in the scene's unit):
//  1. dropout: a pixel gives no point with probability `dropout`, independently of the others,
//     and always when the angle between its ray and the surface normal exceeds `grazingAngle`
//     (structured light returns too little of its pattern from surfaces seen edge-on);
//  2. depth noise: z_measured = z + sigma(z) n with n ~ N(0, 1) and
//         sigma(z) = sigma0 (z / z0)^2,
//     since the depth error of triangulation (structured light, stereo) grows with the square of
//     the distance. The point stays on its pixel's ray: it moves along the ray, by
//     (z_measured - z) |ray| with ray = (x / z, y / z, 1);
//  3. quantisation: z_measured is rounded to a multiple of `depthUnit` (0: not quantised), the
//     unit of the sensor's 16-bit depth values (the SR300 reports 1/8 mm).
// The random numbers are a counter-based hash of (seed, frame index, pixel): frame k is the same
// whatever frames were rendered before it, and pixels do not share random numbers.
struct DepthNoise {
  double sigma0 = 0;              // depth standard deviation at z0 (0: no noise)
  double z0 = 1;                  // working distance at which the standard deviation is sigma0
  double dropout = 0;             // probability, in [0, 1)
  double grazingAngleDeg = 90;    // largest angle of incidence giving a point, degrees in (0, 90]
  double depthUnit = 0;           // quantisation step of the depth (0: none)
  std::uint64_t seed = 1;

  // sigma(z) as above.
  double sigma(double z) const { return sigma0 * (z / z0) * (z / z0); }
  // Throws std::invalid_argument "field: what is wrong" for values out of range.
  void validate() const;
};

enum class PointFrame { Camera, Scene };

struct CaptureOptions {
  int stride = 1;                         // keep every stride-th column of every stride-th row
  PointFrame frame = PointFrame::Camera;  // camera frame (as a real sensor) or scene frame
  std::vector<int> labels;                // keep only points on these objects (empty: all)
};

// A frame's points with, per point, the label of the object hit and the pixel index.
struct Capture {
  cloud::PointCloud cloud;  // 3 x n
  std::vector<int> labels;  // n
  std::vector<int> pixels;  // n
};

class DepthCamera {
 public:
  // Sees depths (z along the optical axis) in [minDepth, maxDepth]. A surface nearer than
  // minDepth hides what lies behind it but gives no depth, as the minimum range of a real sensor.
  // Throws std::invalid_argument ("field: what is wrong") for invalid intrinsics or a range
  // other than 0 < minDepth < maxDepth.
  DepthCamera(const CameraIntrinsics& intrinsics, const RigidTransform& cameraToScene, double minDepth, double maxDepth);

  const CameraIntrinsics& intrinsics() const { return k_; }
  const RigidTransform& pose() const { return pose_; }
  double minDepth() const { return minDepth_; }
  double maxDepth() const { return maxDepth_; }
  // The ray through the centre of pixel (column, row) in the camera frame, scaled to z = 1: the
  // point at depth z on it is z * ray.
  Eigen::Vector3d ray(int column, int row) const { return {xs_[column], ys_[row], 1.0}; }

  // Renders the first hit of every pixel's ray into `image`, whose buffers are reused.
  void render(const RenderInput& input, DepthImage& image) const;
  // The points of a rendered image, with the noise of frame `frameIndex`. The cloud's time is 0.
  Capture capture(const DepthImage& image, const DepthNoise& noise, std::uint64_t frameIndex,
                  const CaptureOptions& options = {}) const;

 private:
  void rasteriseSurface(const SurfaceInput& s, DepthImage& image) const;
  void rasteriseSphere(const SphereInput& s, DepthImage& image) const;
  void rasterisePlane(const PlaneInput& p, DepthImage& image) const;

  CameraIntrinsics k_;
  RigidTransform pose_;
  RigidTransform sceneToCamera_;
  double minDepth_, maxDepth_;
  std::vector<double> xs_, ys_;  // ray coordinates of the pixel columns and rows: (i - cx) / fx, (j - cy) / fy
};

// The generalized winding number of a closed triangle surface at p: the solid angles of its
// triangles seen from p summed over 4 pi. +1 inside an outward-oriented surface (-1 inside an
// inward-oriented one), 0 outside.
double windingNumber(const Eigen::Matrix3Xd& points, const TriangleList& triangles, const Eigen::Vector3d& p);

}  // namespace viscera::obs
