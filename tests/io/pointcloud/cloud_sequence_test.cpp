// listCloudSequence (index.csv, times from file names) and CloudSequenceWriter, with the errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/ErrorOf.h"
#include "core/Error.h"
#include "io/pointcloud/CloudIo.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using namespace viscera::cloud;
using viscera::test_support::TempDir;
namespace fs = std::filesystem;

namespace {

using viscera::test_support::errorOf;

void writeText(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Frame files only need to exist for listing (they are not read).
void touch(const std::string& path) { writeText(path, "placeholder\n"); }

PointCloud oneFramePoint(double x) {
  PointCloud c;
  c.points = Eigen::Vector3d(x, 0, 0);
  return c;
}

TEST(CloudSequence, ListsByIndex) {
  TempDir tmp;
  fs::create_directory(tmp / "sub");
  for (const char* f : {"b.pcd", "a.ply", "sub/c.pcd"}) touch(tmp / f);
  // Index order is kept (not the name order); comments and blank lines are skipped; CRLF is fine.
  writeText(tmp / "index.csv", "time,file\r\n# first frame\n0.5,b.pcd\n\n0.75 , a.ply\n1e3,sub/c.pcd\n");
  for (const std::string& where : {tmp.str(), tmp / "index.csv"}) {
    const auto frames = listCloudSequence(where);
    ASSERT_EQ(frames.size(), 3u) << where;
    EXPECT_EQ(frames[0].time, 0.5);
    EXPECT_EQ(frames[1].time, 0.75);
    EXPECT_EQ(frames[2].time, 1000.0);
    EXPECT_TRUE(fs::equivalent(frames[0].path, tmp / "b.pcd"));
    EXPECT_TRUE(fs::equivalent(frames[1].path, tmp / "a.ply"));
    EXPECT_TRUE(fs::equivalent(frames[2].path, tmp / "sub/c.pcd"));
  }
}

TEST(CloudSequence, IndexErrorsNameFileAndLine) {
  TempDir tmp;
  touch(tmp / "a.pcd");
  touch(tmp / "b.pcd");
  const std::string index = tmp / "index.csv";
  struct Case {
    std::string content, expected;
  };
  const std::vector<Case> cases = {
      {"t,f\n0,a.pcd\n", index + ":1: expected the header line 'time,file'"},
      {"time,file\n0,a.pcd\nabc,b.pcd\n", index + ":3: time 'abc' is not a finite number"},
      {"time,file\n0,a.pcd\nnan,b.pcd\n", index + ":3: time 'nan'"},
      {"time,file\n1,a.pcd\n# c\n1,b.pcd\n", index + ":4: time 1 is not after the time 1 of line 2"},
      {"time,file\n1,a.pcd\n0.5,b.pcd\n", index + ":3: time 0.5 is not after"},
      {"time,file\n0,missing.pcd\n", index + ":2: frame file"},
      {"time,file\n0,a.txt\n", index + ":2: 'a.txt' is not a .pcd or .ply file"},
      {"time,file\n0 a.pcd\n", index + ":2: expected 'time,file'"},
      {"time,file\n0,\n", index + ":2: no file name"},
      {"time,file\n", index + ": the index lists no frames"},
      {"", index + ": the index file is empty"},
  };
  for (const auto& c : cases) {
    writeText(index, c.content);
    const std::string e = errorOf([&] { listCloudSequence(tmp.str()); });
    EXPECT_EQ(e.rfind(c.expected, 0), 0u) << c.content << "-> " << e;
  }
}

TEST(CloudSequence, ListsByNames) {
  TempDir tmp;
  for (const char* f : {"frame_12.5.pcd", "frame_2.pcd", "frame_0.033.PLY", "notes.txt", "cloud-7.pcd"}) touch(tmp / f);
  const auto frames = listCloudSequence(tmp.str());
  ASSERT_EQ(frames.size(), 4u);  // notes.txt is not a cloud
  EXPECT_EQ(frames[0].time, 0.033);
  EXPECT_EQ(frames[1].time, 2.0);
  EXPECT_EQ(frames[2].time, 7.0);  // '-' separates words, it is not a minus sign
  EXPECT_EQ(frames[3].time, 12.5);
  EXPECT_EQ(fs::path(frames[2].path).filename(), "cloud-7.pcd");

  // Nanosecond stamps with a scale.
  TempDir ns;
  touch(ns / "cam_1700000000500000000.pcd");
  touch(ns / "cam_1700000000000000000.pcd");
  const auto stamped = listCloudSequence(ns.str(), 1e-9);
  ASSERT_EQ(stamped.size(), 2u);
  EXPECT_NEAR(stamped[1].time - stamped[0].time, 0.5, 1e-6);  // doubles near 1.7e9 s resolve ~2e-7 s
}

TEST(CloudSequence, NameErrors) {
  TempDir tmp;
  EXPECT_NE(errorOf([&] { listCloudSequence(tmp.str()); }).find("no .pcd or .ply files"), std::string::npos);
  touch(tmp / "frame_1.pcd");
  touch(tmp / "frame_1.0.ply");
  std::string e = errorOf([&] { listCloudSequence(tmp.str()); });
  EXPECT_NE(e.find("frame_1.0.ply and frame_1.pcd have the same time 1"), std::string::npos) << e;
  fs::remove(tmp / "frame_1.0.ply");
  touch(tmp / "last.pcd");
  e = errorOf([&] { listCloudSequence(tmp.str()); });
  EXPECT_EQ(e.rfind(tmp / "last.pcd", 0), 0u) << e;
  EXPECT_NE(e.find("no number in the file name"), std::string::npos) << e;

  EXPECT_NE(errorOf([&] { listCloudSequence(tmp / "missing"); }).find("no such folder or index file"), std::string::npos);
  EXPECT_NE(errorOf([&] { listCloudSequence(tmp / "frame_1.pcd"); }).find("single cloud file"), std::string::npos);
  EXPECT_NE(errorOf([&] { listCloudSequence(tmp.str(), 0.0); }).find("time scale"), std::string::npos);
}

TEST(CloudSequence, WriterWritesFramesAndIndex) {
  TempDir tmp;
  const std::string folder = tmp / "out/seq";  // created, parents included
  CloudSequenceWriter w(folder);
  const std::string first = w.add(oneFramePoint(1), 0.1);
  EXPECT_EQ(fs::path(first).filename(), "frame_000000.pcd");
  // The index is rewritten after every frame: after one frame it lists one.
  EXPECT_EQ(slurp(folder + "/index.csv"), "time,file\n0.1,frame_000000.pcd\n");
  w.add(oneFramePoint(2), 0.2);
  w.add(oneFramePoint(3), 1.0 / 3.0);
  EXPECT_NE(errorOf([&] { w.add(oneFramePoint(4), 0.3); }).find("not after"), std::string::npos);
  ASSERT_EQ(w.frames().size(), 3u);

  const auto frames = listCloudSequence(folder);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[2].time, 1.0 / 3.0);  // times are written to round-trip exactly
  for (int i = 0; i < 3; ++i) {
    EXPECT_TRUE(fs::equivalent(frames[i].path, w.frames()[i].path));
    EXPECT_EQ(readCloud(frames[i].path).points(0, 0), i + 1.0);
  }

  CloudSequenceWriter ply(tmp / "plys", "scan", "ply", CloudEncoding::Ascii);
  EXPECT_EQ(fs::path(ply.add(oneFramePoint(1), 0)).filename(), "scan_000000.ply");
  EXPECT_NE(errorOf([&] { CloudSequenceWriter(tmp / "x", "frame", "xyz"); }).find("must be .pcd or .ply"), std::string::npos);
}

}  // namespace
