// `viscera mesh`: meshing to .msh and .vtu with the JSON report, `--check`, the flip of an
// inward-oriented surface, and bad input (exit code 2, a message naming the file, no output).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>

#include "io/mesh/Mesh.h"
#include "tests/apps/cli_helpers.h"
#include "tests/io/meshing/shapes.h"

using namespace viscera_test;
namespace io = viscera::io;

namespace {

SurfaceMesh box(bool skipTop = false) { return gridBox(Eigen::Vector3d(20, 10, 5), {8, 4, 2}, skipTop); }

// The number after "key": in a JSON text (NaN if absent).
double jsonNumber(const std::string& json, const std::string& key) {
  size_t p = json.find("\"" + key + "\": ");
  if (p == std::string::npos) return std::nan("");
  return std::strtod(json.c_str() + p + key.size() + 4, nullptr);
}

TEST(MeshCli, WritesGmshAndReport) {
  TempDir dir;
  io::writeSurface(dir / "box.obj", box());
  const auto r = runViscera({"mesh", dir / "box.obj", dir / "box.msh", "--max-volume", "2", "--report", dir / "report.json"});
  ASSERT_EQ(r.rc, 0) << r;
  const io::VolumeMesh m = io::readGmsh(dir / "box.msh");
  EXPECT_EQ(io::checkTetMesh(m, "box.msh"), 1);
  EXPECT_GT(m.triangles.cols(), 0);
  const std::string json = slurp(dir / "report.json");
  EXPECT_EQ(jsonNumber(json, "tetrahedra"), static_cast<double>(m.tets.cols()));
  EXPECT_EQ(jsonNumber(json, "nodes"), static_cast<double>(m.points.cols()));
  // Exact box: 1000 both ways (to the 10 digits the report keeps).
  EXPECT_NEAR(jsonNumber(json, "volume"), 1000.0, 1e-6);
  EXPECT_NEAR(jsonNumber(json, "surface_volume"), 1000.0, 1e-6);
  EXPECT_NE(json.find("\"radius_edge_ratio\": {\"max\": "), std::string::npos) << json;
  EXPECT_NE(r.out.find("box.msh: " + std::to_string(m.points.cols()) + " nodes, " + std::to_string(m.tets.cols()) + " tetrahedra"),
            std::string::npos)
      << r;
  EXPECT_NE(r.out.find("radius-edge ratio: max"), std::string::npos) << r;
}

TEST(MeshCli, WritesVtuKeepingTheSurface) {
  TempDir dir;
  io::writeSurface(dir / "box.stl", box(), true);
  const auto r = runViscera({"mesh", dir / "box.stl", dir / "box.vtu", "--keep-surface", "--quality", "0", "--quiet"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "");
  const io::VolumeMesh m = io::readVtu(dir / "box.vtu");
  EXPECT_EQ(io::checkTetMesh(m, "box.vtu"), 1);
  // Every input vertex is a node (TetGen -Y keeps the boundary as it is).
  EXPECT_GE(m.points.cols(), box().points.cols());
}

TEST(MeshCli, CheckPrintsTheSurfaceReport) {
  TempDir dir;
  io::writeSurface(dir / "box.ply", box());
  const auto r = runViscera({"mesh", "--check", dir / "box.ply"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.out.find("box.ply: closed, manifold, consistently oriented surface"), std::string::npos) << r;
  EXPECT_NE(r.out.find("vertices 114, triangles 224"), std::string::npos) << r;
  EXPECT_NE(r.out.find("area 700, enclosed volume 1000"), std::string::npos) << r;
  EXPECT_TRUE(absentOrEmpty(dir / "box.msh"));
}

TEST(MeshCli, InwardSurfaceIsFlippedWithANote) {
  TempDir dir;
  SurfaceMesh s = box();
  io::flipSurface(s);
  io::writeSurface(dir / "inward.off", s);
  const auto r = runViscera({"mesh", dir / "inward.off", dir / "inward.msh", "--report", dir / "r.json"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.err.find("oriented inwards"), std::string::npos) << r;
  EXPECT_NE(slurp(dir / "r.json").find("\"flipped\": true"), std::string::npos);
  EXPECT_EQ(io::checkTetMesh(io::readGmsh(dir / "inward.msh"), "inward.msh"), 1);
  const auto c = runViscera({"mesh", "--check", dir / "inward.off"});
  ASSERT_EQ(c.rc, 0) << c;
  EXPECT_NE(c.out.find("oriented inwards"), std::string::npos) << c;
}

// A bad run: exit code 2, `expect` in the message, and neither output file.
void expectRejected(const TempDir& dir, const std::vector<std::string>& args, const std::string& expect) {
  const auto r = runViscera(args);
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find(expect), std::string::npos) << "expected '" << expect << "' in\n" << r;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.msh"));
  EXPECT_FALSE(std::filesystem::exists(dir / "report.json"));
}

TEST(MeshCli, BadSurfacesExitWithCode2AndWriteNothing) {
  TempDir dir;
  auto mesh = [&](const std::string& surface) {
    return std::vector<std::string>{"mesh", dir / surface, dir / "out.msh", "--report", dir / "report.json"};
  };
  writeOff(dir / "open.off", box(true));
  expectRejected(dir, mesh("open.off"), "open.off: the surface cannot be meshed: it is not closed: 24 edges");
  expectRejected(dir, {"mesh", "--check", dir / "open.off"}, "open.off: the surface cannot be meshed: it is not closed");

  SurfaceMesh two = gridBox(Eigen::Vector3d(1, 1, 1), {1, 1, 1});
  appendCube(two, Eigen::Vector3d(1, 1, 0));
  writeOff(dir / "two.off", two);
  expectRejected(dir, mesh("two.off"), "two.off: the surface cannot be meshed: it is not manifold: 1 edge is shared by more than two");

  SurfaceMesh flipped = box();
  std::swap(flipped.triangles(1, 0), flipped.triangles(2, 0));
  writeOff(dir / "flipped.off", flipped);
  expectRejected(dir, mesh("flipped.off"), "flipped.off: the surface cannot be meshed: it is not consistently oriented: 3 edges");

  std::ofstream(dir / "empty.stl").close();
  expectRejected(dir, mesh("empty.stl"), "empty.stl: the surface file is empty");
  expectRejected(dir, mesh("missing.obj"), "missing.obj: cannot open surface file");
  std::ofstream(dir / "box.step") << "ISO-10303-21;\n";
  expectRejected(dir, mesh("box.step"), "box.step: cannot read surface: unsupported format '.step'");
}

TEST(MeshCli, BadOptionsAndProgramExitWithCode2AndWriteNothing) {
  TempDir dir;
  io::writeSurface(dir / "box.off", box());
  const std::string in = dir / "box.off", out = dir / "out.msh", report = dir / "report.json";
  expectRejected(dir, {"mesh", in, out, "--report", report, "--tetgen", "viscera-no-such-tetgen"},
                 "box.off: the TetGen program 'viscera-no-such-tetgen' was not found on PATH: install the Debian package tetgen");
  expectRejected(dir, {"mesh", in, dir / "out.stl"}, "output " + dir / "out.stl" + ": unknown format '.stl'");
  EXPECT_FALSE(std::filesystem::exists(dir / "out.stl"));
  expectRejected(dir, {"mesh", in, out, "--quality", "0.5"},
                 "--quality: give 0 (no quality refinement) or a radius-edge ratio bound of at least 1.1");
  expectRejected(dir, {"mesh", in, out, "--max-volume", "-1"}, "--max-volume: must be >= 0");
  expectRejected(dir, {"mesh", in, out, "--report", dir / "no/such/folder/r.json"},
                 "the folder " + dir / "no/such/folder" + " does not exist");
  expectRejected(dir, {"mesh", in}, "give the output file (.msh or .vtu), or --check");
  expectRejected(dir, {"mesh", "--check", in, out}, "mesh --check takes only the surface");
}

}  // namespace
