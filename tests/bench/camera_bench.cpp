// One frame of the virtual depth camera (observation/DepthCamera.h) on the gel phantom: the
// 25 x 9 x 9 grid's boundary (1792 triangles) and the 5 mm instrument sphere above its top face,
// seen from 400 mm, 40 degrees from the vertical, by a 640 x 480 camera with the RealSense-like
// noise (2 mm at 400 mm, 1 % dropout, 80 degree grazing limit, 1/8 mm depth unit). Rendering and
// capture run on one thread. The second benchmark adds the binary .pcd write.
#include <benchmark/benchmark.h>

#include <cmath>

#include "observation/DepthCamera.h"
#include "observation/SurfaceIndex.h"
#include "engine/topology/GridSplit.h"
#include "io/pointcloud/CloudIo.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using namespace viscera::obs;

namespace {

struct PhantomView {
  Eigen::Matrix3Xd points;
  TriangleList triangles;
  RenderInput input;
  DepthNoise noise;
  DepthCamera camera;

  PhantomView() : camera(makeCamera()) {
    const std::array<int, 3> n = {25, 9, 9};
    points = gridPoints(n, Eigen::Vector3d::Zero(), Eigen::Vector3d(68.7, 35.8, 39.3));
    triangles = boundaryTriangles(splitHexahedra(gridHexahedra(n), n[0] - 1, n[1] - 1, true), points);
    input.surfaces.push_back({&points, &triangles, 0});
    input.spheres.push_back({Eigen::Vector3d(30, 18, 39.3 + 6), 5, 1});
    noise.sigma0 = 2;
    noise.z0 = 400;
    noise.dropout = 0.01;
    noise.grazingAngleDeg = 80;
    noise.depthUnit = 0.125;
  }
  static DepthCamera makeCamera() {
    const Eigen::Vector3d target(34.35, 17.9, 19.65);
    const Eigen::Vector3d position = target + 400 * Eigen::Vector3d(0, -std::sin(0.7), std::cos(0.7));
    return DepthCamera(CameraIntrinsics::fromFov(640, 480, 60), lookAtPose(position, target, Eigen::Vector3d::UnitZ()),
                       200, 1500);
  }
};

void BM_DepthCameraFrame(benchmark::State& state) {
  PhantomView view;
  DepthImage image;
  std::uint64_t frame = 0;
  int points = 0;
  for (auto _ : state) {
    view.camera.render(view.input, image);
    const Capture c = view.camera.capture(image, view.noise, frame++);
    points = c.cloud.size();
    benchmark::DoNotOptimize(c.cloud.points.data());
  }
  state.counters["points"] = points;
  state.counters["triangles"] = static_cast<double>(view.triangles.cols());
}
BENCHMARK(BM_DepthCameraFrame)->Unit(benchmark::kMillisecond);

void BM_DepthCameraFrameWithPcdWrite(benchmark::State& state) {
  PhantomView view;
  DepthImage image;
  test_support::TempDir dir("camera_bench");
  const std::string path = dir / "frame.pcd";
  std::uint64_t frame = 0;
  for (auto _ : state) {
    view.camera.render(view.input, image);
    const Capture c = view.camera.capture(image, view.noise, frame++);
    cloud::writeCloud(path, c.cloud, cloud::CloudEncoding::Binary);
  }
}
BENCHMARK(BM_DepthCameraFrameWithPcdWrite)->Unit(benchmark::kMillisecond);

}  // namespace
