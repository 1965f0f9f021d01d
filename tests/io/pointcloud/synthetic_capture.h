// A synthetic depth-camera capture of the gel phantom on a table, built with a fixed seed: a table
// (400 x 300 mm, 1 mm jitter normal to it), the phantom (the top and two visible side faces of a
// 68.7 x 35.8 x 39.3 mm box standing on the table, 0.5 mm noise), an instrument (a 5 mm sphere on
// a 3 mm shaft, 8 mm above the phantom's top: more than the 4 mm cluster tolerance away) and
// uniformly scattered outliers. Points are in the camera's frame (millimetres); the camera looks
// down at the phantom from about 400 mm, as in the recorded captures.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "io/pointcloud/PointCloud.h"

namespace viscera_test {

struct SyntheticCapture {
  viscera::cloud::PointCloud cloud;  // camera frame
  // world -> camera: p_camera = rotation * p_world + translation. The table is the world's z = 0
  // plane, z up; the phantom's box spans boxMin .. boxMax.
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  Eigen::Vector3d boxMin{-34.35, -17.9, 0.0}, boxMax{34.35, 17.9, 39.3};

  Eigen::Vector3d toWorld(const Eigen::Vector3d& p) const { return rotation.transpose() * (p - translation); }

  // Distance of a world point to the surface of the phantom's box (inside or outside).
  double boxSurfaceDistance(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d below = boxMin - p, above = p - boxMax;
    const Eigen::Vector3d outside = below.cwiseMax(above).cwiseMax(0.0);
    if (outside.squaredNorm() > 0) return outside.norm();
    return (-below).cwiseMin(-above).minCoeff();  // inside: distance to the nearest face
  }
};

inline SyntheticCapture makeCapture(unsigned seed = 7) {
  SyntheticCapture c;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto uniform = [&](double a, double b) { return a + (b - a) * unit(rng); };
  std::vector<Eigen::Vector3d> world;

  // Table: 0.25 points / mm^2 (2 mm spacing), none under the phantom.
  for (int i = 0; i < 30000; ++i) {
    const Eigen::Vector3d p(uniform(-200, 200), uniform(-150, 150), uniform(-1, 1));
    if (p.x() > c.boxMin.x() && p.x() < c.boxMax.x() && p.y() > c.boxMin.y() && p.y() < c.boxMax.y()) continue;
    world.push_back(p);
  }
  // Phantom: 2 points / mm^2 on the faces the camera sees (top, x = min, y = min).
  const Eigen::Vector3d lo = c.boxMin, hi = c.boxMax, size = hi - lo;
  auto face = [&](int count, auto point) {
    for (int i = 0; i < count; ++i) world.push_back(point(unit(rng), unit(rng), uniform(-0.5, 0.5)));
  };
  face(static_cast<int>(2 * size.x() * size.y()), [&](double u, double v, double n) {
    return Eigen::Vector3d(lo.x() + u * size.x(), lo.y() + v * size.y(), hi.z() + n);
  });
  face(static_cast<int>(2 * size.y() * size.z()), [&](double u, double v, double n) {
    return Eigen::Vector3d(lo.x() + n, lo.y() + u * size.y(), lo.z() + v * size.z());
  });
  face(static_cast<int>(2 * size.x() * size.z()), [&](double u, double v, double n) {
    return Eigen::Vector3d(lo.x() + u * size.x(), lo.y() + n, lo.z() + v * size.z());
  });
  // Instrument: sphere of radius 5 with its lowest point 8 mm above the top face, and a shaft of
  // radius 3 going up 60 mm; 2 points / mm^2, 0.3 mm noise.
  const Eigen::Vector3d centre(0, 0, hi.z() + 8 + 5);
  for (int i = 0; i < 630; ++i) {
    const double z = uniform(-1, 1), phi = uniform(0, 2 * M_PI), r = std::sqrt(1 - z * z);
    world.push_back(centre + (5 + uniform(-0.3, 0.3)) * Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z));
  }
  for (int i = 0; i < 2260; ++i) {
    const double phi = uniform(0, 2 * M_PI), rr = 3 + uniform(-0.3, 0.3);
    world.push_back(centre + Eigen::Vector3d(rr * std::cos(phi), rr * std::sin(phi), 5 + uniform(0, 60)));
  }
  // Outliers: scattered over the volume above the table.
  for (int i = 0; i < 500; ++i) world.emplace_back(uniform(-200, 200), uniform(-150, 150), uniform(0, 150));

  // Camera 400 mm from the phantom's centre, looking down at it from the front left.
  const Eigen::Vector3d target = 0.5 * (lo + hi);
  const Eigen::Vector3d eye = target + 400.0 * Eigen::Vector3d(-0.5, -0.6, 0.62).normalized();
  const Eigen::Vector3d forward = (target - eye).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  c.rotation.row(0) = right;  // camera x right, y down, z forward (the depth cameras' convention)
  c.rotation.row(1) = down;
  c.rotation.row(2) = forward;
  c.translation = -c.rotation * eye;

  c.cloud.points.resize(3, static_cast<Eigen::Index>(world.size()));
  for (size_t i = 0; i < world.size(); ++i) c.cloud.points.col(static_cast<Eigen::Index>(i)) = c.rotation * world[i] + c.translation;
  c.cloud.source = "synthetic capture";
  return c;
}

}  // namespace viscera_test
