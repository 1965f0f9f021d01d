// The gel phantom of the registration tests: a 68.7 x 35.8 x 39.3 mm block meshed as SOFA's
// RegularGridTopology 25 x 9 x 9 split into tetrahedra, and synthetic depth-camera clouds of it.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "observation/SurfaceIndex.h"
#include "engine/topology/GridSplit.h"
#include "io/scene/Transform.h"

namespace registration_test {

const Eigen::Vector3d kLo(0, 0, 0);
const Eigen::Vector3d kHi(68.7, 35.8, 39.3);

struct PhantomMesh {
  Eigen::Matrix3Xd points;  // 3 x 2025
  viscera::TetList tets;    // 4 x 6144
};

inline PhantomMesh phantomMesh() {
  const std::array<int, 3> n = {25, 9, 9};
  PhantomMesh m;
  m.points = viscera::gridPoints(n, kLo, kHi);
  m.tets = viscera::splitHexahedra(viscera::gridHexahedra(n), n[0] - 1, n[1] - 1, true);
  return m;
}

inline viscera::obs::SurfaceIndex phantomSurface() {
  const PhantomMesh m = phantomMesh();
  return viscera::obs::SurfaceIndex(m.points, viscera::obs::boundaryTriangles(m.tets, m.points));
}

// The 8 corners of the block, 3 x 8; the first 4 are the top ones (z = 39.3).
inline Eigen::Matrix3Xd phantomCorners() {
  Eigen::Matrix3Xd c(3, 8);
  c << 0, 68.7, 68.7, 0, 0, 68.7, 68.7, 0,
       0, 0, 35.8, 35.8, 0, 0, 35.8, 35.8,
       39.3, 39.3, 39.3, 39.3, 0, 0, 0, 0;
  return c;
}

// Points spread uniformly at random over an axis-aligned rectangle: `axis` is the constant
// coordinate (at `value`), the two others range over [lo, hi] (their components of lo/hi).
inline void sampleRectangle(std::mt19937& rng, int count, int axis, double value, const Eigen::Vector3d& lo,
                            const Eigen::Vector3d& hi, std::vector<Eigen::Vector3d>& out) {
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < count; ++i) {
    Eigen::Vector3d p;
    for (int a = 0; a < 3; ++a) p[a] = a == axis ? value : lo[a] + u(rng) * (hi[a] - lo[a]);
    out.push_back(p);
  }
}

struct CloudSpec {
  int top = 8000, front = 4400, left = 2300;  // points on z = 39.3, y = 0 and x = 0 (a camera above-left-front)
  double noise = 2.0 / std::sqrt(3.0);       // mm, Gaussian, each axis: a 2 mm RMS displacement
  double outlierFraction = 0.05;             // of the surface points, uniform within 20 mm of the block
  unsigned seed = 7;
};

// A partial cloud of the phantom in the scene frame, 3 x n: the top and two side faces, noisy, with outliers.
inline Eigen::Matrix3Xd phantomCloud(const CloudSpec& s) {
  std::mt19937 rng(s.seed);
  std::vector<Eigen::Vector3d> pts;
  sampleRectangle(rng, s.top, 2, kHi.z(), kLo, kHi, pts);
  sampleRectangle(rng, s.front, 1, kLo.y(), kLo, kHi, pts);
  sampleRectangle(rng, s.left, 0, kLo.x(), kLo, kHi, pts);
  std::normal_distribution<double> g(0, s.noise);
  for (auto& p : pts) p += Eigen::Vector3d(g(rng), g(rng), g(rng));
  const int outliers = static_cast<int>(std::lround(s.outlierFraction * static_cast<double>(pts.size())));
  std::uniform_real_distribution<double> u(0, 1);
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(20);
  for (int i = 0; i < outliers; ++i) {
    Eigen::Vector3d p;
    for (int a = 0; a < 3; ++a) p[a] = kLo[a] - margin[a] + u(rng) * (kHi[a] - kLo[a] + 2 * margin[a]);
    pts.push_back(p);
  }
  Eigen::Matrix3Xd m(3, static_cast<Eigen::Index>(pts.size()));
  for (size_t i = 0; i < pts.size(); ++i) m.col(static_cast<Eigen::Index>(i)) = pts[i];
  return m;
}

// A camera -> scene transform: the camera 0.4 m above-left-front of the block, looking down at it.
inline viscera::RigidTransform cameraToScene() {
  viscera::RigidTransform T = viscera::RigidTransform::Identity();
  T.linear() = (Eigen::AngleAxisd(0.9, Eigen::Vector3d(-1, 1, 0).normalized()) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(-180, -220, 310);
  return T;
}

// `T` disturbed by a rotation of `degrees` about `axis` through the block's centre, then a shift.
inline viscera::RigidTransform perturbed(const viscera::RigidTransform& T, double degrees, const Eigen::Vector3d& axis,
                                         const Eigen::Vector3d& shift) {
  const Eigen::Vector3d c = 0.5 * (kLo + kHi);
  viscera::RigidTransform D = viscera::RigidTransform::Identity();
  D.linear() = Eigen::AngleAxisd(degrees * M_PI / 180, axis.normalized()).toRotationMatrix();
  D.translation() = c + shift - D.linear() * c;
  return D * T;
}

// Angle in degrees of the rotation between two transforms.
inline double angleBetweenDeg(const viscera::RigidTransform& a, const viscera::RigidTransform& b) {
  return Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle() * 180 / M_PI;
}

// The largest distance between where two transforms put the scene's phantom corners, given in
// camera coordinates through `truth` (so the error is measured where the phantom is).
inline double cornerErrorMm(const viscera::RigidTransform& estimate, const viscera::RigidTransform& truth) {
  const Eigen::Matrix3Xd cam = truth.inverse() * phantomCorners();
  return ((estimate * cam) - phantomCorners()).colwise().norm().maxCoeff();
}

}  // namespace registration_test
