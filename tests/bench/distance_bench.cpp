// Cloud -> surface distance per depth-camera frame, on one thread: a 45,000-point cloud against the
// gel phantom's surface (scenes/gel_phantom.xml: a 25 x 9 x 9 grid over 68.7 x 35.8 x 39.3 mm split
// into tetrahedra). The cloud covers the top and two side faces, as a camera above and in front of
// the block sees them, in image order (face by face, row by row), with 2 mm of Gaussian noise.
//
// BM_CloudDistanceVertices times what a frame costs with the surface super-sampled x3: re-sampling
// the surface from its vertex positions, building the k-d tree and measuring every point (statistics
// and per-vertex means included). BM_CloudDistanceTriangles: refitting the hierarchy and the exact
// point-to-triangle distances.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <cmath>
#include <random>

#include "observation/CloudDistance.h"
#include "engine/topology/GridSplit.h"

using namespace viscera;

namespace {

struct Phantom {
  Eigen::Matrix3Xd x;       // 3 x 2025 grid nodes
  obs::TriangleList surface;  // 3 x 1792 boundary triangles
  Eigen::Matrix3Xd cloud;   // 3 x 45,000
};

const Phantom& phantom() {
  static const Phantom p = [] {
    Phantom ph;
    const Eigen::Vector3d lo(0, 0, 0), hi(68.7, 35.8, 39.3);
    ph.x = gridPoints({25, 9, 9}, lo, hi);
    const TetList tets = splitHexahedra(gridHexahedra({25, 9, 9}), 24, 8, true);
    ph.surface = obs::boundaryTriangles(tets, ph.x);

    // Points per face in proportion to its area; each face sampled on a regular raster (a depth
    // image's rows), every point displaced by N(0, 2 mm) per axis.
    const int total = 45000;
    const Eigen::Vector3d size = hi - lo;
    struct Face {
      Eigen::Vector3d origin, u, v;  // points origin + s u + t v, s, t in [0, 1]
    };
    const Face faces[3] = {
        {Eigen::Vector3d(lo.x(), lo.y(), hi.z()), Eigen::Vector3d(size.x(), 0, 0), Eigen::Vector3d(0, size.y(), 0)},  // top
        {Eigen::Vector3d(lo.x(), lo.y(), lo.z()), Eigen::Vector3d(size.x(), 0, 0), Eigen::Vector3d(0, 0, size.z())},  // y-
        {Eigen::Vector3d(hi.x(), lo.y(), lo.z()), Eigen::Vector3d(0, size.y(), 0), Eigen::Vector3d(0, 0, size.z())},  // x+
    };
    double area[3], areaSum = 0;
    for (int f = 0; f < 3; ++f) areaSum += area[f] = faces[f].u.norm() * faces[f].v.norm();
    std::mt19937 rng(42);
    std::normal_distribution<double> noise(0.0, 2.0);
    ph.cloud.resize(3, total);
    int written = 0;
    for (int f = 0; f < 3; ++f) {
      const int count = f < 2 ? static_cast<int>(std::lround(total * area[f] / areaSum)) : total - written;
      // A raster of cols x rows >= count points with the face's aspect ratio, cut at count.
      const double aspect = faces[f].u.norm() / faces[f].v.norm();
      const int cols = static_cast<int>(std::ceil(std::sqrt(count * aspect)));
      const int rows = (count + cols - 1) / cols;
      for (int k = 0; k < count; ++k) {
        const double s = (k % cols + 0.5) / cols, t = (k / cols + 0.5) / rows;
        const Eigen::Vector3d e(noise(rng), noise(rng), noise(rng));
        ph.cloud.col(written++) = faces[f].origin + s * faces[f].u + t * faces[f].v + e;
      }
    }
    return ph;
  }();
  return p;
}

void runFrames(benchmark::State& state, obs::DistanceMethod method) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
  const Phantom& ph = phantom();
  obs::DistanceOptions options;
  options.method = method;
  options.factor = 3;
  options.parallel = false;
  obs::CloudDistance distance(ph.surface, static_cast<int>(ph.x.cols()), options);
  obs::DistanceResult result;
  for (auto _ : state) {
    distance.setSurface(ph.x);
    distance.measure(ph.cloud, result);
    // Kept alive through memory (the pointer): DoNotOptimize on a double held in a register can
    // corrupt it in the Google Benchmark release this builds against.
    benchmark::DoNotOptimize(result.distance.data());
    benchmark::ClobberMemory();
  }
  state.counters["points"] = static_cast<double>(ph.cloud.cols());
  state.counters["triangles"] = static_cast<double>(ph.surface.cols());
  state.counters["samples"] = static_cast<double>(distance.samples().cols());
  state.counters["mean_mm"] = result.stats.mean;
  state.SetItemsProcessed(state.iterations() * ph.cloud.cols());
}

void BM_CloudDistanceVertices(benchmark::State& state) { runFrames(state, obs::DistanceMethod::Vertices); }
void BM_CloudDistanceTriangles(benchmark::State& state) { runFrames(state, obs::DistanceMethod::Triangles); }

}  // namespace

BENCHMARK(BM_CloudDistanceVertices)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CloudDistanceTriangles)->Unit(benchmark::kMillisecond);
