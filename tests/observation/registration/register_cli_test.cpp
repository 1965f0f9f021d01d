// `viscera register points` and `viscera register icp` through the built binary: the transform
// files they write read back to the known transforms, and bad input exits with 2 naming the file
// or option, with nothing written.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "io/mesh/Mesh.h"
#include "io/scene/Transform.h"
#include "tests/apps/cli_helpers.h"
#include "tests/observation/registration/phantom.h"

using namespace viscera_test;
using namespace registration_test;
using viscera::RigidTransform;

namespace {

void write(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

std::string fmt(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// A points CSV with a header; names when `names` is given.
std::string pointsCsv(const Eigen::Matrix3Xd& p, const std::vector<std::string>& names = {}) {
  std::string s = names.empty() ? "x,y,z\n" : "name,x,y,z\n";
  for (Eigen::Index i = 0; i < p.cols(); ++i)
    s += (names.empty() ? "" : names[static_cast<size_t>(i)] + ",") + fmt(p(0, i)) + "," + fmt(p(1, i)) + "," + fmt(p(2, i)) + "\n";
  return s;
}

// An ASCII .pcd file with float64 coordinates.
std::string pcd(const Eigen::Matrix3Xd& p) {
  const std::string n = std::to_string(p.cols());
  std::string s = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " +
                  n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\nDATA ascii\n";
  for (Eigen::Index i = 0; i < p.cols(); ++i) s += fmt(p(0, i)) + " " + fmt(p(1, i)) + " " + fmt(p(2, i)) + "\n";
  return s;
}

RigidTransform robotToScene() {
  RigidTransform T = RigidTransform::Identity();
  T.linear() = Eigen::AngleAxisd(2.1, Eigen::Vector3d(0.3, -1, 0.4).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(412.5, -87.25, 130);
  return T;
}

// ---------------------------------------------------------------------------------------------
// points

TEST(RegisterPointsCli, WritesTheTransformAndReport) {
  TempDir tmp("viscera_register");
  const Eigen::Matrix3Xd scene = phantomCorners().leftCols(4);
  const Eigen::Matrix3Xd robot = robotToScene().inverse() * scene;
  // Named, in different orders in the two files: pairing is by name.
  write(tmp / "robot.csv", pointsCsv(robot, {"front_left", "front_right", "back_right", "back_left"}));
  Eigen::Matrix3Xd shuffled(3, 4);
  shuffled << scene.col(2), scene.col(0), scene.col(3), scene.col(1);
  write(tmp / "scene.csv", pointsCsv(shuffled, {"back_right", "front_left", "back_left", "front_right"}));
  const RunResult r = runViscera({"register", "points", "--source", tmp / "robot.csv", "--target", tmp / "scene.csv", "--out",
                                  tmp / "robot_to_scene.txt", "--report", tmp / "report.json"});
  ASSERT_EQ(r.rc, 0) << r;
  const RigidTransform T = viscera::readTransform(tmp / "robot_to_scene.txt");
  // Exact data written with 17 digits: the fit is exact to rounding.
  EXPECT_LT((T.matrix() - robotToScene().matrix()).cwiseAbs().maxCoeff(), 1e-11);
  // The residual table names every point; the file's comment holds the command.
  for (const char* name : {"front_left", "front_right", "back_right", "back_left", "RMS"})
    EXPECT_NE(r.out.find(name), std::string::npos) << name << "\n" << r;
  const std::string text = slurp(tmp / "robot_to_scene.txt");
  EXPECT_EQ(text.rfind("# robot -> scene from 4 corresponding points: viscera register points", 0), 0u) << text;
  const std::string report = slurp(tmp / "report.json");
  EXPECT_NE(report.find("\"method\": \"points\""), std::string::npos) << report;
  EXPECT_NE(report.find("\"name\": \"back_left\""), std::string::npos) << report;
}

TEST(RegisterPointsCli, PairsByOrderWithoutNames) {
  TempDir tmp("viscera_register");
  const Eigen::Matrix3Xd scene = phantomCorners();
  write(tmp / "robot.csv", pointsCsv(robotToScene().inverse() * scene));
  write(tmp / "scene.csv", pointsCsv(scene));
  const RunResult r = runViscera({"register", "points", "--source", tmp / "robot.csv", "--target", tmp / "scene.csv", "--out", tmp / "T.txt"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_LT((viscera::readTransform(tmp / "T.txt").matrix() - robotToScene().matrix()).cwiseAbs().maxCoeff(), 1e-11);
}

struct BadPoints {
  std::string robot, scene;  // file contents ("" = no file)
  std::string expect;        // in stderr; "{robot}" / "{scene}" stand for the paths
  std::vector<std::string> extra = {};
};

TEST(RegisterPointsCli, BadInputExitsWithTwoAndWritesNothing) {
  const std::string good = pointsCsv(phantomCorners().leftCols(4));
  const std::vector<BadPoints> cases = {
      {"", good, "{robot}: cannot open point file"},
      {"x,y,z\n", good, "{robot}: no points"},
      {"1,2,3\n4,5,6\n", "1,2,3\n4,5,6\n", "at least 3"},
      {good, "x,y,z\n0,0,0\n1,0,0\n", "has 4 points but"},
      {"0,0,0\n1,0,0\n2,0,0\n3,0,0\n", good, "collinear"},
      {good, "0,0,0\n0,1,0\n0,2,0\n0,3,0\n", "{scene}: "},
      {good, "x,y,z\n0,0,0\n1,0,nan\n0,1,0\n1,1,0\n", "{scene}:3: z: 'nan' is not finite"},
      {"A,0,0,0\nB,1,0,0\nC,0,1,0\n", "A,0,0,0\nB,1,0,0\nD,0,1,0\n", "{robot}:3: point 'C' has no point of the same name"},
      {"A,0,0,0\nB,1,0,0\nC,0,1,0\n", good, "names its points but"},
      {good, good, "--out: the folder", {"--out", "{tmp}/no/such/folder/T.txt"}},
  };
  for (const auto& c : cases) {
    TempDir tmp("viscera_register");
    auto sub = [&](std::string s) {
      for (const auto& [key, value] : {std::pair<std::string, std::string>{"{robot}", tmp / "robot.csv"},
                                       {"{scene}", tmp / "scene.csv"},
                                       {"{tmp}", tmp.str()}}) {
        for (size_t p; (p = s.find(key)) != std::string::npos;) s.replace(p, key.size(), value);
      }
      return s;
    };
    if (!c.robot.empty()) write(tmp / "robot.csv", c.robot);
    if (!c.scene.empty()) write(tmp / "scene.csv", c.scene);
    std::vector<std::string> args = {"register", "points", "--source", tmp / "robot.csv", "--target", tmp / "scene.csv",
                                     "--report", tmp / "report.json"};
    if (c.extra.empty()) args.insert(args.end(), {"--out", tmp / "T.txt"});
    for (const auto& e : c.extra) args.push_back(sub(e));
    const RunResult r = runViscera(args);
    const std::string expect = sub(c.expect);
    EXPECT_EQ(r.rc, 2) << expect << "\n" << r;
    EXPECT_NE(r.err.find(expect), std::string::npos) << "expected '" << expect << "'\n" << r;
    EXPECT_FALSE(fs::exists(tmp / "T.txt")) << expect;
    EXPECT_FALSE(fs::exists(tmp / "report.json")) << expect;
  }
  // A missing required option is a usage error: exit 2 too.
  const RunResult r = runViscera({"register", "points", "--source", "a.csv", "--out", "T.txt"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("--target"), std::string::npos) << r;
}

// ---------------------------------------------------------------------------------------------
// icp

// The default cloud of the CLI tests: 5500 surface points with 1 mm noise and 275 outliers.
Eigen::Matrix3Xd smallCloud() {
  CloudSpec s;
  s.top = 3000, s.front = 1600, s.left = 900, s.noise = 1.0;
  return phantomCloud(s);
}

// The phantom as phantom.vtu and a cloud of it (given in the scene frame) as rest.pcd in the camera frame.
struct IcpFiles {
  TempDir tmp{"viscera_register"};
  RigidTransform truth = cameraToScene();
  explicit IcpFiles(const Eigen::Matrix3Xd& sceneCloud = smallCloud()) {
    const PhantomMesh m = phantomMesh();
    viscera::io::writeVtu(tmp / "phantom.vtu", m.points, m.tets, {}, {});
    write(tmp / "rest.pcd", pcd(truth.inverse() * sceneCloud));
  }
  // The initial guess as CLI options: the truth off by 5 degrees and a few mm, as Euler angles.
  std::vector<std::string> initOptions(const RigidTransform& init) const {
    const Eigen::Vector3d e = init.linear().eulerAngles(2, 1, 0);  // z, y, x: R = Rz Ry Rx
    const Eigen::Vector3d t = init.translation();
    const double d = 180 / M_PI;
    return {"--init-rotation", fmt(e[2] * d) + " " + fmt(e[1] * d) + " " + fmt(e[0] * d), "--init-translation",
            fmt(t.x()) + "," + fmt(t.y()) + "," + fmt(t.z())};
  }
};

TEST(RegisterIcpCli, RecoversTheCameraAndWritesEveryOutput) {
  IcpFiles f;
  const RigidTransform init = perturbed(f.truth, 5, Eigen::Vector3d(1, 1, -2), Eigen::Vector3d(-4, 3, 2));
  std::vector<std::string> args = {"register", "icp", "--cloud", f.tmp / "rest.pcd", "--mesh", f.tmp / "phantom.vtu",
                                   "--out", f.tmp / "camera_to_scene.txt", "--report", f.tmp / "report.json",
                                   "--aligned", f.tmp / "aligned.vtp"};
  for (const auto& o : f.initOptions(init)) args.push_back(o);
  const RunResult r = runViscera(args);
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.out.find("ICP converged"), std::string::npos) << r;
  const RigidTransform T = viscera::readTransform(f.tmp / "camera_to_scene.txt");
  // 5500 points with 1 mm noise: the errors are ~0.05 degrees and ~0.05 mm (see icp_test.cpp for
  // the estimate with 2 mm); the initial error was 5 degrees.
  EXPECT_LT(angleBetweenDeg(T, f.truth), 0.5);
  EXPECT_LT(cornerErrorMm(T, f.truth), 0.5);
  EXPECT_EQ(slurp(f.tmp / "camera_to_scene.txt").rfind("# camera -> scene by ICP: viscera register icp --cloud", 0), 0u);
  const std::string report = slurp(f.tmp / "report.json");
  EXPECT_NE(report.find("\"converged\": true"), std::string::npos) << report;
  EXPECT_NE(report.find("\"degenerate\": false"), std::string::npos) << report;
  const std::string vtp = slurp(f.tmp / "aligned.vtp");
  EXPECT_NE(vtp.find("PolyData"), std::string::npos);
  EXPECT_NE(vtp.find("Name=\"residual\""), std::string::npos);
  EXPECT_NE(vtp.find("Name=\"kept\""), std::string::npos);
}

TEST(RegisterIcpCli, InitialTransformFromAFile) {
  IcpFiles f;
  viscera::writeTransform(f.tmp / "init.txt", perturbed(f.truth, 4, Eigen::Vector3d(0, 1, 1), Eigen::Vector3d(3, 3, -3)));
  const RunResult r = runViscera({"register", "icp", "--cloud", f.tmp / "rest.pcd", "--mesh", f.tmp / "phantom.vtu", "--init",
                                  f.tmp / "init.txt", "--out", f.tmp / "T.txt"});
  ASSERT_EQ(r.rc, 0) << r;
  const RigidTransform T = viscera::readTransform(f.tmp / "T.txt");
  EXPECT_LT(angleBetweenDeg(T, f.truth), 0.5);
  EXPECT_LT(cornerErrorMm(T, f.truth), 0.5);
}

TEST(RegisterIcpCli, WarnsWhenOneFlatFaceLeavesDirectionsOpen) {
  // The top face away from its edges (near them the side faces would give the in-plane directions
  // some support).
  std::mt19937 rng(2);
  std::vector<Eigen::Vector3d> pts;
  sampleRectangle(rng, 1500, 2, kHi.z(), Eigen::Vector3d(10, 8, 0), Eigen::Vector3d(58.7, 27.8, 0), pts);
  Eigen::Matrix3Xd top(3, static_cast<Eigen::Index>(pts.size()));
  for (size_t i = 0; i < pts.size(); ++i) top.col(static_cast<Eigen::Index>(i)) = pts[i];
  IcpFiles f(top);
  viscera::writeTransform(f.tmp / "init.txt", perturbed(f.truth, 2, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 0, 2)));
  const RunResult r = runViscera({"register", "icp", "--cloud", f.tmp / "rest.pcd", "--mesh", f.tmp / "phantom.vtu", "--init",
                                  f.tmp / "init.txt", "--out", f.tmp / "T.txt", "--report", f.tmp / "report.json"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.err.find("under-constrained"), std::string::npos) << r;
  EXPECT_NE(r.err.find("translation along"), std::string::npos) << r;
  EXPECT_NE(slurp(f.tmp / "report.json").find("\"degenerate\": true"), std::string::npos);
}

TEST(RegisterIcpCli, BadInputExitsWithTwoAndWritesNothing) {
  IcpFiles f;
  std::string withNan = pcd(Eigen::Matrix3Xd::Identity(3, 3));
  withNan.replace(withNan.rfind("0 0 1"), 5, "0 nan 1");
  write(f.tmp / "nan.pcd", withNan);
  struct Case {
    std::vector<std::string> args;
    std::string expect;
  };
  const std::string cloud = f.tmp / "rest.pcd", mesh = f.tmp / "phantom.vtu";
  const std::vector<Case> cases = {
      {{"--cloud", f.tmp / "missing.pcd", "--mesh", mesh}, "missing.pcd"},
      {{"--cloud", f.tmp / "nan.pcd", "--mesh", mesh}, "nan.pcd"},
      {{"--cloud", cloud, "--mesh", f.tmp / "missing.vtu"}, "missing.vtu"},
      {{"--cloud", cloud, "--mesh", mesh, "--trim", "1.5"}, "--trim"},
      {{"--cloud", cloud, "--mesh", mesh, "--trim", "0"}, "--trim"},
      {{"--cloud", cloud, "--mesh", mesh, "--max-distance", "-2"}, "--max-distance"},
      {{"--cloud", cloud, "--mesh", mesh, "--iterations", "0"}, "--iterations"},
      {{"--cloud", cloud, "--mesh", mesh, "--init-rotation", "1 2"}, "--init-rotation: expected 3 numbers"},
      {{"--cloud", cloud, "--mesh", mesh, "--init-translation", "1 x 3"}, "--init-translation: 'x' is not a finite number"},
      {{"--cloud", cloud, "--mesh", mesh, "--init", f.tmp / "missing.txt"}, "missing.txt: cannot open transform file"},
      {{"--cloud", cloud, "--mesh", mesh, "--init", f.tmp / "x.txt", "--init-translation", "1 2 3"}, "excludes"},
      // Identity start: the cloud is ~400 mm from the phantom, beyond a 10 mm limit.
      {{"--cloud", cloud, "--mesh", mesh, "--max-distance", "10"}, "within the maximum distance"},
  };
  for (const auto& c : cases) {
    std::vector<std::string> args = {"register", "icp", "--out", f.tmp / "T.txt", "--report", f.tmp / "report.json",
                                     "--aligned", f.tmp / "aligned.vtp"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const RunResult r = runViscera(args);
    EXPECT_EQ(r.rc, 2) << c.expect << "\n" << r;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << "expected '" << c.expect << "'\n" << r;
    for (const char* out : {"T.txt", "report.json", "aligned.vtp"}) EXPECT_FALSE(fs::exists(f.tmp / out)) << c.expect;
  }
  // An output folder that does not exist: rejected before the other outputs are written.
  const RunResult r = runViscera({"register", "icp", "--cloud", cloud, "--mesh", mesh, "--out", f.tmp / "T.txt", "--report",
                                  f.tmp / "none/report.json"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("--report: the folder"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(f.tmp / "T.txt"));
}

}  // namespace
