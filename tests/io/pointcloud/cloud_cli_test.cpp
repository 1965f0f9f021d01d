// `viscera cloud prep` and `viscera cloud info` on a synthetic capture: a file, a sequence, and bad
// input (exit code 2, the file or option named, no output left behind).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "io/pointcloud/CloudIo.h"
#include "tests/apps/cli_helpers.h"
#include "tests/io/pointcloud/synthetic_capture.h"

using namespace viscera_test;
using namespace viscera::cloud;

namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

void writeText(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

// The synthetic capture written as a binary .pcd (float32, as a camera driver writes it).
std::string writeCapture(const TempDir& tmp, const std::string& name, unsigned seed = 7) {
  const std::string path = tmp / name;
  writeCloud(path, makeCapture(seed).cloud);
  return path;
}

TEST(CloudCli, PrepFileWritesTheSpecimenAndAReport) {
  TempDir tmp;
  const std::string in = writeCapture(tmp, "scan.pcd");
  const RunResult r = runViscera({"cloud", "prep", in, tmp / "phantom.ply", "--target", "3000", "--report", tmp / "report.json"});
  ASSERT_EQ(r.rc, 0) << r;
  const PointCloud out = readCloud(tmp / "phantom.ply");
  EXPECT_LE(out.size(), 3000);
  EXPECT_GE(out.size(), 2970);  // within 1 % below the target
  const int inputCount = makeCapture().cloud.size();
  EXPECT_TRUE(contains(r.err, "scan.pcd: " + std::to_string(inputCount) + " -> " + std::to_string(out.size()))) << r;
  const std::string report = slurp(tmp / "report.json");
  EXPECT_TRUE(contains(report, "\"output\": " + std::to_string(out.size()) + "}")) << report;
  EXPECT_TRUE(contains(report, "\"kept_rank\": 1")) << report;
  EXPECT_TRUE(contains(report, "\"plane\": {\"coefficients\": [")) << report;
}

TEST(CloudCli, PrepSequenceKeepsTheTimes) {
  TempDir tmp;
  fs::create_directory(tmp / "capture");
  writeCapture(tmp, "capture/a.pcd", 1);
  writeCapture(tmp, "capture/b.pcd", 2);
  writeText(tmp / "capture/index.csv", "time,file\n0.5,a.pcd\n0.5333333333333333,b.pcd\n");
  const RunResult r = runViscera({"cloud", "prep", tmp / "capture", tmp / "prepared", "--target", "2000", "--report", tmp / "r.json"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_TRUE(contains(r.err, "[1/2] t = 0.5 s")) << r;
  EXPECT_TRUE(contains(r.err, "[2/2]")) << r;
  const auto frames = listCloudSequence(tmp / "prepared");
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].time, 0.5);
  EXPECT_EQ(frames[1].time, 0.5333333333333333);
  EXPECT_EQ(fs::path(frames[1].path).filename(), "frame_000001.pcd");
  for (const auto& f : frames) EXPECT_LE(readCloud(f.path).size(), 2000);
  EXPECT_TRUE(contains(slurp(tmp / "r.json"), "\"time\": 0.5333333333")) << slurp(tmp / "r.json");

  // --quiet: no progress lines.
  const RunResult q = runViscera({"cloud", "prep", tmp / "capture/index.csv", tmp / "again", "--target", "2000", "--quiet"});
  ASSERT_EQ(q.rc, 0) << q;
  EXPECT_EQ(q.err, "");
}

TEST(CloudCli, InfoDescribesFilesAndSequences) {
  TempDir tmp;
  PointCloud c;
  c.points.resize(3, 4);
  c.points << 0, 2, 0, 2,  //
      0, 0, 4, 4,          //
      1, 1, 1, 5;
  writeCloud(tmp / "c.pcd", c, CloudEncoding::Ascii);
  const RunResult r = runViscera({"cloud", "info", tmp / "c.pcd"});
  ASSERT_EQ(r.rc, 0) << r;
  EXPECT_TRUE(contains(r.out, "format    pcd ascii")) << r;
  EXPECT_TRUE(contains(r.out, "fields    x y z\n")) << r;
  EXPECT_TRUE(contains(r.out, "points    4\n")) << r;
  EXPECT_TRUE(contains(r.out, "min (0 0 1)  max (2 4 5)")) << r;
  EXPECT_TRUE(contains(r.out, "centroid  (1 2 2)")) << r;  // by hand: means of the columns above

  fs::create_directory(tmp / "seq");
  writeCloud(tmp / "seq/frame_0.25.pcd", c);
  writeCloud(tmp / "seq/frame_0.5.pcd", c);
  const RunResult s = runViscera({"cloud", "info", tmp / "seq"});
  ASSERT_EQ(s.rc, 0) << s;
  EXPECT_TRUE(contains(s.out, "frames    2, t = 0.25 .. 0.5 s")) << s;
  EXPECT_TRUE(contains(s.out, "times from the file names")) << s;
  EXPECT_EQ(lines(s.out).size(), 5u) << s;  // sequence, frames, column titles, two frames
}

TEST(CloudCli, BadInputExitsTwoAndWritesNothing) {
  TempDir tmp;
  const std::string good = writeCapture(tmp, "good.pcd");
  writeText(tmp / "empty.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 0\nHEIGHT 1\nPOINTS 0\nDATA ascii\n");
  writeText(tmp / "nan.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\nnan 0 0\n");
  struct Case {
    std::vector<std::string> args;
    std::string expected;
  };
  const std::string out = tmp / "out.pcd";
  const std::vector<Case> cases = {
      {{tmp / "missing.pcd", out}, tmp / "missing.pcd: no such file"},
      {{tmp / "empty.pcd", out}, tmp / "empty.pcd: the cloud has no points"},
      {{tmp / "nan.pcd", out}, tmp / "nan.pcd: point 1 has a non-finite coordinate"},
      {{good, out, "--cluster-tolerance", "-1"}, "--cluster-tolerance"},
      {{good, out, "--target", "many"}, "--target"},
      {{good, out, "--crop", "0 0 0 1 1"}, "--crop: expected 6 numbers"},
      {{good, out, "--keep-rank", "50"}, "--keep-rank 50"},
      {{good, out, "--report", tmp / "no/dir/r.json"}, "does not exist"},
      {{good, tmp / "out.txt"}, "must be a .pcd or .ply file name"},
      {{good, out, "--format", "xyz"}, "--format"},
  };
  for (const auto& c : cases) {
    std::vector<std::string> args = {"cloud", "prep"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const RunResult r = runViscera(args);
    EXPECT_EQ(r.rc, 2) << c.expected << "\n" << r;
    EXPECT_TRUE(contains(r.err, c.expected)) << r;
    EXPECT_FALSE(fs::exists(out)) << c.expected;
    EXPECT_FALSE(fs::exists(tmp / "out.txt"));
  }
  // The NaN file goes through with --drop-nan (one point left: too few for a plane).
  const RunResult d = runViscera({"cloud", "prep", tmp / "nan.pcd", out, "--drop-nan"});
  EXPECT_EQ(d.rc, 2) << d;
  EXPECT_TRUE(contains(d.err, "no plane found")) << d;
  EXPECT_TRUE(contains(runViscera({"cloud", "info", tmp / "nan.pcd"}).out, "points    1 (1 non-finite not counted)"));
}

TEST(CloudCli, FailedSequenceLeavesNoPartialOutput) {
  TempDir tmp;
  fs::create_directory(tmp / "capture");
  writeCapture(tmp, "capture/frame_1.pcd");
  writeText(tmp / "capture/frame_2.pcd", "garbage\n");
  const RunResult r = runViscera({"cloud", "prep", tmp / "capture", tmp / "prepared", "--target", "1000"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_TRUE(contains(r.err, tmp / "capture/frame_2.pcd:1:")) << r;
  EXPECT_TRUE(contains(r.err, "stopped at frame 2 of 2")) << r;
  EXPECT_FALSE(fs::exists(tmp / "prepared")) << r;

  // Writing into the input folder would overwrite it.
  fs::remove(tmp / "capture/frame_2.pcd");
  const RunResult same = runViscera({"cloud", "prep", tmp / "capture", tmp / "capture"});
  EXPECT_EQ(same.rc, 2) << same;
  EXPECT_TRUE(contains(same.err, "holds input frames")) << same;
}

}  // namespace
