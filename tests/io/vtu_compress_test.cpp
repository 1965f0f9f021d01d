// zlib-compressed .vtu (compressor="vtkZLibDataCompressor"): writeVtu's block layout checked
// with an independent decoder, round trips through readVtu, files written by VTK itself, corrupt
// data, the VTKExporter default, and (where python3-vtk is installed) VTK's own reader.
#include <gtest/gtest.h>
#include <zlib.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "io/mesh/Mesh.h"
#include "io/scene/SceneReader.h"
#include "tests/support/TempDir.h"

namespace fs = std::filesystem;
using viscera::io::DataArray;
using viscera::io::VolumeMesh;
using viscera::io::VtuWriteOptions;
using viscera::test_support::TempDir;
using Tets = Eigen::Matrix<int, 4, Eigen::Dynamic>;

namespace {

#define EXPECT_CONTAINS(haystack, needle) EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void spit(const fs::path& p, const std::string& content) { std::ofstream(p, std::ios::binary) << content; }

template <class F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const viscera::Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no viscera::Error thrown";
  return "";
}

VtuWriteOptions compressed(bool int32Indices = true, int blockSize = 32768) {
  VtuWriteOptions o;
  o.compress = true;
  o.int32Indices = int32Indices;
  o.compressionBlockSize = blockSize;
  return o;
}

// ---- An independent decoder of VTK's inline binary DataArrays ----

// One base64 run: a multiple of four characters, '=' only at its end.
std::vector<unsigned char> base64Run(const std::string& s) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::vector<unsigned char> out;
  EXPECT_EQ(s.size() % 4, 0u) << s.substr(0, 80);
  for (size_t i = 0; i + 3 < s.size(); i += 4) {
    const int a = value(s[i]), b = value(s[i + 1]), c = s[i + 2] == '=' ? -1 : value(s[i + 2]), d = s[i + 3] == '=' ? -1 : value(s[i + 3]);
    EXPECT_TRUE(a >= 0 && b >= 0) << "bad base64 at " << i;
    EXPECT_TRUE((c >= 0 && d >= 0) || i + 4 == s.size()) << "padding inside a run at " << i;
    out.push_back(static_cast<unsigned char>(a << 2 | b >> 4));
    if (c >= 0) out.push_back(static_cast<unsigned char>((b & 15) << 4 | c >> 2));
    if (d >= 0) out.push_back(static_cast<unsigned char>((c & 3) << 6 | d));
  }
  return out;
}

uint64_t le64(const unsigned char* p) {
  uint64_t v = 0;
  for (int k = 0; k < 8; ++k) v |= static_cast<uint64_t>(p[k]) << (8 * k);
  return v;
}

struct Array {
  std::string type, text;
};

// The type and base64 text (without white space) of the DataArray called `name`.
Array findArray(const std::string& file, const std::string& name) {
  const size_t at = file.find("Name=\"" + name + "\"");
  if (at == std::string::npos) {
    ADD_FAILURE() << "no DataArray " << name;
    return {};
  }
  const size_t open = file.rfind("<DataArray", at), type = file.find("type=\"", open) + 6;
  const size_t begin = file.find('>', at) + 1, end = file.find('<', begin);  // VTK may nest an <InformationKey>
  std::string text;
  for (char c : file.substr(begin, end - begin))
    if (c != ' ' && c != '\n' && c != '\r' && c != '\t') text += c;
  return {file.substr(type, file.find('"', type) - type), text};
}

struct Compressed {
  uint64_t numBlocks = 0, blockSize = 0, lastSize = 0;
  std::vector<uint64_t> packedSizes;
  std::vector<unsigned char> raw;  // inflated values
};

// VTK's compressed layout: the UInt64 header [#blocks, block size, last partial block size,
// compressed sizes...] as one base64 run, the zlib blocks as a second run.
Compressed decodeCompressed(const std::string& text) {
  Compressed c;
  const std::vector<unsigned char> first = base64Run(text.substr(0, 32));  // 24 bytes: no padding
  if (first.size() != 24) {
    ADD_FAILURE() << "header too short";
    return c;
  }
  c.numBlocks = le64(first.data());
  c.blockSize = le64(first.data() + 8);
  c.lastSize = le64(first.data() + 16);
  const size_t headerBytes = 8 * (3 + c.numBlocks), headerChars = (headerBytes + 2) / 3 * 4;
  const std::vector<unsigned char> header = base64Run(text.substr(0, headerChars));
  const std::vector<unsigned char> data = base64Run(text.substr(headerChars));
  EXPECT_EQ(header.size(), headerBytes);
  size_t at = 0;
  for (uint64_t b = 0; b < c.numBlocks; ++b) {
    const uint64_t packed = le64(header.data() + 8 * (3 + b));
    c.packedSizes.push_back(packed);
    const uint64_t size = b + 1 == c.numBlocks && c.lastSize ? c.lastSize : c.blockSize;
    std::vector<unsigned char> block(size);
    uLongf got = static_cast<uLongf>(size);
    EXPECT_LE(at + packed, data.size());
    if (at + packed > data.size()) return c;
    EXPECT_EQ(uncompress(block.data(), &got, data.data() + at, static_cast<uLong>(packed)), Z_OK) << "block " << b;
    EXPECT_EQ(got, size) << "block " << b;
    c.raw.insert(c.raw.end(), block.begin(), block.begin() + static_cast<std::ptrdiff_t>(got));
    at += packed;
  }
  EXPECT_EQ(at, data.size()) << "bytes after the last block";
  return c;
}

// Doubles from little-endian bytes.
std::vector<double> float64s(const std::vector<unsigned char>& raw) {
  std::vector<double> v(raw.size() / 8);
  for (size_t i = 0; i < v.size(); ++i) v[i] = std::bit_cast<double>(le64(raw.data() + 8 * i));
  return v;
}

void expectBitExact(const std::vector<double>& got, const std::vector<double>& want, const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  for (size_t i = 0; i < got.size(); ++i)
    ASSERT_EQ(std::bit_cast<uint64_t>(got[i]), std::bit_cast<uint64_t>(want[i])) << what << " value " << i;
}

// ---- Meshes ----

// An nx x ny x nz node grid over [0,68.7] x [0,35.8] x [0,39.3] (the gel phantom), each hexahedron
// split into six tetrahedra, with smooth but full-precision fields like a deformed FEM frame.
struct Frame {
  Eigen::Matrix3Xd points;
  Tets tets;
  std::vector<DataArray> pointData, cellData;
};

Frame gridFrame(int nx, int ny, int nz) {
  Frame f;
  auto id = [&](int i, int j, int k) { return i + nx * (j + ny * k); };
  f.points.resize(3, nx * ny * nz);
  std::vector<double> u, v;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const Eigen::Vector3d x0(68.7 * i / (nx - 1), 35.8 * j / (ny - 1), 39.3 * k / (nz - 1));
        const Eigen::Vector3d d(0.01 * std::sin(0.1 * x0.x()) * x0.z(), -0.02 * std::cos(0.07 * x0.y()) * x0.z(),
                                -0.3 * std::exp(-0.002 * x0.squaredNorm()) * x0.z());
        f.points.col(id(i, j, k)) = x0 + d;
        for (int c = 0; c < 3; ++c) u.push_back(d[c]), v.push_back(-0.7 * d[c] + 1e-3 * std::sin(x0[c]));
      }
  std::vector<Eigen::Vector4i> tets;
  for (int k = 0; k + 1 < nz; ++k)
    for (int j = 0; j + 1 < ny; ++j)
      for (int i = 0; i + 1 < nx; ++i) {
        const int c[8] = {id(i, j, k),     id(i + 1, j, k),     id(i + 1, j + 1, k),     id(i, j + 1, k),
                          id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
        static const int kSplit[6][4] = {{0, 5, 1, 6}, {0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6}, {0, 7, 4, 6}, {0, 4, 5, 6}};
        for (const auto& t : kSplit) tets.emplace_back(c[t[0]], c[t[1]], c[t[2]], c[t[3]]);
      }
  f.tets.resize(4, static_cast<Eigen::Index>(tets.size()));
  std::vector<double> vm;
  for (size_t t = 0; t < tets.size(); ++t) {
    f.tets.col(static_cast<Eigen::Index>(t)) = tets[t];
    vm.push_back(1e3 * std::abs(std::sin(0.37 * t)) + 17.0 / (t + 3.0));
  }
  f.pointData = {{"displacement", 3, u}, {"velocity", 3, v}};
  f.cellData = {{"vonMises", 1, vm}};
  return f;
}

std::vector<double> pointsAsVector(const Eigen::Matrix3Xd& p) { return std::vector<double>(p.data(), p.data() + p.size()); }

// ---- Tests ----

TEST(VtuCompress, RoundTripIsExact) {
  const TempDir dir("viscera_vtuz");
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uniform(-1e3, 1e3);
  const int numPoints = 300, numTets = 500;
  Eigen::Matrix3Xd points(3, numPoints);
  for (int i = 0; i < numPoints; ++i)
    for (int k = 0; k < 3; ++k) points(k, i) = uniform(rng);
  points.col(0) << 0.1, 1.0 / 3.0, -0.0;
  points.col(1) << 1e-300, std::numeric_limits<double>::denorm_min(), 1e300;
  points.col(2) << std::nextafter(1.0, 2.0), -std::numeric_limits<double>::max(), 123456789.123456789;
  Tets tets(4, numTets);
  for (int c = 0; c < numTets; ++c)
    for (int k = 0; k < 4; ++k) tets(k, c) = static_cast<int>(rng() % numPoints);
  std::vector<double> u(3 * numPoints), s(6 * numTets);
  for (double& x : u) x = uniform(rng) * 1e-7;
  for (double& x : s) x = uniform(rng);
  const std::vector<DataArray> pointData{{"displacement", 3, u}, {"pressure & <stuff>", 1, std::vector<double>(numPoints, -1.5)}};
  const std::vector<DataArray> cellData{{"stress", 6, s}};

  for (const bool int32 : {true, false}) {
    SCOPED_TRACE(int32 ? "Int32 indices" : "Int64 indices");
    const fs::path path = dir.path() / "frame.vtu";
    viscera::io::writeVtu(path.string(), points, tets, pointData, cellData, compressed(int32));

    const VolumeMesh back = viscera::io::readVtu(path.string());
    expectBitExact(pointsAsVector(back.points), pointsAsVector(points), "points");
    EXPECT_TRUE(back.tets == tets);
    EXPECT_EQ(back.triangles.cols(), 0);

    const std::string text = slurp(path);
    EXPECT_CONTAINS(text, "header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">");
    EXPECT_CONTAINS(text, "Name=\"pressure &amp; &lt;stuff&gt;\"");
    // The fields, decoded independently of readVtu.
    expectBitExact(float64s(decodeCompressed(findArray(text, "displacement").text).raw), u, "displacement");
    expectBitExact(float64s(decodeCompressed(findArray(text, "pressure &amp; &lt;stuff&gt;").text).raw), pointData[1].values, "pressure");
    expectBitExact(float64s(decodeCompressed(findArray(text, "stress").text).raw), s, "stress");
    expectBitExact(float64s(decodeCompressed(findArray(text, "Points").text).raw), pointsAsVector(points), "Points");
    const Array conn = findArray(text, "connectivity"), offsets = findArray(text, "offsets");
    EXPECT_EQ(conn.type, int32 ? "Int32" : "Int64");
    EXPECT_EQ(offsets.type, conn.type);
    EXPECT_EQ(findArray(text, "types").type, "UInt8");
    const size_t width = int32 ? 4 : 8;
    const std::vector<unsigned char> connRaw = decodeCompressed(conn.text).raw, offRaw = decodeCompressed(offsets.text).raw;
    ASSERT_EQ(connRaw.size(), width * 4 * numTets);
    ASSERT_EQ(offRaw.size(), width * numTets);
    for (int c = 0; c < numTets; ++c) {
      EXPECT_EQ(connRaw[width * (4 * c + 1)], tets(1, c) & 0xFF);
      EXPECT_EQ(offRaw[width * c], (4 * (c + 1)) & 0xFF);
    }
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);  // no temporary left
  }
}

TEST(VtuCompress, FollowsVtkBlockLayout) {
  const TempDir dir("viscera_vtuz");
  // 2000 points: 48000 bytes of coordinates, one full 32 KiB block and a partial one.
  Frame f = gridFrame(20, 10, 10);
  const fs::path path = dir.path() / "f.vtu";
  viscera::io::writeVtu(path.string(), f.points, f.tets, f.pointData, f.cellData, compressed());
  const std::string text = slurp(path);
  Compressed c = decodeCompressed(findArray(text, "Points").text);
  EXPECT_EQ(c.numBlocks, 2u);
  EXPECT_EQ(c.blockSize, 32768u);
  EXPECT_EQ(c.lastSize, 48000u - 32768u);
  ASSERT_EQ(c.packedSizes.size(), 2u);
  EXPECT_LT(c.packedSizes[0], 32768u);
  expectBitExact(float64s(c.raw), pointsAsVector(f.points), "Points");
  // The header is a base64 run of its own: 8 x 5 = 40 bytes, 56 characters ending in one '='.
  EXPECT_EQ(findArray(text, "Points").text[55], '=');

  // A size that is a multiple of the block size: the last-block field is 0 (the block is full).
  Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Random(3, 128);  // 3072 bytes = 3 x 1024
  viscera::io::writeVtu(path.string(), points, {}, {}, {}, compressed(true, 1024));
  c = decodeCompressed(findArray(slurp(path), "Points").text);
  EXPECT_EQ(c.numBlocks, 3u);
  EXPECT_EQ(c.blockSize, 1024u);
  EXPECT_EQ(c.lastSize, 0u);
  expectBitExact(float64s(c.raw), pointsAsVector(points), "Points");
  expectBitExact(pointsAsVector(viscera::io::readVtu(path.string()).points), pointsAsVector(points), "readVtu points");
}

TEST(VtuCompress, MultiBlockRoundTrip) {
  const TempDir dir("viscera_vtuz");
  // 25 x 25 x 25 nodes: 375 KB of coordinates (12 blocks), 82944 tetrahedra (1.3 MB of Int32 connectivity).
  const Frame f = gridFrame(25, 25, 25);
  const fs::path path = dir.path() / "big.vtu";
  for (const int blockSize : {32768, 4096, 1 << 20}) {
    SCOPED_TRACE("block size " + std::to_string(blockSize));
    viscera::io::writeVtu(path.string(), f.points, f.tets, f.pointData, f.cellData, compressed(true, blockSize));
    const std::string text = slurp(path);
    const Compressed c = decodeCompressed(findArray(text, "Points").text);
    EXPECT_EQ(c.numBlocks, (24u * 15625u + blockSize - 1) / blockSize);
    expectBitExact(float64s(decodeCompressed(findArray(text, "velocity").text).raw), f.pointData[1].values, "velocity");
    expectBitExact(float64s(decodeCompressed(findArray(text, "vonMises").text).raw), f.cellData[0].values, "vonMises");
    const VolumeMesh back = viscera::io::readVtu(path.string());
    expectBitExact(pointsAsVector(back.points), pointsAsVector(f.points), "points");
    EXPECT_TRUE(back.tets == f.tets);
  }
}

TEST(VtuCompress, MuchSmallerThanUncompressedForTheGelPhantom) {
  const TempDir dir("viscera_vtuz");
  const Frame f = gridFrame(25, 9, 9);  // 2025 nodes, 9216 tetrahedra
  ASSERT_EQ(f.tets.cols(), 9216);
  const fs::path plain = dir.path() / "plain.vtu", packed = dir.path() / "packed.vtu";
  viscera::io::writeVtu(plain.string(), f.points, f.tets, f.pointData, f.cellData);
  viscera::io::writeVtu(packed.string(), f.points, f.tets, f.pointData, f.cellData, compressed());
  const auto plainSize = fs::file_size(plain), packedSize = fs::file_size(packed);
  // About 800 KB plain. Compressed, the connectivity and offsets (Int32) shrink ~8x, the Float64
  // arrays only ~1.2-1.5x: 0.29 of the plain size here, 0.37-0.40 for simulated gel-phantom frames.
  EXPECT_GT(plainSize, 750000u);
  EXPECT_LT(packedSize * 5, plainSize * 2) << plainSize << " -> " << packedSize;
  const VolumeMesh a = viscera::io::readVtu(plain.string()), b = viscera::io::readVtu(packed.string());
  expectBitExact(pointsAsVector(b.points), pointsAsVector(a.points), "points");
  EXPECT_TRUE(a.tets == b.tets);
}

TEST(VtuCompress, EmptyPiecesAndArrays) {
  const TempDir dir("viscera_vtuz");
  const fs::path path = dir.path() / "e.vtu";
  Eigen::Matrix3Xd points(3, 2);
  points << 1, 2, 3, 4, 5, 6;
  viscera::io::writeVtu(path.string(), points, {}, {{"id", 1, {0, 1}}}, {}, compressed());
  VolumeMesh back = viscera::io::readVtu(path.string());
  EXPECT_TRUE(back.points == points);
  EXPECT_EQ(back.tets.cols(), 0);
  const Compressed c = decodeCompressed(findArray(slurp(path), "connectivity").text);
  EXPECT_EQ(c.numBlocks, 0u);
  EXPECT_TRUE(c.raw.empty());

  viscera::io::writeVtu(path.string(), Eigen::Matrix3Xd(3, 0), {}, {}, {}, compressed());
  back = viscera::io::readVtu(path.string());
  EXPECT_EQ(back.points.cols(), 0);
  EXPECT_EQ(back.tets.cols(), 0);
}

// Written by VTK 9.1's vtkXMLUnstructuredGridWriter (binary mode, zlib, tiny blocks so that the
// arrays span several): two tetrahedra on five points, with a displacement field.
const char* const kVtkUInt32 = R"(<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian" header_type="UInt32" compressor="vtkZLibDataCompressor">
  <UnstructuredGrid>
    <Piece NumberOfPoints="5" NumberOfCells="2">
      <PointData>
        <DataArray type="Float64" Name="displacement" NumberOfComponents="3" format="binary" RangeMin="0.3333333333333333" RangeMax="4.465173879904094">
          AgAAAEAAAAA4AAAAJQAAACoAAAA=eF5jYEABDaFgcNV+1kwQ2GkPEb6wHyL+FSp+Eir+YD8A7N0TIXheW70KBJgcTIxB4LI9Axi82L8aLM7lMGsmCNyEin/YHwoGgg4AdhEVIA==
          <InformationKey name="L2_NORM_RANGE" location="vtkDataArray" length="2">
            <Value index="0">
              0.33333333333
            </Value>
            <Value index="1">
              4.4651738799
            </Value>
          </InformationKey>
        </DataArray>
      </PointData>
      <CellData>
      </CellData>
      <Points>
        <DataArray type="Float64" Name="Points" NumberOfComponents="3" format="binary" RangeMin="0" RangeMax="2.0615528128088303">
          AgAAAEAAAAA4AAAAEgAAABIAAAA=eF5jYMAHPtjjlQbKAwAqXgJfeF5jYMAHPthjp3/YAwBBlATF
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="binary" RangeMin="0" RangeMax="4">
          AQAAAEAAAAAAAAAAFgAAAA==eF5jYIAARijNBKWZCYizQGkAAfAAEQ==
        </DataArray>
        <DataArray type="Int64" Name="offsets" format="binary" RangeMin="4" RangeMax="8">
          AQAAAEAAAAAQAAAADgAAAA==eF5jYYAADigNAACQAA0=
        </DataArray>
        <DataArray type="UInt8" Name="types" format="binary" RangeMin="10" RangeMax="10">
          AQAAAEAAAAACAAAACgAAAA==eF7j4gIAACAAFQ==
        </DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
)";

const char* const kVtkUInt64 = R"(<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64" compressor="vtkZLibDataCompressor">
  <UnstructuredGrid>
    <Piece NumberOfPoints="5" NumberOfCells="2">
      <PointData>
        <DataArray type="Float64" Name="displacement" NumberOfComponents="3" format="binary" RangeMin="0.3333333333333333" RangeMax="4.465173879904094">
          AwAAAAAAAAAwAAAAAAAAABgAAAAAAAAAHwAAAAAAAAAkAAAAAAAAABcAAAAAAAAAeF5jYEABDaFgcNV+1kwQ2GkPEb6wHyL+1R4A4ZUM43hemzUTBE7aM4DBg/2rV4EAk4OJMQhchoq/gIpzOQAA1AMSsXhemzUTBG7aM4DBh/2hYCDoAAB8KAiu
        </DataArray>
      </PointData>
      <CellData>
      </CellData>
      <Points>
        <DataArray type="Float64" Name="Points" NumberOfComponents="3" format="binary" RangeMin="0" RangeMax="2.0615528128088303">
          AwAAAAAAAAAwAAAAAAAAABgAAAAAAAAAEAAAAAAAAAASAAAAAAAAABIAAAAAAAAAeF5jYMAHPtijiwAAFT8BMHheY2BABh/sGfCCD/YAKk4CX3heY2AAgQ/2DCj0D3sAIu0Dlg==
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="binary" RangeMin="0" RangeMax="4">
          AgAAAAAAAAAwAAAAAAAAABAAAAAAAAAAFAAAAAAAAAAOAAAAAAAAAA==eF5jYIAARijNBKWZcYgDAAEAAAp4XmNmgAAWKA0AAGAACA==
        </DataArray>
        <DataArray type="Int64" Name="offsets" format="binary" RangeMin="4" RangeMax="8">
          AQAAAAAAAAAwAAAAAAAAABAAAAAAAAAADgAAAAAAAAA=eF5jYYAADigNAACQAA0=
        </DataArray>
        <DataArray type="UInt8" Name="types" format="binary" RangeMin="10" RangeMax="10">
          AQAAAAAAAAAwAAAAAAAAAAIAAAAAAAAACgAAAAAAAAA=eF7j4gIAACAAFQ==
        </DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
)";

TEST(VtuCompress, ReadsFilesWrittenByVtk) {
  const TempDir dir("viscera_vtuz");
  Eigen::Matrix3Xd points(3, 5);
  points << 0, 1, 0, 0, 1,  //
      0, 0, 1, 0, 1,        //
      0, 0, 0, 1, 1.5;
  Tets tets(4, 2);
  tets << 0, 1, 1, 2, 2, 3, 3, 4;
  for (const char* text : {kVtkUInt32, kVtkUInt64}) {
    const fs::path path = dir.path() / "vtk.vtu";
    spit(path, text);
    const VolumeMesh back = viscera::io::readVtu(path.string());
    expectBitExact(pointsAsVector(back.points), pointsAsVector(points), "points");
    EXPECT_TRUE(back.tets == tets) << back.tets;
  }
  // The same layout as writeVtu's, which the independent decoder reads too (UInt64 header).
  const Compressed c = decodeCompressed(findArray(kVtkUInt64, "displacement").text);
  EXPECT_EQ(c.numBlocks, 3u);
  EXPECT_EQ(c.blockSize, 48u);
  EXPECT_EQ(c.lastSize, 24u);
  const std::vector<double> d = float64s(c.raw);
  ASSERT_EQ(d.size(), 15u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(d[3 * i], 0.1 * i);
    EXPECT_EQ(d[3 * i + 1], -0.25 * i);
    EXPECT_EQ(d[3 * i + 2], 1.0 / 3.0 + i);
  }
}

TEST(VtuCompress, CorruptDataIsReported) {
  const TempDir dir("viscera_vtuz");
  const Frame f = gridFrame(6, 5, 5);
  const fs::path path = dir.path() / "bad.vtu";
  viscera::io::writeVtu(path.string(), f.points, f.tets, {}, {}, compressed());
  const std::string good = slurp(path);
  const Array points = findArray(good, "Points");
  const size_t start = good.find(points.text);
  ASSERT_EQ(decodeCompressed(points.text).numBlocks, 1u);
  const size_t headerChars = 44;  // 3 + 1 header words, 32 bytes: the data run starts after 44 characters

  // Data cut short: the sizes in the header no longer add up.
  std::string text = good;
  text.erase(start + points.text.size() - 8, 8);
  spit(path, text);
  EXPECT_CONTAINS(errorOf([&] { viscera::io::readVtu(path.string()); }), "the compressed points DataArray declares");
  // A changed byte inside the zlib stream.
  text = good;
  char& ch = text[start + headerChars + (points.text.size() - headerChars) / 2];
  ch = ch == 'A' ? 'B' : 'A';
  spit(path, text);
  EXPECT_CONTAINS(errorOf([&] { viscera::io::readVtu(path.string()); }), "does not inflate to its declared 3600 bytes");
  // A header claiming more blocks than it holds.
  text = good;
  text.replace(start, 4, "/wAA");  // numBlocks = 0xFF + ...
  spit(path, text);
  EXPECT_CONTAINS(errorOf([&] { viscera::io::readVtu(path.string()); }), "blocks, more than its header can hold");
  // Other compressors are not supported.
  text = good;
  text.replace(text.find("vtkZLibDataCompressor"), 21, "vtkLZ4DataCompressor");
  spit(path, text);
  EXPECT_CONTAINS(errorOf([&] { viscera::io::readVtu(path.string()); }),
                  path.string() + ":2: compressed .vtu (compressor=\"vtkLZ4DataCompressor\") is not supported");
}

TEST(VtuCompress, OptionsAreChecked) {
  const TempDir dir("viscera_vtuz");
  const Frame f = gridFrame(3, 3, 3);
  const std::string path = dir / "o.vtu";
  VtuWriteOptions o = compressed();
  for (int level : {1, 9}) {
    o.compressionLevel = level;
    viscera::io::writeVtu(path, f.points, f.tets, f.pointData, f.cellData, o);
    EXPECT_TRUE(viscera::io::readVtu(path).tets == f.tets);
  }
  o.compressionLevel = 0;
  EXPECT_CONTAINS(errorOf([&] { viscera::io::writeVtu(path, f.points, f.tets, {}, {}, o); }), "compression level must be 1..9");
  o = compressed(true, 100);
  EXPECT_CONTAINS(errorOf([&] { viscera::io::writeVtu(path, f.points, f.tets, {}, {}, o); }), "block size must be at least 1024");
}

TEST(VtuCompress, ExporterCompressesByDefault) {
  const TempDir dir("viscera_vtuz");
  spit(dir.path() / "scene.xml", R"(<Node name="root" dt="0.01" gravity="0 -9 0">
    <Node name="cube">
        <EulerImplicitSolver/>
        <CGLinearSolver iterations="25" tolerance="1e-9" threshold="1e-20"/>
        <RegularGridTopology name="grid" n="4 4 4" min="0 0 0" max="1 1 1"/>
        <MechanicalObject name="dofs"/>
        <TetrahedronSetTopologyContainer name="tetra"/>
        <Hexa2TetraTopologicalMapping input="@grid" output="@tetra"/>
        <DiagonalMass massDensity="1"/>
        <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3" method="large"/>
        <BoxROI name="clamp" box="-1 -1 -1 2 2 0.1"/>
        <FixedConstraint indices="@clamp.indices"/>
        <VTKExporter filename="packed" precision="float64"/>
        <VTKExporter filename="plain" compress="false" precision="float64"/>
        <VTKExporter filename="single"/>
    </Node>
</Node>
)");
  auto scene = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
  scene->setOutputDirectory(dir / "out");
  viscera::Simulation sim(*scene);
  sim.begin();
  for (int i = 0; i < 3; ++i) ASSERT_FALSE(sim.step());
  sim.end();
  const std::string packed = slurp(dir.path() / "out" / "packed_000003.vtu"), plain = slurp(dir.path() / "out" / "plain_000003.vtu");
  EXPECT_CONTAINS(packed, "compressor=\"vtkZLibDataCompressor\"");
  EXPECT_EQ(findArray(packed, "connectivity").type, "Int32");
  EXPECT_EQ(plain.find("compressor"), std::string::npos);
  EXPECT_EQ(findArray(plain, "connectivity").type, "Int64");
  std::vector<unsigned char> plainBytes = base64Run(findArray(plain, "displacement").text);
  ASSERT_GE(plainBytes.size(), 8u);
  plainBytes.erase(plainBytes.begin(), plainBytes.begin() + 8);  // the byte count
  const std::vector<double> displacement = float64s(plainBytes);
  EXPECT_EQ(displacement.size(), 3u * 64u);
  expectBitExact(float64s(decodeCompressed(findArray(packed, "displacement").text).raw), displacement, "displacement");
  const VolumeMesh a = viscera::io::readVtu(dir / "out/packed_000003.vtu"), b = viscera::io::readVtu(dir / "out/plain_000003.vtu");
  expectBitExact(pointsAsVector(a.points), pointsAsVector(b.points), "points");
  EXPECT_TRUE(a.tets == b.tets);

  // By default points and fields are Float32: each value is the double rounded to the nearest float.
  const std::string single = slurp(dir.path() / "out" / "single_000003.vtu");
  EXPECT_EQ(findArray(single, "Points").type, "Float32");
  EXPECT_EQ(findArray(single, "displacement").type, "Float32");
  EXPECT_EQ(findArray(single, "vonMises").type, "Float32");
  const std::vector<unsigned char> raw = decodeCompressed(findArray(single, "displacement").text).raw;
  ASSERT_EQ(raw.size(), 4u * displacement.size());
  for (size_t i = 0; i < displacement.size(); ++i) {
    float v;
    std::memcpy(&v, raw.data() + 4 * i, 4);
    ASSERT_EQ(v, static_cast<float>(displacement[i])) << "displacement value " << i;
  }
  const VolumeMesh c = viscera::io::readVtu(dir / "out/single_000003.vtu");
  ASSERT_EQ(c.points.cols(), a.points.cols());
  for (Eigen::Index i = 0; i < c.points.size(); ++i)
    ASSERT_EQ(c.points.data()[i], static_cast<double>(static_cast<float>(a.points.data()[i]))) << "point coordinate " << i;
  EXPECT_LT(fs::file_size(dir.path() / "out" / "single_000003.vtu"), fs::file_size(dir.path() / "out" / "packed_000003.vtu"));
}

// VTK's own reader, where the python3 VTK bindings are installed (Debian's python3-vtk9).
TEST(VtuCompress, VtkReaderReadsCompressedFiles) {
  const char* python = "/usr/bin/python3";
  if (!fs::exists(python) || std::system("/usr/bin/python3 -c 'import vtk' >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "no python3 with VTK bindings";
  const TempDir dir("viscera_vtuz");
  const Frame f = gridFrame(25, 9, 9);
  const std::string path = dir / "gel.vtu";
  viscera::io::writeVtu(path, f.points, f.tets, f.pointData, f.cellData, compressed());
  spit(dir.path() / "check.py", R"(import sys, vtk
r = vtk.vtkXMLUnstructuredGridReader()
r.SetFileName(sys.argv[1])
r.Update()
o = r.GetOutput()
def values(a):
    return ' '.join(repr(a.GetValue(i)) for i in range(a.GetNumberOfTuples() * a.GetNumberOfComponents()))
print(o.GetNumberOfPoints(), o.GetNumberOfCells())
print(values(o.GetPoints().GetData()))
print(values(o.GetPointData().GetArray('displacement')))
print(values(o.GetCellData().GetArray('vonMises')))
print(values(o.GetCells().GetConnectivityArray()))
print(' '.join(str(o.GetCellType(i)) for i in range(o.GetNumberOfCells())))
)");
  const std::string command =
      std::string(python) + " " + (dir / "check.py") + " " + path + " > " + (dir / "out.txt") + " 2> " + (dir / "err.txt");
  const int rc = std::system(command.c_str());
  ASSERT_EQ(rc, 0) << slurp(dir.path() / "err.txt");
  EXPECT_EQ(slurp(dir.path() / "err.txt"), "");  // VTK reports read errors on stderr
  std::istringstream out(slurp(dir.path() / "out.txt"));
  auto doubles = [&] {
    std::string line;
    std::getline(out, line);
    std::istringstream in(line);
    std::vector<double> v;
    for (std::string w; in >> w;) v.push_back(std::strtod(w.c_str(), nullptr));
    return v;
  };
  std::string counts;
  std::getline(out, counts);
  EXPECT_EQ(counts, "2025 9216");
  expectBitExact(doubles(), pointsAsVector(f.points), "points");
  expectBitExact(doubles(), f.pointData[0].values, "displacement");
  expectBitExact(doubles(), f.cellData[0].values, "vonMises");
  const std::vector<double> conn = doubles();
  ASSERT_EQ(conn.size(), 4u * 9216u);
  for (Eigen::Index c = 0; c < f.tets.cols(); ++c)
    for (int k = 0; k < 4; ++k) ASSERT_EQ(conn[4 * c + k], f.tets(k, c));
  const std::vector<double> types = doubles();
  ASSERT_EQ(types.size(), 9216u);
  for (double t : types) ASSERT_EQ(t, 10);

  // Float32 arrays read back as the doubles rounded to floats; cells encoded once (as an exporter
  // does for a series) read as the others.
  VtuWriteOptions single = compressed();
  single.float32 = true;
  const std::string cells = viscera::io::encodeVtuCells(f.tets, single);
  single.encodedCells = &cells;
  const std::string path32 = dir / "gel32.vtu";
  viscera::io::writeVtu(path32, f.points, f.tets, f.pointData, f.cellData, single);
  const std::string command32 =
      std::string(python) + " " + (dir / "check.py") + " " + path32 + " > " + (dir / "out.txt") + " 2> " + (dir / "err.txt");
  ASSERT_EQ(std::system(command32.c_str()), 0) << slurp(dir.path() / "err.txt");
  EXPECT_EQ(slurp(dir.path() / "err.txt"), "");
  out = std::istringstream(slurp(dir.path() / "out.txt"));
  std::getline(out, counts);
  EXPECT_EQ(counts, "2025 9216");
  auto rounded = [](std::vector<double> v) {
    for (double& x : v) x = static_cast<float>(x);
    return v;
  };
  expectBitExact(doubles(), rounded(pointsAsVector(f.points)), "Float32 points");
  expectBitExact(doubles(), rounded(f.pointData[0].values), "Float32 displacement");
  expectBitExact(doubles(), rounded(f.cellData[0].values), "Float32 vonMises");
  const std::vector<double> conn32 = doubles();
  ASSERT_EQ(conn32.size(), 4u * 9216u);
  for (Eigen::Index c = 0; c < f.tets.cols(); ++c)
    for (int k = 0; k < 4; ++k) ASSERT_EQ(conn32[4 * c + k], f.tets(k, c));
  EXPECT_TRUE(viscera::io::readVtu(path32).tets == f.tets);
}

}  // namespace
