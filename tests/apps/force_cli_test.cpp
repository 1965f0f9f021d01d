// `viscera force`: a simulated palpation through the whole command chain (simulate, identify,
// evaluate, estimate), with known truth; bad logs exit 2 naming file and line, and nothing is left
// half-written.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "robot/force/ArmLogs.h"
#include "tests/apps/cli_helpers.h"

using namespace viscera_test;

namespace {

TEST(ForceCli, SimulateIdentifyEvaluateEstimate) {
  TempDir dir("viscera_force");
  RunResult r = runViscera({"force", "simulate", dir / "free", "--duration", "90", "--seed", "1"});
  ASSERT_EQ(r.rc, 0) << r;
  r = runViscera({"force", "simulate", dir / "press", "--duration", "30", "--seed", "2", "--phantom", "--jacobian"});
  ASSERT_EQ(r.rc, 0) << r;
  for (const char* f : {"joints.csv", "wrench.csv", "jacobian.csv", "truth.csv", "simulation.json"})
    EXPECT_TRUE(fs::exists(fs::path(dir / "press") / f)) << f;
  r = runViscera({"force", "train", dir / "free", "--kind", "physical", "--out", dir / "model"});
  ASSERT_EQ(r.rc, 0) << r;
  r = runViscera({"force", "eval", dir / "model", dir / "press", "--out", dir / "eval", "--no-plot"});
  ASSERT_EQ(r.rc, 0) << r;
  const auto report = nlohmann::json::parse(slurp(fs::path(dir / "eval") / "eval.json"));
  for (const char* axis : {"Fx", "Fy", "Fz"}) EXPECT_TRUE(report["all"]["wrench"][axis]["rmse"].is_number()) << axis;
  EXPECT_TRUE(report["recordings"][0]["stiffness"].contains("fromTrueForces")) << report.dump(2);
  // While the tool presses (|F| > 1 N) the estimate follows the true force: its error is a small
  // share of the force (a model that estimated nothing would have a share of 1).
  std::istringstream csv(slurp(fs::path(dir / "eval") / "estimates.csv"));
  std::string line;
  std::getline(csv, line);
  double error2 = 0, force2 = 0;
  int pressing = 0;
  while (std::getline(csv, line)) {
    std::vector<double> v;
    std::istringstream fields(line);
    for (std::string f; std::getline(fields, f, ',');) v.push_back(std::stod(f));
    ASSERT_EQ(v.size(), 2u + 12 + 12);
    Eigen::Vector3d F(v[14], v[16], v[18]), Fhat(v[15], v[17], v[19]);
    if (F.norm() <= 1) continue;
    error2 += (Fhat - F).squaredNorm();
    force2 += F.squaredNorm();
    ++pressing;
  }
  ASSERT_GT(pressing, 100);
  EXPECT_LT(std::sqrt(error2 / force2), 0.4);
  r = runViscera({"force", "estimate", dir / "model", fs::path(dir / "press") / "joints.csv", "--out", dir / "w.csv",
                  "--jacobian", fs::path(dir / "press") / "jacobian.csv"});
  ASSERT_EQ(r.rc, 0) << r;
  const viscera::robot::Series w = viscera::robot::readWrenchCsv(dir / "w.csv");
  EXPECT_EQ(w.samples(), 30 * 200 + 1);  // at the model's 200 Hz
}

TEST(ForceCli, BadLogsExit2NamingFileAndLine) {
  TempDir dir("viscera_force_bad");
  std::ofstream(dir / "back.csv") << "0,0,0,0.1,0,0,0,0,0,0,0,0,0,1,1,1,0,0,0\n"
                                     "0.001,0,0,0.1,0,0,0,0,0,0,0,0,0,1,1,1,0,0,0\n"
                                     "0.0005,0,0,0.1,0,0,0,0,0,0,0,0,0,1,1,1,0,0,0\n";
  RunResult r = runViscera({"force", "train", dir / "back.csv", "--kind", "physical", "--out", dir / "m"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("back.csv:3"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(dir / "m"));
  std::ofstream(dir / "short.csv") << "0,1,2,3\n";
  r = runViscera({"force", "train", dir / "short.csv", "--kind", "physical", "--out", dir / "m"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("short.csv:1: 4 columns"), std::string::npos) << r;
  r = runViscera({"force", "train", dir / "short.csv", "--kind", "magic", "--out", dir / "m"});
  EXPECT_EQ(r.rc, 2) << r;
  std::ofstream(dir / "file") << "x";
  r = runViscera({"force", "simulate", dir / "file", "--duration", "1"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_EQ(slurp(dir / "file"), "x");
}

TEST(ForceCli, OutputFoldersNeverSwallowInputsOrOtherFiles) {
  TempDir dir("viscera_force_out");
  fs::create_directories(fs::path(dir / "parent"));
  RunResult r = runViscera({"force", "simulate", fs::path(dir / "parent") / "rec", "--duration", "3"});
  ASSERT_EQ(r.rc, 0) << r;
  // --out above an input: refused, the input kept.
  r = runViscera({"force", "train", fs::path(dir / "parent") / "rec", "--kind", "physical", "--out", dir / "parent"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("holds the input"), std::string::npos) << r;
  EXPECT_TRUE(fs::exists(fs::path(dir / "parent") / "rec" / "joints.csv"));
  // A folder of other things: refused; one the command wrote before: replaced.
  fs::create_directories(fs::path(dir / "mine"));
  std::ofstream(fs::path(dir / "mine") / "notes.txt") << "keep";
  r = runViscera({"force", "simulate", dir / "mine", "--duration", "1"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_EQ(slurp(fs::path(dir / "mine") / "notes.txt"), "keep");
  r = runViscera({"force", "simulate", fs::path(dir / "parent") / "rec", "--duration", "2"});
  EXPECT_EQ(r.rc, 0) << r;
  // Options that would do nothing are refused.
  r = runViscera({"force", "simulate", dir / "s", "--duration", "1", "--stiffness", "300"});
  EXPECT_EQ(r.rc, 2) << r;
  r = runViscera({"force", "simulate", dir / "s", "--duration", "1", "--digits", "40"});
  EXPECT_EQ(r.rc, 2) << r;
  for (const char* step : {"0", "1.5"}) {
    r = runViscera({"force", "simulate", dir / "s", "--duration", "1", "--step", step});
    EXPECT_EQ(r.rc, 2) << r;
    EXPECT_NE(r.err.find("--step"), std::string::npos) << r;
  }
  r = runViscera({"force", "simulate", dir / "s", "--duration", "1", "--step", "0.5"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_NE(slurp(fs::path(dir / "s") / "simulation.json").find("\"step\": 0.5"), std::string::npos);
}

}  // namespace
