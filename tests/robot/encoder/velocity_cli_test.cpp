// `viscera velocity compare` end to end: the files it writes (CSV, JSON, the gnuplot script and
// PNG), a motion read from a CSV, option errors with exit code 2 and nothing written, and a
// missing gnuplot.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include "tests/apps/cli_helpers.h"

using namespace viscera_test;

namespace {

// Whether a program is on PATH.
bool onPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  if (!path) return false;
  std::string dirs = path;
  size_t start = 0;
  while (start <= dirs.size()) {
    const size_t end = std::min(dirs.find(':', start), dirs.size());
    const fs::path candidate = fs::path(dirs.substr(start, end - start)) / program;
    if (::access(candidate.c_str(), X_OK) == 0) return true;
    start = end + 1;
  }
  return false;
}

// The number after "key": in a JSON text (NaN if absent).
double jsonNumber(const std::string& json, const std::string& key, size_t from = 0) {
  size_t p = json.find("\"" + key + "\": ", from);
  if (p == std::string::npos) return std::nan("");
  return std::strtod(json.c_str() + p + key.size() + 4, nullptr);
}

// Everything in a folder.
std::vector<std::string> entries(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

void write(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// Runs with PATH set to `path` for the duration of the call.
RunResult runWithPath(const std::string& path, const std::vector<std::string>& args) {
  const std::string saved = std::getenv("PATH") ? std::getenv("PATH") : "";
  ::setenv("PATH", path.c_str(), 1);
  RunResult r = runViscera(args);
  ::setenv("PATH", saved.c_str(), 1);
  return r;
}

}  // namespace

TEST(VelocityCli, WritesTheTableAndTheRmsOrderingHolds) {
  TempDir tmp;
  const std::string out = tmp / "bench";
  const RunResult r = runViscera({"velocity", "compare", "--out", out, "--no-plot"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_EQ(entries(out), (std::vector<std::string>{"summary.json", "velocity.csv"}));

  const auto csv = lines(slurp(out + "/velocity.csv"));
  ASSERT_EQ(csv.size(), 4002u);  // header and 4 s of reads at 1 kHz, both ends included
  EXPECT_EQ(csv[0], "t,exact,truth,fixed_time,quarter,full,full_acc");
  EXPECT_EQ(csv[1000].substr(0, 6), "0.999,");  // row 1000 is read 999: t = 0.999 s

  const std::string json = slurp(out + "/summary.json");
  const double quarter = jsonNumber(json, "vs_truth", json.find("\"quarter\""));
  const double full = jsonNumber(json, "vs_truth", json.find("\"full\""));
  const double fullAcc = jsonNumber(json, "vs_truth", json.find("\"full_acc\""));
  EXPECT_GT(quarter, full);
  EXPECT_GT(full, fullAcc);
  EXPECT_LE(fullAcc, 0.6 * quarter);
  EXPECT_EQ(jsonNumber(json, "reads"), 4001);
  EXPECT_EQ(jsonNumber(json, "lines", json.find("\"test_encoder\"")), 16);
  EXPECT_NE(json.find("\"format\": \"rev6\""), std::string::npos);
  // The table on stdout names every estimator.
  for (const char* name : {"fixed_time", "quarter", "full", "full_acc", "vs 600-line", "vs exact"})
    EXPECT_NE(r.out.find(name), std::string::npos) << name;
}

TEST(VelocityCli, Rev7AddsTheRunningCounterEstimate) {
  TempDir tmp;
  const RunResult r = runViscera({"velocity", "compare", "--out", tmp.str(), "--no-plot", "--format", "rev7", "--duration", "1",
                                  "--rate", "500"});
  ASSERT_EQ(r.rc, 0) << r;
  const auto csv = lines(slurp(tmp / "velocity.csv"));
  ASSERT_EQ(csv.size(), 502u);
  EXPECT_EQ(csv[0], "t,exact,truth,fixed_time,quarter,full,full_acc,full_acc_running");
  EXPECT_NE(slurp(tmp / "summary.json").find("\"full_acc_running\""), std::string::npos);
}

TEST(VelocityCli, ReadsAMotionCsv) {
  TempDir tmp;
  // 2 s of theta = 3 sin(2 pi 0.5 t) rad sampled at 200 Hz.
  std::string text = "t,theta\n";
  for (int k = 0; k <= 400; ++k) {
    const double t = k / 200.0;
    text += std::to_string(t) + "," + std::to_string(3 * std::sin(std::numbers::pi * t)) + "\n";
  }
  write(tmp / "motion.csv", text);
  const RunResult r = runViscera({"velocity", "compare", "--out", tmp / "out", "--no-plot", "--motion", tmp / "motion.csv"});
  ASSERT_EQ(r.rc, 0) << r;
  const std::string json = slurp(tmp / "out/summary.json");
  EXPECT_EQ(jsonNumber(json, "reads"), 2001);
  EXPECT_EQ(jsonNumber(json, "end_s"), 2);
  EXPECT_NE(json.find("motion.csv"), std::string::npos);
}

TEST(VelocityCli, BadOptionsExitWithTwoAndWriteNothing) {
  TempDir tmp;
  write(tmp / "backwards.csv", "t,theta\n0,0\n0.5,1\n0.4,2\n");
  const struct {
    std::vector<std::string> args;
    std::string message;
  } cases[] = {
      {{"--rate", "0"}, "--rate"},
      {{"--duty-a", "1.5"}, "--duty-a"},
      {{"--phase", "200"}, "--phase"},
      {{"--lines", "-4"}, "--lines"},
      {{"--format", "rev9"}, "--format"},
      {{"--duration", "0"}, "--duration"},
      {{"--acc-threshold", "-1"}, "--acc-threshold"},
      {{"--motion", tmp / "missing.csv"}, "missing.csv"},
      {{"--motion", tmp / "backwards.csv"}, "backwards.csv:4:1: t must increase"},
      {{"--motion", tmp / "backwards.csv", "--duration", "2"}, "excludes"},
      {{"--rate", "fast"}, "--rate"},
  };
  for (const auto& c : cases) {
    std::vector<std::string> args = {"velocity", "compare", "--out", tmp / "out", "--no-plot"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const RunResult r = runViscera(args);
    EXPECT_EQ(r.rc, 2) << r;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r;
    EXPECT_TRUE(absentOrEmpty(tmp / "out")) << c.message;
  }
  // `velocity` needs its subcommand; `compare` needs --out.
  EXPECT_EQ(runViscera({"velocity"}).rc, 2);
  EXPECT_EQ(runViscera({"velocity", "compare"}).rc, 2);
}

TEST(VelocityCli, PlotsWithGnuplot) {
  if (!onPath("gnuplot")) GTEST_SKIP() << "gnuplot is not installed";
  TempDir tmp;
  const RunResult r = runViscera({"velocity", "compare", "--out", tmp.str(), "--duration", "1"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_EQ(entries(tmp.str()), (std::vector<std::string>{"summary.json", "velocity.csv", "velocity.gp", "velocity.png"}));
  const std::string png = slurp(tmp / "velocity.png");
  ASSERT_GT(png.size(), 1000u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  // The script re-plots from the folder it sits in.
  EXPECT_NE(slurp(tmp / "velocity.gp").find("\"velocity.csv\""), std::string::npos);
}

TEST(VelocityCli, MissingGnuplotIsAnErrorAfterTheTables) {
  TempDir tmp, emptyBin;
  const RunResult r = runWithPath(emptyBin.str(), {"velocity", "compare", "--out", tmp / "out", "--duration", "1"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("gnuplot was not found"), std::string::npos) << r;
  EXPECT_NE(r.err.find("--no-plot"), std::string::npos) << r;
  // The CSV and JSON are there, no image and no temporary file.
  EXPECT_EQ(entries(tmp / "out"), (std::vector<std::string>{"summary.json", "velocity.csv", "velocity.gp"}));
}
