// readCloud / writeCloud: PCD and PLY round trips (binary and ASCII, with and without normals),
// files written by hand (float32, float64, organized with NaN), and malformed files.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
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

void writeText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Random points at a scale where float32 rounding shows (~400 mm, 1e-7 mm digits), unit normals.
PointCloud randomCloud(int n, bool normals, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-400, 400);
  PointCloud c;
  c.points.resize(3, n);
  for (int i = 0; i < n; ++i) c.points.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng)) + Eigen::Vector3d(1e-7, 0, 0);
  if (normals) {
    c.normals.resize(3, n);
    for (int i = 0; i < n; ++i) c.normals.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
  }
  return c;
}

// The values a float32 file holds: each double rounded to float.
Eigen::Matrix3Xd floatRounded(const Eigen::Matrix3Xd& m) { return m.cast<float>().cast<double>(); }

std::string pcdHeader(const std::string& fields, const std::string& size, const std::string& type, long long width, long long height,
                      const std::string& data) {
  std::ostringstream h;
  const int nf = static_cast<int>(std::count(fields.begin(), fields.end(), ' ')) + 1;
  h << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS " << fields << "\nSIZE " << size << "\nTYPE " << type
    << "\nCOUNT";
  for (int i = 0; i < nf; ++i) h << " 1";
  h << "\nWIDTH " << width << "\nHEIGHT " << height << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << width * height << "\nDATA " << data
    << "\n";
  return h.str();
}

const char* kName[2] = {"binary", "ascii"};

TEST(CloudIo, RoundTripsAreExactToFloat32) {
  TempDir tmp;
  for (const char* ext : {"pcd", "ply"})
    for (bool normals : {false, true})
      for (CloudEncoding enc : {CloudEncoding::Binary, CloudEncoding::Ascii}) {
        const std::string path = tmp / (std::string("c_") + (normals ? "n_" : "") + kName[int(enc)] + "." + ext);
        const PointCloud c = randomCloud(500, normals, 1);
        writeCloud(path, c, enc);
        CloudFileInfo info;
        const PointCloud r = readCloud(path, {}, &info);
        SCOPED_TRACE(path);
        ASSERT_EQ(r.size(), 500);
        // Bit-exact: both formats store float32 (ASCII with 9 significant digits, enough for any float).
        EXPECT_TRUE(r.points == floatRounded(c.points));
        ASSERT_EQ(r.normals.cols(), normals ? 500 : 0);
        if (normals) {
          EXPECT_TRUE(r.normals == floatRounded(c.normals));
        }
        EXPECT_EQ(r.source, path);
        EXPECT_EQ(info.format, std::string(ext) + (enc == CloudEncoding::Ascii ? " ascii" : ext == std::string("pcd") ? " binary" : " binary_little_endian"));
        EXPECT_EQ(info.fields.size(), normals ? 6u : 3u);
        // Written atomically: nothing but the files themselves in the folder.
        for (const auto& e : fs::directory_iterator(tmp.path()))
          EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
      }
}

TEST(CloudIo, BinaryPcdLayoutIsFloat32RecordsAfterTheHeader) {
  // Read the written file without PCL: the header ends with "DATA binary\n", then x y z float32
  // per point, little-endian (the machine's order, as PCL writes it).
  TempDir tmp;
  const PointCloud c = randomCloud(7, false, 2);
  writeCloud(tmp / "c.pcd", c);
  const std::string bytes = slurp(tmp / "c.pcd");
  const std::string marker = "DATA binary\n";
  const size_t body = bytes.find(marker);
  ASSERT_NE(body, std::string::npos);
  EXPECT_NE(bytes.find("FIELDS x y z\n"), std::string::npos);
  EXPECT_NE(bytes.find("POINTS 7\n"), std::string::npos);
  for (int i = 0; i < 7; ++i)
    for (int k = 0; k < 3; ++k) {
      float f;
      std::memcpy(&f, bytes.data() + body + marker.size() + 4 * (3 * i + k), 4);
      EXPECT_EQ(f, static_cast<float>(c.points(k, i)));
    }
}

TEST(CloudIo, ReadsHandWrittenFiles) {
  TempDir tmp;
  // ASCII PCD with an extra rgb field.
  writeText(tmp / "a.pcd", pcdHeader("x y z rgb", "4 4 4 4", "F F F U", 2, 1, "ascii") + "1.5 -2 3.25 255\n4 5e2 -6e-3 0\n");
  PointCloud c = readCloud(tmp / "a.pcd");
  ASSERT_EQ(c.size(), 2);
  EXPECT_EQ(c.points.col(0), Eigen::Vector3d(1.5, -2, 3.25));
  EXPECT_EQ(c.points.col(1), Eigen::Vector3d(4, 500, double(-6e-3f)));
  EXPECT_EQ(c.normals.cols(), 0);

  // Binary PCD with float64 coordinates: doubles come through unrounded.
  const double xyz[6] = {0.1, 0.2, 0.3, 400.123456789012, -1e-9, 7};
  std::string bin = pcdHeader("x y z", "8 8 8", "F F F", 2, 1, "binary");
  bin.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
  writeText(tmp / "d.pcd", bin);
  c = readCloud(tmp / "d.pcd");
  ASSERT_EQ(c.size(), 2);
  EXPECT_EQ(c.points.col(0), Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(c.points.col(1), Eigen::Vector3d(400.123456789012, -1e-9, 7));

  // ASCII PLY with nx ny nz normals and a face element after the vertices.
  writeText(tmp / "n.ply",
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
            "property float nx\nproperty float ny\nproperty float nz\nelement face 0\n"
            "property list uchar int vertex_indices\nend_header\n1 2 3 0 0 1\n4 5 6 1 0 0\n");
  CloudFileInfo info;
  c = readCloud(tmp / "n.ply", {}, &info);
  ASSERT_EQ(c.size(), 2);
  ASSERT_EQ(c.normals.cols(), 2);
  EXPECT_EQ(c.points.col(1), Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(c.normals.col(0), Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(c.normals.col(1), Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(info.format, "ply ascii");

  // Upper-case extension.
  writeText(tmp / "u.PCD", pcdHeader("x y z", "4 4 4", "F F F", 1, 1, "ascii") + "1 2 3\n");
  EXPECT_EQ(readCloud(tmp / "u.PCD").size(), 1);
}

TEST(CloudIo, NonFinitePointsAreAnErrorOrDropped) {
  // An organized 3 x 2 cloud as a camera writes it: NaN marks missing pixels (points 2 and 4).
  TempDir tmp;
  writeText(tmp / "o.pcd", pcdHeader("x y z", "4 4 4", "F F F", 3, 2, "ascii") +
                               "1 1 1\n2 2 2\nnan nan nan\n4 4 4\nnan nan nan\n6 6 6\n");
  const std::string e = errorOf([&] { readCloud(tmp / "o.pcd"); });
  EXPECT_NE(e.find(tmp / "o.pcd"), std::string::npos) << e;
  EXPECT_NE(e.find("point 2 "), std::string::npos) << e;
  EXPECT_NE(e.find("non-finite"), std::string::npos) << e;

  ReadOptions drop;
  drop.dropNonFinite = true;
  CloudFileInfo info;
  const PointCloud c = readCloud(tmp / "o.pcd", drop, &info);
  ASSERT_EQ(c.size(), 4);
  EXPECT_EQ(c.points.row(0), Eigen::RowVector4d(1, 2, 4, 6));
  EXPECT_EQ(info.nonFinite, 2);
  EXPECT_EQ(info.width, 3);
  EXPECT_EQ(info.height, 2);

  // Every point NaN: nothing left is an error even when dropping.
  writeText(tmp / "all.pcd", pcdHeader("x y z", "4 4 4", "F F F", 1, 1, "ascii") + "nan 0 0\n");
  EXPECT_NE(errorOf([&] { readCloud(tmp / "all.pcd", drop); }).find("non-finite"), std::string::npos);
  // A NaN normal counts too.
  writeText(tmp / "nn.pcd", pcdHeader("x y z normal_x normal_y normal_z", "4 4 4 4 4 4", "F F F F F F", 1, 1, "ascii") +
                                "0 0 0 nan 0 1\n");
  EXPECT_NE(errorOf([&] { readCloud(tmp / "nn.pcd"); }).find("point 0 has a non-finite normal"), std::string::npos);
}

TEST(CloudIo, MalformedFilesNameTheFile) {
  TempDir tmp;
  struct Case {
    std::string name, content, expected;
  };
  const std::string ok3 = pcdHeader("x y z", "4 4 4", "F F F", 3, 1, "ascii");
  std::string truncatedBinary = pcdHeader("x y z", "4 4 4", "F F F", 3, 1, "binary");
  truncatedBinary.append(std::string(7 * 4, '\0'));  // 7 of the 9 floats
  const std::vector<Case> cases = {
      {"trunc.pcd", ok3 + "1 2 3\n4 5 6\n", "declares 3 points but the file has 2"},
      {"short.pcd", ok3 + "1 2 3\n4 5 6\n7 8\n", ":14: expected 3 values, got 2"},
      {"word.pcd", ok3 + "1 2 3\n4 x 6\n7 8 9\n", ":13: 'x' is not a number"},
      {"trunc_bin.pcd", truncatedBinary, "truncated"},
      {"garbage.pcd", "hello world\n", ":1: unexpected line 'hello world'"},
      {"sizes.pcd", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n", "same number of fields"},
      {"nodata.pcd", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\n", "no DATA line"},
      {"count.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 3\nDATA ascii\n", "differs from POINTS"},
      {"nox.pcd", pcdHeader("a y z", "4 4 4", "F F F", 1, 1, "ascii") + "1 2 3\n", "has no x field (fields: a y z)"},
      {"zero.pcd", "", "empty (0 bytes)"},
      {"empty.pcd", pcdHeader("x y z", "4 4 4", "F F F", 0, 1, "ascii"), "the cloud has no points"},
      {"trunc.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n",
       "cannot read"},
      {"noformat.ply", "ply\nelement vertex 1\nproperty float x\nend_header\n1\n", "no 'format' line"},
      {"noz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
       "has no z field"},
      {"c.xyz", "1 2 3\n", "expected a .pcd or .ply file"},
      // Headers announcing billions of points are refused at once against the file's size.
      {"huge_bin.pcd", pcdHeader("x y z", "4 4 4", "F F F", 4000000000LL, 1, "binary") + std::string(24, '\0'),
       "declares 4000000000 points of 12 bytes, but the file has"},
      {"huge_lzf.pcd", pcdHeader("x y z", "4 4 4", "F F F", 4000000000LL, 1, "binary_compressed") + std::string(24, '\0'),
       "declares 4000000000 points"},
      {"wide.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4000000000000\nHEIGHT 4000000000000\nPOINTS 1\nDATA binary\n",
       "is too large"},
      {"manycount.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 4000000000\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n",
       "from 1 to 1000000"},
      {"huge.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
                   "property float z\nend_header\n" + std::string(24, '\0'),
       ":7: the header declares 4000000000 vertex elements of at least 12 bytes"},
      {"huge_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
                         "property float z\nend_header\n1 2 3\n",
       "4000000000 vertex elements of at least 6 bytes"},
      {"negative.ply", "ply\nformat ascii 1.0\nelement vertex -3\nproperty float x\nend_header\n", ":3: element vertex needs"},
      // PCL aborts on a list property among the vertices', or on one it takes for theirs after a
      // header line it passed over.
      {"vertex_list.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                          "property list uchar int vertex_indices\nend_header\n0 0 0 3 0 1 2\n",
       ":7: a list property in the vertex element is not supported"},
      {"stray.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                    "\x9b\x93" "ement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 2\n",
       ":7: malformed PLY header"},
  };
  for (const auto& c : cases) {
    const std::string path = tmp / c.name;
    writeText(path, c.content);
    const std::string e = errorOf([&] { readCloud(path); });
    EXPECT_EQ(e.rfind(path, 0), 0u) << c.name << ": " << e;
    EXPECT_NE(e.find(c.expected), std::string::npos) << c.name << ": " << e;
  }
  // An empty cloud is accepted on request.
  ReadOptions allow;
  allow.allowEmpty = true;
  EXPECT_EQ(readCloud(tmp / "empty.pcd", allow).size(), 0);

  EXPECT_NE(errorOf([&] { readCloud(tmp / "missing.pcd"); }).find("no such file"), std::string::npos);
  fs::create_directory(tmp / "dir.pcd");
  EXPECT_NE(errorOf([&] { readCloud(tmp / "dir.pcd"); }).find("is a folder"), std::string::npos);
}

TEST(CloudIo, WriteErrorsLeaveNothingBehind) {
  TempDir tmp;
  PointCloud c = randomCloud(3, false, 3);
  writeCloud(tmp / "keep.pcd", c);
  const std::string before = slurp(tmp / "keep.pcd");

  PointCloud bad = c;
  bad.points(1, 2) = std::numeric_limits<double>::quiet_NaN();
  std::string e = errorOf([&] { writeCloud(tmp / "keep.pcd", bad); });
  EXPECT_NE(e.find("point 2"), std::string::npos) << e;
  EXPECT_EQ(slurp(tmp / "keep.pcd"), before);  // the old file is untouched

  bad.points(1, 2) = 1e39;  // beyond float32
  EXPECT_NE(errorOf([&] { writeCloud(tmp / "f.pcd", bad); }).find("float32"), std::string::npos);
  EXPECT_NE(errorOf([&] { writeCloud(tmp / "e.pcd", PointCloud{}); }).find("empty"), std::string::npos);
  EXPECT_NE(errorOf([&] { writeCloud(tmp / "no/such/dir/c.pcd", c); }).find("does not exist"), std::string::npos);
  EXPECT_NE(errorOf([&] { writeCloud(tmp / "c.txt", c); }).find(".pcd or .ply"), std::string::npos);
  // Only keep.pcd: no temporary or partial files.
  EXPECT_EQ(std::distance(fs::directory_iterator(tmp.path()), fs::directory_iterator{}), 1);
}

}  // namespace
