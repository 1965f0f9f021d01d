// `viscera distance` end to end: clouds written with writeCloud against a box mesh written with
// writeVtu, alone or as a time series; the table, the summary, the residual files and the errors.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "engine/topology/GridSplit.h"
#include "io/mesh/Exodus.h"
#include "io/mesh/Mesh.h"
#include "io/pointcloud/CloudIo.h"
#include "io/scene/Transform.h"
#include "tests/apps/cli_helpers.h"

using namespace viscera_test;

namespace {

// The box [0, 2]^3 as a 3 x 3 x 3 grid split into tetrahedra (8 cubes of side 1), moved up by `lift`.
void writeBox(const std::string& path, double lift = 0) {
  Eigen::Matrix3Xd x = viscera::gridPoints({3, 3, 3}, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(2, 2, 2));
  x.row(2).array() += lift;
  viscera::io::writeVtu(path, x, viscera::splitHexahedra(viscera::gridHexahedra({3, 3, 3}), 2, 2, true), {}, {});
}

// 25 points over the top face (z = 2) at height `height`, on the lattice of thirds of the unit
// squares (x, y = 1/3 .. 5/3), where the factor-3 samples lie: both methods give `height`.
Eigen::Matrix3Xd overTheTop(double height) {
  Eigen::Matrix3Xd p(3, 25);
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) p.col(5 * i + j) = Eigen::Vector3d((i + 1) / 3.0, (j + 1) / 3.0, 2 + height);
  return p;
}

viscera::cloud::PointCloud makeCloud(const Eigen::Matrix3Xd& points) {
  viscera::cloud::PointCloud c;
  c.points = points;
  return c;
}

// The number after "key": in a JSON text (NaN if absent).
double jsonNumber(const std::string& json, const std::string& key) {
  size_t p = json.find("\"" + key + "\":");
  if (p == std::string::npos) return std::nan("");
  p += key.size() + 3;
  char* end = nullptr;
  const double d = std::strtod(json.c_str() + p, &end);
  return end == json.c_str() + p ? std::nan("") : d;
}

// The table as rows of fields (header first).
std::vector<std::vector<std::string>> readTable(const std::string& path) {
  std::vector<std::vector<std::string>> rows;
  for (const std::string& line : lines(slurp(path))) {
    std::vector<std::string> f(1);
    for (char c : line) {
      if (c == ',') f.emplace_back();
      else f.back() += c;
    }
    rows.push_back(f);
  }
  return rows;
}

// The value in `column` of data row `row` (0-based, after the header).
double cell(const std::vector<std::vector<std::string>>& table, size_t row, const std::string& column) {
  const auto& header = table.at(0);
  const auto it = std::find(header.begin(), header.end(), column);
  if (it == header.end()) {
    ADD_FAILURE() << "no column " << column;
    return std::nan("");
  }
  return std::stod(table.at(row + 1).at(static_cast<size_t>(it - header.begin())));
}

// Clouds are stored as float32, so coordinates carry ~1e-7 relative rounding: 1e-6 on distances
// of order 1 in a box of size 2.
constexpr double kFloatTol = 1e-6;

TEST(DistanceCli, SingleCloudAgainstAMesh) {
  TempDir tmp;
  writeBox(tmp / "box.vtu");
  viscera::cloud::writeCloud(tmp / "cloud.pcd", makeCloud(overTheTop(0.5)));
  const RunResult r = runViscera({"distance", "--cloud", tmp / "cloud.pcd", "--mesh", tmp / "box.vtu", "--out", tmp / "table.csv",
                                  "--summary", tmp / "summary.json", "--residuals", tmp / "res"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.err.find("[1/1]"), std::string::npos) << r;  // progress line

  const auto table = readTable(tmp / "table.csv");
  ASSERT_EQ(table.size(), 2u);
  EXPECT_EQ(table[0], (std::vector<std::string>{"frame", "time", "count", "beyond", "mean", "rms", "mean_squared", "median", "p95",
                                                "max", "cloud"}));
  EXPECT_EQ(cell(table, 0, "count"), 25);
  EXPECT_EQ(cell(table, 0, "beyond"), 0);
  for (const char* c : {"mean", "rms", "median", "p95", "max"}) EXPECT_NEAR(cell(table, 0, c), 0.5, kFloatTol) << c;
  EXPECT_NEAR(cell(table, 0, "mean_squared"), 0.25, kFloatTol);

  const std::string summary = slurp(tmp / "summary.json");
  EXPECT_NEAR(jsonNumber(summary, "mean"), 0.5, kFloatTol) << summary;
  EXPECT_EQ(jsonNumber(summary, "frames"), 1);
  EXPECT_EQ(jsonNumber(summary, "counted"), 25);
  EXPECT_NE(summary.find("\"method\": \"vertices\""), std::string::npos);

  for (const char* f : {"cloud_000000.vtp", "surface_000000.vtp", "cloud.pvd", "surface.pvd"})
    EXPECT_TRUE(fs::exists(tmp.path() / "res" / f)) << f;
  const std::string cloudVtp = slurp(tmp.path() / "res" / "cloud_000000.vtp");
  EXPECT_NE(cloudVtp.find("Name=\"distance\""), std::string::npos);
  EXPECT_NE(cloudVtp.find("NumberOfPoints=\"25\""), std::string::npos);
  const std::string surfaceVtp = slurp(tmp.path() / "res" / "surface_000000.vtp");
  EXPECT_NE(surfaceVtp.find("Name=\"pointCount\""), std::string::npos);
  EXPECT_NE(surfaceVtp.find("NumberOfPoints=\"27\""), std::string::npos);
  EXPECT_NE(surfaceVtp.find("NumberOfPolys=\"48\""), std::string::npos);  // 6 faces x 4 squares x 2
}

TEST(DistanceCli, TrianglesWithATransformAndACutOff) {
  // The cloud is stored in a camera frame: p_camera = T^-1 p_scene, with T (camera -> scene) a
  // rotation of 30 degrees about (1, 2, 3) and a translation. Two points are 5 above the box and
  // fall beyond --max-distance 1.
  TempDir tmp;
  writeBox(tmp / "box.vtu");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.rotate(Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d(1, 2, 3).normalized()));
  T.pretranslate(Eigen::Vector3d(10, -4, 7));
  viscera::writeTransform(tmp / "camera.txt", T);
  Eigen::Matrix3Xd scene(3, 27);
  scene << overTheTop(0.25), Eigen::Vector3d(1, 1, 7), Eigen::Vector3d(0.5, 0.5, 7);
  viscera::cloud::writeCloud(tmp / "cloud.ply", makeCloud(T.inverse() * scene));
  const RunResult r = runViscera({"distance", "--cloud", tmp / "cloud.ply", "--mesh", tmp / "box.vtu", "--transform", tmp / "camera.txt",
                                  "--method", "triangles", "--max-distance", "1", "--out", tmp / "table.csv", "--quiet"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_TRUE(r.err.empty()) << r;
  const auto table = readTable(tmp / "table.csv");
  ASSERT_EQ(table.size(), 2u);
  EXPECT_EQ(cell(table, 0, "count"), 25);
  EXPECT_EQ(cell(table, 0, "beyond"), 2);
  // The rotation spreads float32 rounding of camera coordinates of size ~10: 1e-5.
  EXPECT_NEAR(cell(table, 0, "mean"), 0.25, 1e-5);
  EXPECT_NEAR(cell(table, 0, "signed_mean"), 0.25, 1e-5);
  EXPECT_NEAR(cell(table, 0, "max"), 0.25, 1e-5);
}

TEST(DistanceCli, SequenceAgainstASeriesByTime) {
  // The simulated box rises by 0.1 per 0.1 s (frames at t = 0, 0.1, 0.2); the clouds stay at
  // z = 2.5 at t = 0.01, 0.12, 0.21, so they meet frames 0, 1, 2 and lie 0.5, 0.4, 0.3 above.
  TempDir tmp;
  std::vector<std::pair<double, std::string>> series;
  for (int f = 0; f < 3; ++f) {
    const std::string name = "box_" + std::to_string(f) + ".vtu";
    writeBox(tmp / name, 0.1 * f);
    series.push_back({0.1 * f, name});
  }
  viscera::io::writePvd(tmp / "box.pvd", series);
  {
    viscera::cloud::CloudSequenceWriter writer(tmp / "clouds");
    for (double t : {0.01, 0.12, 0.21}) writer.add(makeCloud(overTheTop(0.5)), t);
  }
  const RunResult r = runViscera({"distance", "--cloud", tmp / "clouds", "--series", tmp / "box.pvd", "--out", tmp / "table.csv",
                                  "--summary", tmp / "summary.json", "--residuals", tmp / "res"});
  ASSERT_EQ(r.rc, 0) << r;
  const auto table = readTable(tmp / "table.csv");
  ASSERT_EQ(table.size(), 4u);
  const double expected[3] = {0.5, 0.4, 0.3}, meshTime[3] = {0, 0.1, 0.2}, gap[3] = {0.01, 0.02, 0.01};
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(cell(table, i, "mean"), expected[i], kFloatTol) << "frame " << i;
    EXPECT_NEAR(cell(table, i, "mesh_time"), meshTime[i], 1e-12) << "frame " << i;
    EXPECT_NEAR(cell(table, i, "time_gap"), gap[i], 1e-9) << "frame " << i;
  }
  const std::string summary = slurp(tmp / "summary.json");
  EXPECT_NEAR(jsonNumber(summary, "mean"), 0.4, kFloatTol);
  EXPECT_NEAR(jsonNumber(summary, "max_time_gap"), 0.02, 1e-9);
  EXPECT_EQ(jsonNumber(summary, "counted"), 75);
  // The residual series: three frames in each .pvd, at the clouds' times.
  const std::string pvd = slurp(tmp.path() / "res" / "surface.pvd");
  EXPECT_NE(pvd.find("surface_000002.vtp"), std::string::npos) << pvd;
  EXPECT_NE(pvd.find("timestep=\"0.12\""), std::string::npos) << pvd;
}

// The same rising box as one Exodus series (the mesh once, the rise as its displacement, Float64):
// the same distances, frame by frame; and --mesh takes the series' first frame.
TEST(DistanceCli, SequenceAgainstAnExodusSeries) {
  TempDir tmp;
  viscera::io::ExodusLayout layout;
  layout.rest = viscera::gridPoints({3, 3, 3}, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(2, 2, 2));
  layout.tets = viscera::splitHexahedra(viscera::gridHexahedra({3, 3, 3}), 2, 2, true);
  layout.nodeVectors = {"displacement"};
  layout.float32 = false;
  {
    viscera::io::ExodusWriter w(tmp / "box.exo", layout);
    for (int f = 0; f < 3; ++f) {
      Eigen::Matrix3Xd d = Eigen::Matrix3Xd::Zero(3, layout.rest.cols());
      d.row(2).setConstant(0.1 * f);
      w.append(0.1 * f, {d}, {});
    }
    w.finish();
  }
  {
    viscera::cloud::CloudSequenceWriter writer(tmp / "clouds");
    for (double t : {0.01, 0.12, 0.21}) writer.add(makeCloud(overTheTop(0.5)), t);
  }
  RunResult r = runViscera({"distance", "--cloud", tmp / "clouds", "--series", tmp / "box.exo", "--out", tmp / "table.csv"});
  ASSERT_EQ(r.rc, 0) << r;
  const auto table = readTable(tmp / "table.csv");
  ASSERT_EQ(table.size(), 4u);
  const double expected[3] = {0.5, 0.4, 0.3}, meshTime[3] = {0, 0.1, 0.2};
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(cell(table, i, "mean"), expected[i], kFloatTol) << "frame " << i;
    EXPECT_NEAR(cell(table, i, "mesh_time"), meshTime[i], 1e-12) << "frame " << i;
  }
  r = runViscera({"distance", "--cloud", tmp / "clouds/frame_000000.pcd", "--mesh", tmp / "box.exo", "--out", tmp / "one.csv"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NEAR(cell(readTable(tmp / "one.csv"), 0, "mean"), 0.5, kFloatTol);
}

TEST(DistanceCli, TimeGapTooLargeWritesNothing) {
  // Frames at 0 and 0.1 (default gap: 0.05); a cloud at 0.3 has no frame close enough.
  TempDir tmp;
  writeBox(tmp / "a.vtu");
  writeBox(tmp / "b.vtu");
  viscera::io::writePvd(tmp / "box.pvd", {{0.0, "a.vtu"}, {0.1, "b.vtu"}});
  {
    viscera::cloud::CloudSequenceWriter writer(tmp / "clouds");
    writer.add(makeCloud(overTheTop(0.5)), 0.05);
    writer.add(makeCloud(overTheTop(0.5)), 0.3);
  }
  const std::vector<std::string> base = {"distance", "--cloud", tmp / "clouds", "--series", tmp / "box.pvd", "--out", tmp / "t.csv",
                                         "--summary", tmp / "s.json", "--residuals", tmp / "res"};
  RunResult r = runViscera(base);
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("frame_000001.pcd"), std::string::npos) << r;
  EXPECT_NE(r.err.find("--max-time-gap"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(tmp / "t.csv"));
  EXPECT_FALSE(fs::exists(tmp / "s.json"));
  EXPECT_TRUE(absentOrEmpty(tmp.path() / "res"));
  // A larger allowed gap accepts it.
  std::vector<std::string> wider = base;
  wider.insert(wider.end(), {"--max-time-gap", "0.25", "--quiet"});
  r = runViscera(wider);
  EXPECT_EQ(r.rc, 0) << r;

  // A single cloud file is matched at --time (default 0).
  r = runViscera({"distance", "--cloud", tmp / "clouds/frame_000000.pcd", "--series", tmp / "box.pvd", "--time", "0.09", "--out",
                  tmp / "one.csv", "--quiet"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NEAR(cell(readTable(tmp / "one.csv"), 0, "mesh_time"), 0.1, 1e-12);
  r = runViscera({"distance", "--cloud", tmp / "clouds", "--series", tmp / "box.pvd", "--time", "0.09"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("--time"), std::string::npos) << r;
}

TEST(DistanceCli, BadFrameMidSequenceLeavesNoOutput) {
  TempDir tmp;
  writeBox(tmp / "box.vtu");
  {
    viscera::cloud::CloudSequenceWriter writer(tmp / "clouds");
    writer.add(makeCloud(overTheTop(0.5)), 0.0);
    writer.add(makeCloud(overTheTop(0.5)), 0.1);
  }
  // Corrupt the second frame.
  std::ofstream(tmp.path() / "clouds" / "frame_000001.pcd") << "not a point cloud\n";
  const RunResult r = runViscera({"distance", "--cloud", tmp / "clouds", "--mesh", tmp / "box.vtu", "--out", tmp / "t.csv",
                                  "--residuals", tmp / "res"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("frame_000001.pcd"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(tmp / "t.csv"));
  EXPECT_FALSE(fs::exists(tmp.path() / "res")) << "the residual files of frame 0 must be removed";
}

TEST(DistanceCli, OptionErrorsExitTwo) {
  TempDir tmp;
  writeBox(tmp / "box.vtu");
  viscera::cloud::writeCloud(tmp / "c.pcd", makeCloud(overTheTop(0.5)));
  struct Case {
    std::vector<std::string> args;
    std::string message;  // a part of the error message
  };
  const std::vector<Case> cases = {
      {{"--cloud", tmp / "missing.pcd", "--mesh", tmp / "box.vtu"}, "missing.pcd"},
      {{"--cloud", tmp / "c.pcd", "--mesh", tmp / "nothere.vtu"}, "nothere.vtu"},
      {{"--cloud", tmp / "c.pcd"}, "--mesh or --series"},
      {{"--cloud", tmp / "c.pcd", "--mesh", tmp / "box.vtu", "--series", tmp / "x.pvd"}, "excludes"},
      {{"--cloud", tmp / "c.pcd", "--mesh", tmp / "box.vtu", "--method", "nearest"}, "--method"},
      {{"--cloud", tmp / "c.pcd", "--mesh", tmp / "box.vtu", "--factor", "0"}, "--factor"},
      {{"--cloud", tmp / "c.pcd", "--mesh", tmp / "box.vtu", "--max-distance", "-1"}, "--max-distance"},
      {{"--cloud", tmp / "c.pcd", "--mesh", tmp / "box.vtu", "--transform", tmp / "none.txt"}, "none.txt"},
      {{"--cloud", tmp / "c.pcd", "--series", tmp / "box.vtu"}, "box.vtu"},  // not a .pvd
      {{"--cloud", tmp / "c.pcd", "--mesh", tmp / "box.vtu", "--out", tmp / "no/such/folder/t.csv"}, "does not exist"},
  };
  for (const Case& c : cases) {
    std::vector<std::string> args = {"distance"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const RunResult r = runViscera(args);
    EXPECT_EQ(r.rc, 2) << r;
    EXPECT_NE((r.err + r.out).find(c.message), std::string::npos) << "expected '" << c.message << "' in\n" << r;
  }
}

}  // namespace
