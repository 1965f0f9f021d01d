// Mesh readers on the reference cube in every format, and .vtu/.pvd writers.
#include <gtest/gtest.h>
#include <unistd.h>

#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include <Eigen/Dense>

#include "core/Error.h"
#include "io/mesh/Mesh.h"

namespace fs = std::filesystem;
using viscera::io::VolumeMesh;

namespace {

std::string dataPath(const std::string& name) { return std::string(VISCERA_SOURCE_DIR) + "/tests/data/meshes/" + name; }

// A fresh folder per test (tests may run in parallel processes), removed afterwards.
class TempFolder {
 public:
  TempFolder() {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    std::string name = "viscera_mesh_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" + std::to_string(::getpid());
    for (char& c : name)
      if (c == '/') c = '_';
    path_ = fs::temp_directory_path() / name;
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  operator const fs::path&() const { return path_; }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void spit(const fs::path& p, const std::string& content) {
  std::ofstream out(p, std::ios::binary);
  out << content;
}

template <class F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const viscera::Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected viscera::Error, got another exception: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected viscera::Error, nothing was thrown";
  return {};
}

#define EXPECT_CONTAINS(text, part) EXPECT_NE(std::string(text).find(part), std::string::npos) << "message: " << (text)

// The unit cube of tests/data/meshes: five positive tetrahedra, two bottom triangles.
VolumeMesh referenceCube() {
  VolumeMesh m;
  m.points.resize(3, 8);
  m.points << 0, 1, 1, 0, 0, 1, 1, 0,  //
      0, 0, 1, 1, 0, 0, 1, 1,          //
      0, 0, 0, 0, 1, 1, 1, 1;
  m.tets.resize(4, 5);
  m.tets << 0, 2, 5, 7, 1,  //
      1, 3, 4, 4, 3,        //
      3, 1, 6, 3, 4,        //
      4, 6, 1, 6, 6;
  m.triangles.resize(3, 2);
  m.triangles << 0, 0,  //
      2, 3,             //
      1, 2;
  return m;
}

void expectSameMesh(const VolumeMesh& a, const VolumeMesh& b) {
  ASSERT_EQ(a.points.cols(), b.points.cols());
  EXPECT_TRUE(a.points == b.points) << a.points << "\nvs\n" << b.points;
  ASSERT_EQ(a.tets.cols(), b.tets.cols());
  EXPECT_TRUE(a.tets == b.tets) << a.tets << "\nvs\n" << b.tets;
  ASSERT_EQ(a.triangles.cols(), b.triangles.cols());
  EXPECT_TRUE(a.triangles == b.triangles) << a.triangles << "\nvs\n" << b.triangles;
}

class MeshCubeFiles : public testing::TestWithParam<const char*> {};

TEST_P(MeshCubeFiles, ReadsTheReferenceCube) {
  const VolumeMesh mesh = viscera::io::readVolumeMesh(dataPath(GetParam()));
  expectSameMesh(mesh, referenceCube());
  EXPECT_EQ(viscera::io::checkTetMesh(mesh, GetParam()), 1);
  double volume = 0;
  for (Eigen::Index c = 0; c < mesh.tets.cols(); ++c) {
    Eigen::Matrix3d e;
    for (int k = 0; k < 3; ++k) e.col(k) = mesh.points.col(mesh.tets(k + 1, c)) - mesh.points.col(mesh.tets(0, c));
    volume += e.determinant() / 6;
  }
  EXPECT_NEAR(volume, 1.0, 1e-14);
}

INSTANTIATE_TEST_SUITE_P(AllFormats, MeshCubeFiles,
                         testing::Values("cube_v1.msh", "cube_v2.msh", "cube_v40.msh", "cube_v41.msh", "cube.vtk", "cube_v51.vtk",
                                         "cube_ascii.vtu", "cube_binary32.vtu", "cube_bigendian.vtu"),
                         [](const testing::TestParamInfo<const char*>& param) {
                           std::string name = param.param;
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

TEST(MeshRead, FormatSpecificEntryPointsAgree) {
  expectSameMesh(viscera::io::readGmsh(dataPath("cube_v2.msh")), referenceCube());
  expectSameMesh(viscera::io::readVtkLegacy(dataPath("cube.vtk")), referenceCube());
  expectSameMesh(viscera::io::readVtu(dataPath("cube_ascii.vtu")), referenceCube());
}

TEST(MeshRead, LegacyVtkWithPointsOnly) {
  const VolumeMesh mesh = viscera::io::readVtkLegacy(dataPath("points_only.vtk"));
  ASSERT_EQ(mesh.points.cols(), 3);
  EXPECT_EQ(mesh.tets.cols(), 0);
  EXPECT_EQ(mesh.triangles.cols(), 0);
  EXPECT_EQ(mesh.points.col(1), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(mesh.points.col(2), Eigen::Vector3d(-4.5, 6e-3, 7));
}

TEST(MeshRead, ExtensionIsCaseInsensitiveAndUnknownOnesAreRejected) {
  const TempFolder dir;
  fs::copy_file(dataPath("cube_v2.msh"), dir / "CUBE.MSH");
  expectSameMesh(viscera::io::readVolumeMesh((dir / "CUBE.MSH").string()), referenceCube());
  spit(dir / "cube.obj", "v 0 0 0\n");
  const std::string msg = errorOf([&] { viscera::io::readVolumeMesh((dir / "cube.obj").string()); });
  EXPECT_CONTAINS(msg, "cube.obj");
  EXPECT_CONTAINS(msg, "unknown mesh format");
}

TEST(MeshRead, MissingFileNamesThePath) {
  for (const char* name : {"nope.msh", "nope.vtk", "nope.vtu"}) {
    const std::string path = dataPath(name);
    const std::string msg = errorOf([&] { viscera::io::readVolumeMesh(path); });
    EXPECT_CONTAINS(msg, path);
    EXPECT_CONTAINS(msg, "No such file");
  }
}

TEST(MeshRead, VtuWithTwoPiecesIsConcatenated) {
  const TempFolder dir;
  const std::string piece =
      "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">"
      "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>"
      "<Cells><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>"
      "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">4</DataArray>"
      "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray></Cells></Piece>\n";
  spit(dir / "two.vtu",
       "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>\n" + piece + piece + "</UnstructuredGrid></VTKFile>\n");
  const VolumeMesh mesh = viscera::io::readVtu((dir / "two.vtu").string());
  ASSERT_EQ(mesh.points.cols(), 8);
  ASSERT_EQ(mesh.tets.cols(), 2);
  EXPECT_EQ(mesh.tets.col(1), Eigen::Vector4i(4, 5, 6, 7));
}

TEST(MeshWrite, VtuRoundTripIsExact) {
  const TempFolder dir;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uniform(-1e3, 1e3);
  const int numPoints = 50, numTets = 40;
  Eigen::Matrix3Xd points(3, numPoints);
  for (int i = 0; i < numPoints; ++i)
    for (int k = 0; k < 3; ++k) points(k, i) = uniform(rng);
  // Values whose text form would lose bits.
  points.col(0) << 0.1, 1.0 / 3.0, -0.0;
  points.col(1) << 1e-300, std::numeric_limits<double>::denorm_min(), 1e300;
  points.col(2) << std::nextafter(1.0, 2.0), -std::numeric_limits<double>::max(), 123456789.123456789;
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets(4, numTets);
  for (int c = 0; c < numTets; ++c)
    for (int k = 0; k < 4; ++k) tets(k, c) = static_cast<int>(rng() % numPoints);

  std::vector<viscera::io::DataArray> pointData{{"displacement", 3, std::vector<double>(3 * numPoints, 0.25)},
                                                {"pressure & <stuff>", 1, std::vector<double>(numPoints, -1.5)}};
  std::vector<viscera::io::DataArray> cellData{{"stress", 6, std::vector<double>(6 * numTets, 2.0)}};
  const std::string path = (dir / "frame.vtu").string();
  viscera::io::writeVtu(path, points, tets, pointData, cellData);

  const VolumeMesh back = viscera::io::readVtu(path);
  ASSERT_EQ(back.points.cols(), numPoints);
  for (int i = 0; i < numPoints; ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(std::bit_cast<uint64_t>(back.points(k, i)), std::bit_cast<uint64_t>(points(k, i)));
  EXPECT_TRUE(back.tets == tets);
  EXPECT_EQ(back.triangles.cols(), 0);

  const std::string text = slurp(path);
  EXPECT_CONTAINS(text, "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">");
  EXPECT_CONTAINS(text, "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"binary\">");
  EXPECT_CONTAINS(text, "Name=\"pressure &amp; &lt;stuff&gt;\"");
  EXPECT_CONTAINS(text, "<DataArray type=\"Float64\" Name=\"stress\" NumberOfComponents=\"6\" format=\"binary\">");
  EXPECT_CONTAINS(text, "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"binary\">");
  EXPECT_CONTAINS(text, "<DataArray type=\"UInt8\" Name=\"types\" format=\"binary\">");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);  // no temporary left
}

// SOFA's meshes include VTK XML grids saved as .vtk (its loader looks at the content): one is read
// as the .vtu it is.
TEST(MeshRead, XmlGridUnderTheVtkExtension) {
  const TempFolder dir;
  Eigen::Matrix3Xd points(3, 4);
  points << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets(4, 1);
  tets << 0, 1, 2, 3;
  const std::string path = (dir / "grid.vtk").string();
  viscera::io::writeVtu(path, points, tets, {}, {});
  const VolumeMesh back = viscera::io::readVolumeMesh(path);
  EXPECT_TRUE(back.points == points);
  EXPECT_TRUE(back.tets == tets);
}

TEST(MeshWrite, VtuWithoutCellsOrPoints) {
  const TempFolder dir;
  Eigen::Matrix3Xd points(3, 2);
  points << 1, 2, 3, 4, 5, 6;
  const std::string path = (dir / "cloud.vtu").string();
  viscera::io::writeVtu(path, points, {}, {{"id", 1, {0, 1}}}, {});
  VolumeMesh back = viscera::io::readVtu(path);
  EXPECT_TRUE(back.points == points);
  EXPECT_EQ(back.tets.cols(), 0);
  EXPECT_CONTAINS(slurp(path), "NumberOfPoints=\"2\" NumberOfCells=\"0\"");

  viscera::io::writeVtu(path, Eigen::Matrix3Xd(3, 0), {}, {}, {});
  back = viscera::io::readVtu(path);
  EXPECT_EQ(back.points.cols(), 0);
  EXPECT_EQ(back.tets.cols(), 0);
}

TEST(MeshWrite, VtuRejectsInconsistentData) {
  const TempFolder dir;
  const VolumeMesh cube = referenceCube();
  const std::string path = (dir / "bad.vtu").string();
  std::string msg = errorOf([&] { viscera::io::writeVtu(path, cube.points, cube.tets, {{"u", 3, std::vector<double>(23)}}, {}); });
  EXPECT_CONTAINS(msg, path);
  EXPECT_CONTAINS(msg, "'u'");
  msg = errorOf([&] { viscera::io::writeVtu(path, cube.points, cube.tets, {}, {{"j", 1, std::vector<double>(4)}}); });
  EXPECT_CONTAINS(msg, "'j'");
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets = cube.tets;
  tets(2, 3) = 8;
  msg = errorOf([&] { viscera::io::writeVtu(path, cube.points, tets, {}, {}); });
  EXPECT_CONTAINS(msg, "tetrahedron 3 refers to node 8");
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST(MeshWrite, PvdCollection) {
  const TempFolder dir;
  const std::string path = (dir / "run.pvd").string();
  viscera::io::writePvd(path, {{0.0, "frames/f_0000.vtu"}, {0.1, "frames/f_0001.vtu"}, {1e-7, "a&b.vtu"}, {1.0 / 3.0, "x.vtu"}});
  const std::string text = slurp(path);
  EXPECT_CONTAINS(text, "<VTKFile type=\"Collection\"");
  EXPECT_CONTAINS(text, "<Collection>");
  EXPECT_CONTAINS(text, "<DataSet timestep=\"0\" group=\"\" part=\"0\" file=\"frames/f_0000.vtu\"/>");
  EXPECT_CONTAINS(text, "<DataSet timestep=\"0.1\" group=\"\" part=\"0\" file=\"frames/f_0001.vtu\"/>");
  EXPECT_CONTAINS(text, "timestep=\"1e-07\" group=\"\" part=\"0\" file=\"a&amp;b.vtu\"");
  EXPECT_CONTAINS(text, "timestep=\"0.3333333333333333\"");  // reads back as exactly 1/3
  EXPECT_CONTAINS(text, "</Collection>\n</VTKFile>\n");
  const std::string msg = errorOf([&] { viscera::io::writePvd(path, {{std::nan(""), "a.vtu"}}); });
  EXPECT_CONTAINS(msg, path);
}

TEST(MeshRead, PvdReadsBackWhatWasWrittenInTimeOrder) {
  const TempFolder dir;
  const std::string path = (dir / "run.pvd").string();
  viscera::io::writePvd(path, {{0.5, "b.vtu"}, {1.0 / 3.0, "a&b.vtu"}, {0.0, "/abs/first.vtu"}});
  const auto frames = viscera::io::readPvd(path);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].time, 0.0);
  EXPECT_EQ(frames[0].path, "/abs/first.vtu");
  EXPECT_EQ(frames[1].time, 1.0 / 3.0);  // bit-exact round trip
  EXPECT_EQ(frames[1].path, (dir / "a&b.vtu").string());
  EXPECT_EQ(frames[2].path, (dir / "b.vtu").string());

  auto bad = [&](const std::string& name, const std::string& text) {
    spit(dir / name, text);
    return errorOf([&] { viscera::io::readPvd((dir / name).string()); });
  };
  const std::string head = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\">\n<Collection>\n";
  EXPECT_CONTAINS(bad("t.pvd", head + "<DataSet file=\"a.vtu\"/>\n<DataSet timestep=\"x\" file=\"b.vtu\"/>\n</Collection></VTKFile>"),
                  "t.pvd:4");
  EXPECT_CONTAINS(bad("d.pvd", head + "<DataSet timestep=\"1\" file=\"a.vtu\"/><DataSet timestep=\"1\" file=\"b.vtu\"/></Collection></VTKFile>"),
                  "two frames at time");
  EXPECT_CONTAINS(bad("e.pvd", head + "</Collection></VTKFile>"), "no <DataSet> frames");
  EXPECT_CONTAINS(bad("x.pvd", head + "<DataSet timestep=\"1\" file=\"a.vtu\"></Collection>"), "x.pvd:4");
}

}  // namespace

// Gmsh hexahedra (type 5) and quadrangles (type 3) are read, in every version, with the nodes in
// the file's order (Gmsh, VTK and SOFA order a hexahedron's nodes alike).
TEST(MeshRead, GmshHexahedraAndQuadrangles) {
  TempFolder dir;
  const std::string nodes = "1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n";
  spit(dir / "v2.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n8\n" + nodes + "$EndNodes\n"
                       "$Elements\n2\n1 5 2 0 1 1 2 3 4 5 6 7 8\n2 3 2 0 1 1 2 3 4\n$EndElements\n");
  spit(dir / "v1.msh", "$NOD\n8\n" + nodes + "$ENDNOD\n$ELM\n2\n1 5 1 1 8 1 2 3 4 5 6 7 8\n2 3 1 1 4 1 2 3 4\n$ENDELM\n");
  for (const char* name : {"v2.msh", "v1.msh"}) {
    const VolumeMesh m = viscera::io::readVolumeMesh((dir / name).string());
    ASSERT_EQ(m.hexahedra.cols(), 1) << name;
    for (int k = 0; k < 8; ++k) EXPECT_EQ(m.hexahedra(k, 0), k) << name;
    ASSERT_EQ(m.quads.cols(), 1) << name;
    EXPECT_EQ(m.quads.col(0), Eigen::Vector4i(0, 1, 2, 3)) << name;
    EXPECT_EQ(m.tets.cols(), 0);
  }
}
