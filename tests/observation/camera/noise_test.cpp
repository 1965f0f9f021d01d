// The measurement model against its definition: the depth noise's mean and standard deviation at
// two distances (the z^2 law), the dropout rate, grazing-angle dropout, quantisation, frames that
// do not depend on one another, stride, output frames and label filtering; and a noisy cloud of
// the phantom that lies on its surface on average.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <set>

#include "tests/observation/camera/camera_helpers.h"

using namespace viscera;
using namespace viscera::obs;
using namespace camera_test;

namespace {

// 160 x 120 pixels (19200 samples per frame) looking head-on at the plane z = 0 from (0, 0, D),
// or at a plane through the origin with `normal`.
struct PlaneShot {
  CameraIntrinsics k = CameraIntrinsics::fromFov(160, 120, 60);
  DepthCamera cam;
  DepthImage img;
  PlaneShot(double D, const Eigen::Vector3d& normal = Eigen::Vector3d::UnitZ())
      : cam(k, lookAtPose({0, 0, D}, {0, 0, 0}, {0, 1, 0}), 1, 1e4) {
    RenderInput in;
    in.plane = PlaneInput{normal, 0.0, 0};
    cam.render(in, img);
  }
};

struct Stats {
  double mean = 0, sd = 0;
  int n = 0;
};

// Depth residuals z_measured - z along each point's ray (camera frame, no quantisation).
Stats depthResiduals(const PlaneShot& s, const Capture& c) {
  Stats st;
  double sum = 0, sum2 = 0;
  for (int q = 0; q < c.cloud.size(); ++q) {
    const Eigen::Vector3d p = c.cloud.points.col(q);
    const int pixel = c.pixels[static_cast<size_t>(q)];
    const Eigen::Vector3d ray = s.cam.ray(pixel % s.k.width, pixel / s.k.width);
    // The point stays on its pixel's ray: only its depth is measured with error.
    EXPECT_NEAR((p - p.z() * ray).norm(), 0, 1e-9 * p.z());
    const double r = p.z() - s.img.depth[static_cast<size_t>(pixel)];
    sum += r;
    sum2 += r * r;
  }
  st.n = c.cloud.size();
  st.mean = sum / st.n;
  st.sd = std::sqrt((sum2 - sum * st.mean) / (st.n - 1));
  return st;
}

TEST(DepthCameraNoise, DepthErrorGrowsWithTheSquareOfTheDistance) {
  DepthNoise noise;
  noise.sigma0 = 2;
  noise.z0 = 400;
  noise.seed = 11;
  double sd[2];
  const double distances[2] = {300, 600};
  for (int d = 0; d < 2; ++d) {
    const PlaneShot shot(distances[d]);
    const Capture c = shot.cam.capture(shot.img, noise, 0);
    ASSERT_EQ(c.cloud.size(), 160 * 120);
    const Stats st = depthResiduals(shot, c);
    const double sigma = 2 * std::pow(distances[d] / 400, 2);  // 1.125 mm at 300, 4.5 mm at 600
    std::cout << "z = " << distances[d] << ": mean " << st.mean << ", sd " << st.sd << " (sigma " << sigma << ")\n";
    // The mean's standard error is sigma / sqrt(n) (n = 19200); 4 of them.
    EXPECT_NEAR(st.mean, 0, 4 * sigma / std::sqrt(st.n));
    // The sample sd's relative standard error is 1 / sqrt(2 n) = 0.5 %; 3 % is six of them.
    EXPECT_NEAR(st.sd / sigma, 1, 0.03);
    sd[d] = st.sd;
  }
  // Twice the distance, four times the error (same 3 % per measurement, compounded).
  EXPECT_NEAR(sd[1] / sd[0], 4, 4 * 0.06);
}

TEST(DepthCameraNoise, DropoutRateIsBinomial) {
  const PlaneShot shot(300);
  DepthNoise noise;
  noise.dropout = 0.1;
  noise.seed = 5;
  const int n = 160 * 120;
  std::vector<std::set<int>> kept;
  for (std::uint64_t frame : {0u, 1u, 2u}) {
    const Capture c = shot.cam.capture(shot.img, noise, frame);
    // Kept ~ Binomial(n, 0.9): mean 17280, sd sqrt(n 0.9 0.1) = 41.6; 4 sd.
    const double sd = std::sqrt(n * 0.9 * 0.1);
    std::cout << "frame " << frame << ": kept " << c.cloud.size() << " of " << n << "\n";
    EXPECT_NEAR(c.cloud.size(), 0.9 * n, 4 * sd);
    kept.emplace_back(c.pixels.begin(), c.pixels.end());
  }
  // Frames drop independently: a pixel is missing from frames 0 and 1 with probability 0.01,
  // Binomial(n, 0.01): mean 192, sd 13.8; 4 sd.
  int both = 0;
  for (int p = 0; p < n; ++p) both += !kept[0].count(p) && !kept[1].count(p);
  std::cout << "dropped in frames 0 and 1: " << both << "\n";
  EXPECT_NEAR(both, 0.01 * n, 4 * std::sqrt(n * 0.01 * 0.99));
}

TEST(DepthCameraNoise, GrazingRaysGiveNoPoint) {
  // A plane tilted 60 degrees from the view: incidence angles run from about 30 to 90 degrees
  // across the image. With a 60 degree limit exactly the pixels seen within 60 degrees remain.
  const Eigen::Vector3d n(std::sin(M_PI / 3), 0, std::cos(M_PI / 3));
  const PlaneShot shot(300, n);
  DepthNoise noise;
  noise.grazingAngleDeg = 60;
  const Capture c = shot.cam.capture(shot.img, noise, 0);
  std::set<int> kept(c.pixels.begin(), c.pixels.end());
  int expected = 0;
  for (int j = 0; j < shot.k.height; ++j)
    for (int i = 0; i < shot.k.width; ++i) {
      const int p = shot.img.index(i, j);
      if (!shot.img.hit(p)) continue;
      // Scene-frame ray of the head-on camera (camera y = -scene y, camera z = -scene z).
      const Eigen::Vector3d d((i - shot.k.cx) / shot.k.fx, -(j - shot.k.cy) / shot.k.fy, -1);
      const double cosine = std::abs(n.dot(d)) / d.norm();
      if (std::abs(cosine - 0.5) < 1e-5) continue;  // on the limit, to float precision
      EXPECT_EQ(kept.count(p) == 1, cosine > 0.5) << i << "," << j;
      expected += cosine > 0.5;
    }
  EXPECT_GT(expected, 1000);
  EXPECT_LT(expected, shot.img.count(0) - 1000);
}

TEST(DepthCameraNoise, DepthsAreQuantised) {
  // Tilted 10 degrees: the depth changes by less than a unit from pixel to pixel.
  const PlaneShot shot(350, Eigen::Vector3d(std::sin(M_PI / 18), 0, std::cos(M_PI / 18)));
  DepthNoise noise;
  noise.depthUnit = 1;
  const Capture c = shot.cam.capture(shot.img, noise, 0);
  std::set<long> levels;
  for (int q = 0; q < c.cloud.size(); ++q) {
    const double z = c.cloud.points(2, q);
    EXPECT_NEAR(z, std::round(z), 1e-9);  // a whole number of units
    EXPECT_LE(std::abs(z - shot.img.depth[static_cast<size_t>(c.pixels[static_cast<size_t>(q)])]), 0.5 + 1e-9);
    levels.insert(std::lround(z));
  }
  // The tilted plane spans many levels, one unit apart, none missing.
  EXPECT_GT(levels.size(), 30u);
  EXPECT_EQ(static_cast<long>(levels.size()), *levels.rbegin() - *levels.begin() + 1);
}

TEST(DepthCameraNoise, FrameKDependsOnlyOnSeedAndK) {
  const PlaneShot shot(400);
  DepthNoise noise;
  noise.sigma0 = 2;
  noise.z0 = 400;
  noise.dropout = 0.05;
  noise.depthUnit = 0.125;
  noise.seed = 3;
  const Capture direct = shot.cam.capture(shot.img, noise, 7);
  // Another camera object that renders frames 0 to 6 first gives the same frame 7.
  const PlaneShot other(400);
  for (std::uint64_t f = 0; f < 7; ++f) other.cam.capture(other.img, noise, f);
  const Capture afterOthers = other.cam.capture(other.img, noise, 7);
  EXPECT_EQ(direct.pixels, afterOthers.pixels);
  EXPECT_EQ(direct.cloud.points, afterOthers.cloud.points);
  // Another frame, or another seed, is another draw.
  const Capture next = shot.cam.capture(shot.img, noise, 8);
  EXPECT_NE(direct.pixels, next.pixels);
  noise.seed = 4;
  const Capture reseeded = shot.cam.capture(shot.img, noise, 7);
  EXPECT_NE(direct.pixels, reseeded.pixels);
}

TEST(DepthCameraNoise, StrideFrameAndLabels) {
  PlaneShot shot(200);
  DepthNoise none;
  CaptureOptions every4;
  every4.stride = 4;
  const Capture sparse = shot.cam.capture(shot.img, none, 0, every4);
  EXPECT_EQ(sparse.cloud.size(), (160 / 4) * (120 / 4));
  for (int p : sparse.pixels) {
    EXPECT_EQ(p % 160 % 4, 0);
    EXPECT_EQ(p / 160 % 4, 0);
  }
  // Camera frame: depth 200 along +z; scene frame: on the plane z = 0 (rounding only).
  const Capture inCamera = shot.cam.capture(shot.img, none, 0);
  CaptureOptions sceneFrame;
  sceneFrame.frame = PointFrame::Scene;
  const Capture inScene = shot.cam.capture(shot.img, none, 0, sceneFrame);
  for (int q = 0; q < inCamera.cloud.size(); ++q) {
    EXPECT_NEAR(inCamera.cloud.points(2, q), 200, 1e-9);
    EXPECT_NEAR(inScene.cloud.points(2, q), 0, 1e-9);
  }
  // Only the labels asked for: a sphere in front of the plane, plane points only.
  RenderInput in;
  in.plane = PlaneInput{Eigen::Vector3d::UnitZ(), 0.0, 0};
  in.spheres.push_back({Eigen::Vector3d(0, 0, 50), 20, 1});
  shot.cam.render(in, shot.img);
  CaptureOptions planeOnly;
  planeOnly.labels = {0};
  const Capture c = shot.cam.capture(shot.img, none, 0, planeOnly);
  EXPECT_EQ(c.cloud.size(), shot.img.count(0));
  EXPECT_GT(shot.img.count(1), 100);
  for (int l : c.labels) EXPECT_EQ(l, 0);
}

// Distance from a point on the surface of the box [lo, hi] to the nearest edge of the box.
double distanceToEdge(const Eigen::Vector3d& q, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const Eigen::Vector3d inside = (q - lo).cwiseMin(hi - q);  // the face's own axis is ~0
  int face;
  inside.minCoeff(&face);
  double d = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a)
    if (a != face) d = std::min(d, inside[a]);
  return d;
}

TEST(DepthCameraNoise, PhantomCloudLiesOnItsSurfaceOnAverage) {
  // The setup of the gel phantom: the 25 x 9 x 9 phantom seen from 400 mm, 40 degrees from the
  // vertical, by a 640 x 480 camera with the default RealSense-like noise.
  const Phantom phantom;
  const Eigen::Vector3d target = phantom.centre();
  const Eigen::Vector3d position = target + 400 * Eigen::Vector3d(0, -std::sin(0.7), std::cos(0.7));
  const DepthCamera cam(CameraIntrinsics::fromFov(640, 480, 60), lookAtPose(position, target, {0, 0, 1}), 200, 1500);
  RenderInput in;
  in.surfaces.push_back({&phantom.points, &phantom.triangles, 0});
  DepthImage img;
  cam.render(in, img);
  CaptureOptions options;
  options.frame = PointFrame::Scene;
  const SurfaceIndex index(phantom.points, phantom.triangles);
  auto signedDistance = [&](const Eigen::Vector3d& p) {
    const SurfaceIndex::Hit h = index.closest(p);
    return (p - h.point).dot(index.normal(h.triangle));  // > 0 outside
  };

  // Without noise every point is on the surface.
  const Capture exact = cam.capture(img, DepthNoise{}, 0, options);
  for (int q = 0; q < exact.cloud.size(); ++q) ASSERT_NEAR(signedDistance(exact.cloud.points.col(q)), 0, 1e-9);

  DepthNoise noise;
  noise.sigma0 = 2;
  noise.z0 = 400;
  noise.dropout = 0.01;
  noise.grazingAngleDeg = 80;
  noise.depthUnit = 0.125;
  noise.seed = 1;
  const Capture c = cam.capture(img, noise, 0, options);
  // Near the box's convex edges the distance to the surface is not the noise along the normal
  // (a point pushed inside may be nearer the neighbouring face), which biases it outwards. The
  // points whose noise-free position is 8 mm (4 sigma) or more from every edge measure the
  // noise alone; which points those are does not depend on the noise.
  double sum = 0, sum2 = 0, sumAll = 0;
  int n = 0;
  for (int q = 0; q < c.cloud.size(); ++q) {
    const int pixel = c.pixels[static_cast<size_t>(q)];
    const Eigen::Vector3d truth =
        cam.pose() * (img.depth[static_cast<size_t>(pixel)] * cam.ray(pixel % img.width, pixel / img.width));
    const double d = signedDistance(c.cloud.points.col(q));
    sumAll += d;
    if (distanceToEdge(truth, phantom.lo, phantom.hi) < 8) continue;
    sum += d;
    sum2 += d * d;
    ++n;
  }
  const double mean = sum / n, sd = std::sqrt((sum2 - sum * mean) / (n - 1));
  std::cout << c.cloud.size() << " points: signed distance mean " << sumAll / c.cloud.size() << " mm; " << n
            << " away from the edges: mean " << mean << " mm, sd " << sd << " mm\n";
  EXPECT_GT(n, 3000);
  // Noise along the normal is at most sigma(z) |ray| ~ 2 mm at 400 mm.
  EXPECT_GT(sd, 0.5);
  EXPECT_LT(sd, 2.5);
  // Unbiased: within 4 standard errors of the mean (sd / sqrt(n), ~0.02 mm).
  EXPECT_NEAR(mean, 0, 4 * sd / std::sqrt(n));
}

}  // namespace
