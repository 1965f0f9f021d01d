// `viscera trajectory`: writes a readable palpation CSV from --box or --mesh; bad options exit
// with code 2, name the option and write nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "motion/Trajectory.h"
#include "tests/apps/cli_helpers.h"

using namespace viscera_test;

namespace {

const std::string kPhantom = "0 0 0 68.7 35.8 39.3";

TEST(TrajectoryCli, WritesAReadableCsv) {
  TempDir tmp;
  const std::string out = tmp / "poke.csv";
  RunResult r = runViscera({"trajectory", "--box", kPhantom, "--duration", "20", "--out", out});
  ASSERT_EQ(r.rc, 0) << r;
  const auto tr = viscera::motion::readTrajectoryCsv(out);
  EXPECT_EQ(tr.size(), 20 * 30 + 1);
  EXPECT_EQ(tr.start(), 0.0);
  EXPECT_NEAR(tr.end(), 20.0, 1e-9);
  EXPECT_EQ(lines(slurp(out)).front(), "t,x,y,z,qx,qy,qz,qw");
  EXPECT_NE(r.err.find("wrote 601 samples ("), std::string::npos) << r;
  EXPECT_NE(r.err.find(" poke"), std::string::npos) << r;
  EXPECT_NE(r.err.find("over 20 s to " + out), std::string::npos) << r;
  // Nothing but the CSV in the folder (no temporary file left behind).
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(tmp.path())) files.push_back(e.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"poke.csv"});
}

TEST(TrajectoryCli, SeedAndOptions) {
  TempDir tmp;
  auto run = [&](const std::string& name, std::vector<std::string> extra) {
    std::vector<std::string> args = {"trajectory", "--box", kPhantom, "--duration", "30", "--out", tmp / name};
    args.insert(args.end(), extra.begin(), extra.end());
    RunResult r = runViscera(args);
    EXPECT_EQ(r.rc, 0) << r;
    return r;
  };
  run("a.csv", {"--seed", "5"});
  run("b.csv", {"--seed", "5"});
  run("c.csv", {"--seed", "6"});
  EXPECT_EQ(slurp(tmp / "a.csv"), slurp(tmp / "b.csv"));
  EXPECT_NE(slurp(tmp / "a.csv"), slurp(tmp / "c.csv"));

  run("rate.csv", {"--rate", "10"});
  EXPECT_EQ(viscera::motion::readTrajectoryCsv(tmp / "rate.csv").size(), 301);

  RunResult top = run("top.csv", {"--faces", "top", "--radius", "3", "--depth", "2", "--jitter", "0", "--speed", "5",
                                  "--travel-speed", "20", "--dwell", "0.5", "--rest", "0.2", "--lift", "4", "--margin", "0.1"});
  EXPECT_NE(top.err.find(" top)"), std::string::npos) << top;
  for (const char* side : {"x-", "x+", "y-", "y+"}) EXPECT_EQ(top.err.find(side), std::string::npos) << top;
  // Top pokes only, 2 deep with a radius-3 sphere: the lowest centre is 39.3 + 3 - 2.
  const auto tr = viscera::motion::readTrajectoryCsv(tmp / "top.csv");
  double lowest = INFINITY;
  for (const auto& p : tr.p) lowest = std::min(lowest, p.z());
  EXPECT_NEAR(lowest, 40.3, 1e-9);

  RunResult sides = run("sides.csv", {"--faces", "x-, y+", "--seed", "3"});
  EXPECT_EQ(sides.err.find("top"), std::string::npos) << sides;
}

TEST(TrajectoryCli, BoxFromAMesh) {
  TempDir tmp;
  const std::string out = tmp / "cube.csv";
  // The unit cube, poked by a small sphere.
  RunResult r = runViscera({"trajectory", "--mesh", sourcePath("tests/data/meshes/cube_v41.msh"), "--radius", "0.1", "--depth",
                            "0.05", "--lift", "0.2", "--speed", "0.5", "--travel-speed", "2", "--duration", "20", "--out", out});
  ASSERT_EQ(r.rc, 0) << r;
  const auto tr = viscera::motion::readTrajectoryCsv(out);
  ASSERT_GT(tr.size(), 0);
  // The first sample is the first approach point: 0.2 from the cube's surface.
  const Eigen::Vector3d d = (-tr.p[0]).cwiseMax(tr.p[0] - Eigen::Vector3d::Ones());
  EXPECT_NEAR(d.cwiseMax(0.0).norm() - 0.1, 0.2, 1e-9);
}

// Runs a bad command line; it must exit 2, name `mention` on stderr and write nothing.
void expectRejected(const std::vector<std::string>& args, const std::string& mention) {
  TempDir tmp;
  std::vector<std::string> all = {"trajectory", "--out", tmp / "out.csv"};
  all.insert(all.end(), args.begin(), args.end());
  RunResult r = runViscera(all);
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find(mention), std::string::npos) << "expected '" << mention << "' in\n" << r;
  EXPECT_TRUE(fs::is_empty(tmp.path())) << "wrote output for a bad command line:\n" << r;
}

TEST(TrajectoryCli, BadOptionsExitTwoAndWriteNothing) {
  expectRejected({"--box", "1 2 3"}, "--box");
  expectRejected({"--box", "0 0 0 10 10 abc"}, "--box");
  expectRejected({"--box", "0 0 0 10 -10 10"}, "--box");
  expectRejected({"--box", kPhantom, "--rate", "0"}, "--rate");
  expectRejected({"--box", kPhantom, "--radius", "-1"}, "--radius");
  expectRejected({"--box", kPhantom, "--depth", "30"}, "--depth");
  expectRejected({"--box", kPhantom, "--jitter", "1"}, "--jitter");
  expectRejected({"--box", kPhantom, "--margin", "0.5"}, "--margin");
  expectRejected({"--box", kPhantom, "--travel-speed", "0"}, "--travel-speed");
  expectRejected({"--box", kPhantom, "--duration", "1"}, "--duration");
  expectRejected({"--box", kPhantom, "--faces", "top,z-"}, "--faces");
  expectRejected({"--box", kPhantom, "--faces", "side"}, "--faces");
  expectRejected({"--box", kPhantom, "--speed", "fast"}, "--speed");
  expectRejected({}, "--box");                                             // no specimen
  expectRejected({"--box", kPhantom, "--mesh", sourcePath("tests/data/meshes/cube_v41.msh")}, "--mesh");
  expectRejected({"--mesh", sourcePath("tests/data/no_such_mesh.msh")}, "no_such_mesh.msh");
}

TEST(TrajectoryCli, OutIsRequired) {
  RunResult r = runViscera({"trajectory", "--box", kPhantom});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("--out"), std::string::npos) << r;
}

TEST(TrajectoryCli, HelpNamesTheUnits) {
  RunResult r = runViscera({"trajectory", "--help"});
  EXPECT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.out.find("units=\"mm g s\""), std::string::npos) << r;
  EXPECT_NE(r.out.find("--travel-speed"), std::string::npos) << r;
}

}  // namespace
