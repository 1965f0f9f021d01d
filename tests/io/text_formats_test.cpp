// Text files as other tools write them: a UTF-8 byte-order mark (spreadsheet and Windows editor
// exports) and old Mac line ends (lone CR) read like plain files, in every line-based reader.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "io/mesh/Mesh.h"
#include "io/scene/CsvTable.h"
#include "io/scene/Transform.h"
#include "motion/Trajectory.h"
#include "tests/support/TempDir.h"

namespace {

using viscera::test_support::TempDir;
const std::string kBom = "\xEF\xBB\xBF";

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(TextFormats, TrajectoriesWithABomOrCrLineEndsRead) {
  const std::string rows = "t,x,y,z,qx,qy,qz,qw\n0,1,2,3,0,0,0,1\n1,4,5,6,0,0,0,1\n";
  std::string cr = rows;
  for (char& c : cr)
    if (c == '\n') c = '\r';
  for (const std::string& text : {kBom + rows, cr, kBom + cr}) {
    const viscera::motion::Trajectory t = viscera::motion::parseTrajectoryCsv(text, "t.csv");
    ASSERT_EQ(t.size(), 2);
    EXPECT_EQ(t.p[1].z(), 6);
  }
}

TEST(TextFormats, TablesAndTransformsWithABomOrCrLineEndsRead) {
  const auto table = viscera::io::parseNumericCsv(kBom + "t,q1\r0,1\r1,2\r", "j.csv", {"t", "q1"});
  EXPECT_EQ(table.rows(), 2);
  EXPECT_EQ(table.at(1, 1), 2);
  const auto T = viscera::parseTransform(kBom + "# c\r1 0 0 5\r0 1 0 6\r0 0 1 7\r0 0 0 1\r", "T.txt");
  EXPECT_EQ(T.translation().z(), 7);
}

TEST(TextFormats, MeshesWithABomRead) {
  TempDir tmp;
  for (const char* name : {"cube_v2.msh", "cube_v41.msh", "cube.vtk"}) {
    const std::string src = std::string(VISCERA_SOURCE_DIR) + "/tests/data/meshes/" + name;
    const std::string dst = tmp / name;
    std::ofstream(dst, std::ios::binary) << kBom << slurp(src);
    const auto plain = viscera::io::readVolumeMesh(src), bom = viscera::io::readVolumeMesh(dst);
    EXPECT_EQ(bom.points.cols(), plain.points.cols()) << name;
    EXPECT_EQ(bom.tets.cols(), plain.tets.cols()) << name;
  }
}

}  // namespace
