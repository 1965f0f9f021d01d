// The depth renderer against analytic answers: exact depths of planes, spheres and the phantom
// box, pixel coverage, occlusion by the instrument sphere, the near/far range, triangles that cross
// the camera's plane, and the camera pose and intrinsics conventions.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "tests/observation/camera/camera_helpers.h"

using namespace viscera;
using namespace viscera::obs;
using namespace camera_test;

namespace {

// A camera at (0, 0, distance) looking down the scene's -z at the origin, scene y up in the image:
// camera x = scene x, camera y = -scene y, camera z = -scene z.
DepthCamera headOn(const CameraIntrinsics& k, double distance, double nearDepth = 1, double farDepth = 1e4) {
  return DepthCamera(k, lookAtPose({0, 0, distance}, {0, 0, 0}, {0, 1, 0}), nearDepth, farDepth);
}

// The scene-frame direction of pixel (i, j) of the head-on camera, from the intrinsics alone.
Eigen::Vector3d headOnRay(const CameraIntrinsics& k, int i, int j) {
  return {(i - k.cx) / k.fx, -(j - k.cy) / k.fy, -1.0};
}

TEST(DepthCameraPose, LookAtFollowsTheOpenCvConvention) {
  const RigidTransform T = lookAtPose({0, 0, 10}, {0, 0, 0}, {0, 1, 0});
  // Looking down -z with y up: x right = +x, y down = -y, z forward = -z (exact for these axes).
  EXPECT_EQ(T.linear().col(0), Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(T.linear().col(1), Eigen::Vector3d(0, -1, 0));
  EXPECT_EQ(T.linear().col(2), Eigen::Vector3d(0, 0, -1));
  EXPECT_EQ(T.translation(), Eigen::Vector3d(0, 0, 10));

  // Oblique: the target projects on the principal point, `up` upwards (v < cy) and view x up to the
  // right (u > cx). Rotation orthonormal with det +1 to rounding (1e-12).
  const Eigen::Vector3d pos(34, -300, 300), target(34, 18, 20), up(0, 0, 1);
  const RigidTransform P = lookAtPose(pos, target, up);
  EXPECT_NEAR((P.linear().transpose() * P.linear() - Eigen::Matrix3d::Identity()).norm(), 0, 1e-12);
  EXPECT_NEAR(P.linear().determinant(), 1, 1e-12);
  const RigidTransform toCamera = P.inverse();
  const Eigen::Vector3d t = toCamera * target;
  EXPECT_NEAR(t.x(), 0, 1e-9);
  EXPECT_NEAR(t.y(), 0, 1e-9);
  EXPECT_NEAR(t.z(), (target - pos).norm(), 1e-9);
  EXPECT_LT((toCamera * (target + up)).y(), 0);
  const Eigen::Vector3d right = (target - pos).cross(up);
  EXPECT_GT((toCamera * (target + right.normalized())).x(), 0);
}

TEST(DepthCameraPose, RejectsDegenerateViews) {
  EXPECT_THROW(lookAtPose({1, 2, 3}, {1, 2, 3}, {0, 0, 1}), std::invalid_argument);
  try {
    lookAtPose({0, 0, 100}, {0, 0, 0}, {0, 0, 1});  // straight down with up along the view
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("up: ", 0), 0u) << e.what();
  }
}

TEST(DepthCameraIntrinsics, FieldOfViewSpansTheImage) {
  const CameraIntrinsics k = CameraIntrinsics::fromFov(640, 480, 60);
  // A ray at half the field of view, 30 degrees, meets the right edge of the last pixel (u = 639.5).
  EXPECT_NEAR(k.fx * std::tan(M_PI / 6) + k.cx, 639.5, 1e-9);
  EXPECT_EQ(k.fx, k.fy);
  EXPECT_EQ(k.cx, 319.5);
  EXPECT_EQ(k.cy, 239.5);
  EXPECT_THROW(CameraIntrinsics::fromFov(640, 480, 0), std::invalid_argument);
  EXPECT_THROW(CameraIntrinsics::fromFov(640, 480, 180), std::invalid_argument);
  CameraIntrinsics bad = k;
  bad.cx = 700;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  bad = k;
  bad.fy = 0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  EXPECT_THROW(DepthCamera(k, RigidTransform::Identity(), 10, 10), std::invalid_argument);
  EXPECT_THROW(DepthCamera(k, RigidTransform::Identity(), 0, 10), std::invalid_argument);
}

TEST(DepthCameraRender, PlaneHeadOnHasExactDepthAndCoverage) {
  const CameraIntrinsics k = CameraIntrinsics::fromFov(80, 60, 50);
  const double D = 123.4;
  const DepthCamera cam = headOn(k, D);
  // Edges chosen so that no pixel centre lies on them.
  const double x0 = -21.3, x1 = 17.9, y0 = -11.7, y1 = 14.2;
  for (bool flip : {false, true}) {
    const Rectangle rect(x0, x1, y0, y1, 0.0, flip);
    RenderInput in;
    in.surfaces.push_back({&rect.points, &rect.triangles, 3});
    DepthImage img;
    cam.render(in, img);
    // Pixel centres inside the projected rectangle: x in [x0, x1] is u in [cx + fx x0 / D, cx + fx x1 / D];
    // scene y is -camera y, so y in [y0, y1] is v in [cy - fy y1 / D, cy - fy y0 / D].
    const double u0 = k.cx + k.fx * x0 / D, u1 = k.cx + k.fx * x1 / D;
    const double v0 = k.cy - k.fy * y1 / D, v1 = k.cy - k.fy * y0 / D;
    int expected = 0;
    for (int j = 0; j < k.height; ++j)
      for (int i = 0; i < k.width; ++i) {
        const bool inside = i >= u0 && i <= u1 && j >= v0 && j <= v1;
        expected += inside;
        const int p = img.index(i, j);
        ASSERT_EQ(img.hit(p), inside) << "pixel " << i << "," << j << " flip " << flip;
        if (!inside) continue;
        EXPECT_EQ(img.label[p], 3);
        // Exact to rounding: the plane's depth is D for every ray.
        EXPECT_NEAR(img.depth[p], D, 1e-12 * D);
        EXPECT_NEAR(img.cosIncidence[p], 1.0 / headOnRay(k, i, j).norm(), 1e-6);  // float storage
      }
    EXPECT_EQ(img.count(3), expected);
    // And the projected area in pixels, to within the pixels along its edges.
    const double area = (u1 - u0) * (v1 - v0);
    EXPECT_NEAR(expected, area, (u1 - u0) + (v1 - v0) + 1);
    EXPECT_GT(expected, 300);
  }
}

TEST(DepthCameraRender, TablePlaneHeadOnFillsTheImage) {
  const CameraIntrinsics k = CameraIntrinsics::fromFov(40, 30, 70);
  const DepthCamera cam = headOn(k, 250);
  RenderInput in;
  in.plane = PlaneInput{Eigen::Vector3d(0, 0, 2), 0.0, 0};  // z = 0, normal not unit
  DepthImage img;
  cam.render(in, img);
  for (size_t p = 0; p < img.depth.size(); ++p) {
    ASSERT_EQ(img.label[p], 0);
    EXPECT_NEAR(img.depth[p], 250, 1e-12 * 250);
  }
}

TEST(DepthCameraRender, SphereDepthIsTheAnalyticIntersection) {
  const CameraIntrinsics k = CameraIntrinsics::fromFov(64, 48, 30);
  const double D = 60;
  const DepthCamera cam = headOn(k, D);
  const Eigen::Vector3d c(3, -2, 1), o(0, 0, D);
  const double r = 6;
  RenderInput in;
  in.spheres.push_back({c, r, 1});
  DepthImage img;
  cam.render(in, img);
  int hits = 0;
  for (int j = 0; j < k.height; ++j)
    for (int i = 0; i < k.width; ++i) {
      const Eigen::Vector3d d = headOnRay(k, i, j);
      const SphereCrossing s = sphereCrossing(o, d, c, r);
      if (std::abs(s.distance - r) < 1e-9) continue;  // ray tangent to the sphere: either answer is right
      const int p = img.index(i, j);
      ASSERT_EQ(img.hit(p), s.t.has_value()) << "pixel " << i << "," << j;
      if (!s.t) continue;
      ++hits;
      // d has camera z = 1, so the line parameter is the depth; relative 1e-12 covers the roundings.
      EXPECT_NEAR(img.depth[p], *s.t, 1e-12 * D);
      // The hit point lies on the sphere, on its near side.
      const Eigen::Vector3d hit = o + img.depth[p] * d;
      EXPECT_NEAR((hit - c).norm(), r, 1e-9);
      EXPECT_LT((hit - c).dot(d), 0);
    }
  EXPECT_GT(hits, 200);
}

struct ObliqueView {
  CameraIntrinsics k = CameraIntrinsics::fromFov(320, 240, 40);
  Eigen::Vector3d position{34, -150, 250};
  DepthCamera cam{k, lookAtPose(position, Phantom().centre(), {0, 0, 1}), 1, 1000};
  // Scene-frame direction of pixel (i, j), with camera z = 1.
  Eigen::Vector3d ray(int i, int j) const { return cam.pose().linear() * cam.ray(i, j); }
};

TEST(DepthCameraRender, PhantomDepthIsTheBoxIntersection) {
  const Phantom phantom;
  const ObliqueView v;
  RenderInput in;
  in.surfaces.push_back({&phantom.points, &phantom.triangles, 0});
  DepthImage img;
  v.cam.render(in, img);
  int hits = 0;
  for (int j = 0; j < v.k.height; ++j)
    for (int i = 0; i < v.k.width; ++i) {
      const auto box = boxInterval(v.position, v.ray(i, j), phantom.lo, phantom.hi);
      if (box && box->second - box->first < 1e-6) continue;  // grazes an edge of the box
      const int p = img.index(i, j);
      ASSERT_EQ(img.hit(p), box.has_value()) << "pixel " << i << "," << j;
      if (!box) continue;
      ++hits;
      EXPECT_NEAR(img.depth[p], box->first, 1e-9 * box->first);
    }
  EXPECT_GT(hits, 8000);
}

TEST(DepthCameraRender, SphereHidesExactlyTheTissueBehindIt) {
  const Phantom phantom;
  const ObliqueView v;
  // The instrument 8 mm above the top face, between it and the camera.
  const Eigen::Vector3d c(30, 20, 39.3 + 8);
  const double r = 5;
  RenderInput tissueOnly;
  tissueOnly.surfaces.push_back({&phantom.points, &phantom.triangles, 0});
  RenderInput both = tissueOnly;
  both.spheres.push_back({c, r, 1});
  DepthImage alone, occluded;
  v.cam.render(tissueOnly, alone);
  v.cam.render(both, occluded);
  int hidden = 0, sphere = 0;
  for (int j = 0; j < v.k.height; ++j)
    for (int i = 0; i < v.k.width; ++i) {
      const int p = v.k.width * j + i;
      const SphereCrossing s = sphereCrossing(v.position, v.ray(i, j), c, r);
      if (std::abs(s.distance - r) < 1e-9) continue;
      const bool sphereFirst = s.t && (!alone.hit(p) || *s.t < alone.depth[p]);
      if (sphereFirst) {
        ++sphere;
        ASSERT_EQ(occluded.label[p], 1) << "pixel " << i << "," << j;
        EXPECT_NEAR(occluded.depth[p], *s.t, 1e-9 * *s.t);
        hidden += alone.hit(p);
      } else {
        // No tissue pixel whose ray meets the sphere first survives; all others are unchanged.
        ASSERT_EQ(occluded.label[p], alone.label[p]) << "pixel " << i << "," << j;
        if (alone.hit(p)) {
          EXPECT_EQ(occluded.depth[p], alone.depth[p]);
        }
      }
    }
  EXPECT_EQ(occluded.count(0), alone.count(0) - hidden);
  EXPECT_GT(hidden, 100);  // the test is not vacuous
  EXPECT_GE(sphere, hidden);
}

TEST(DepthCameraRender, NearSurfaceHidesWithoutDepthAndFarIsCut) {
  const CameraIntrinsics k = CameraIntrinsics::fromFov(40, 30, 60);
  const DepthCamera cam = headOn(k, 100, 20, 150);
  const Rectangle close(-1, 1, -1, 1, 95);  // depth 5, nearer than 20
  RenderInput in;
  in.surfaces.push_back({&close.points, &close.triangles, 0});
  in.plane = PlaneInput{Eigen::Vector3d(0, 0, 1), 0, 1};  // depth 100
  DepthImage img;
  cam.render(in, img);
  int blind = 0;
  for (int j = 0; j < k.height; ++j)
    for (int i = 0; i < k.width; ++i) {
      const Eigen::Vector3d d = headOnRay(k, i, j) * 5;  // at the rectangle's depth
      const bool behindClose = std::abs(d.x()) <= 1 && std::abs(d.y()) <= 1;
      const int p = img.index(i, j);
      EXPECT_EQ(img.label[p], behindClose ? -1 : 1) << i << "," << j;
      blind += behindClose;
    }
  EXPECT_GT(blind, 10);
  // A plane beyond `far` is not seen at all.
  const DepthCamera shortRange = headOn(k, 100, 20, 90);
  RenderInput planeOnly;
  planeOnly.plane = PlaneInput{Eigen::Vector3d(0, 0, 1), 0, 1};
  shortRange.render(planeOnly, img);
  EXPECT_EQ(img.count(1), 0);
}

TEST(DepthCameraRender, TrianglesCrossingTheCameraPlaneAreClipped) {
  // A 400 x 400 floor seen from 10 above its middle, looking ahead and down: both triangles reach
  // behind the camera. Where the infinite plane's hit lies on the floor, the depths agree.
  const CameraIntrinsics k = CameraIntrinsics::fromFov(64, 48, 90);
  const DepthCamera cam(k, lookAtPose({0, 0, 10}, {50, 0, 0}, {0, 0, 1}), 0.5, 1e4);
  const Rectangle floor(-200, 200, -200, 200, 0);
  RenderInput surface, plane;
  surface.surfaces.push_back({&floor.points, &floor.triangles, 0});
  plane.plane = PlaneInput{Eigen::Vector3d(0, 0, 1), 0, 0};
  DepthImage a, b;
  cam.render(surface, a);
  cam.render(plane, b);
  int onFloor = 0;
  for (int j = 0; j < k.height; ++j)
    for (int i = 0; i < k.width; ++i) {
      const int p = a.index(i, j);
      if (!b.hit(p)) {
        EXPECT_FALSE(a.hit(p));
        continue;
      }
      const Eigen::Vector3d hit = cam.pose() * (b.depth[p] * cam.ray(i, j));
      const double margin = 200 - std::max(std::abs(hit.x()), std::abs(hit.y()));
      if (std::abs(margin) < 1e-6) continue;
      ASSERT_EQ(a.hit(p), margin > 0) << i << "," << j;
      if (margin > 0) {
        ++onFloor;
        EXPECT_NEAR(a.depth[p], b.depth[p], 1e-9 * b.depth[p]);
      }
    }
  EXPECT_GT(onFloor, 500);
}

TEST(DepthCameraRender, WindingNumberTellsInsideFromOutside) {
  const Phantom phantom({7, 4, 4});
  EXPECT_NEAR(windingNumber(phantom.points, phantom.triangles, phantom.centre()), 1.0, 1e-9);
  EXPECT_NEAR(windingNumber(phantom.points, phantom.triangles, {34, -300, 300}), 0.0, 1e-9);
  TriangleList flipped = phantom.triangles;
  flipped.row(1).swap(flipped.row(2));
  EXPECT_NEAR(windingNumber(phantom.points, flipped, phantom.centre()), -1.0, 1e-9);
}

}  // namespace
