// Broken mesh files: each must throw viscera::Error naming the file and, where one applies, the line.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/Error.h"
#include "io/mesh/Mesh.h"

namespace fs = std::filesystem;

namespace {

class MeshMalformed : public testing::Test {
 protected:
  void SetUp() override {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("viscera_mesh_bad_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Writes `content` as `name`, reads it with readVolumeMesh and returns the error message.
  std::string errorReading(const std::string& name, const std::string& content) {
    const fs::path path = dir_ / name;
    std::ofstream(path, std::ios::binary) << content;
    try {
      viscera::io::readVolumeMesh(path.string());
    } catch (const viscera::Error& e) {
      return e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "expected viscera::Error, got: " << e.what();
      return {};
    }
    ADD_FAILURE() << "reading " << name << " did not throw";
    return {};
  }

  fs::path dir_;
};

// 1-based line of the first line of `text` containing `needle`.
int lineOf(const std::string& text, const std::string& needle) {
  const size_t at = text.find(needle);
  EXPECT_NE(at, std::string::npos) << needle;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

std::string at(const std::string& name, int line) { return name + ":" + std::to_string(line) + ": "; }

#define EXPECT_CONTAINS(text, part) EXPECT_NE(std::string(text).find(part), std::string::npos) << "message: " << (text)

const std::string kV2Head =
    "$MeshFormat\n"
    "2.2 0 8\n"
    "$EndMeshFormat\n";
const std::string kV2Nodes =
    "$Nodes\n"
    "5\n"
    "1 0 0 0\n"
    "2 1 0 0\n"
    "3 0 1 0\n"
    "4 0 0 1\n"
    "5 1 1 1\n"
    "$EndNodes\n";

TEST_F(MeshMalformed, GmshNodeCountLargerThanTheList) {
  const std::string text = kV2Head + "$Nodes\n9\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n";
  const std::string msg = errorReading("count.msh", text);
  EXPECT_CONTAINS(msg, at("count.msh", lineOf(text, "$EndNodes")));
  EXPECT_CONTAINS(msg, "declares 9 nodes but only 4");
}

TEST_F(MeshMalformed, GmshNodeCountSmallerThanTheList) {
  const std::string text = kV2Head + "$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n";
  const std::string msg = errorReading("count.msh", text);
  EXPECT_CONTAINS(msg, at("count.msh", lineOf(text, "4 0 0 1")));
  EXPECT_CONTAINS(msg, "expected $EndNodes after 3 nodes");
}

TEST_F(MeshMalformed, GmshElementRefersToMissingNode) {
  const std::string text = kV2Head + kV2Nodes + "$Elements\n2\n1 4 2 0 1 1 2 3 4\n7 4 2 0 1 1 2 3 99\n$EndElements\n";
  const std::string msg = errorReading("mesh.msh", text);
  EXPECT_CONTAINS(msg, at("mesh.msh", lineOf(text, "7 4 2")) + "element 7 refers to node 99, but the file has 5 nodes");
}

TEST_F(MeshMalformed, GmshSecondOrderTetIsRejected) {
  const std::string text = kV2Head + kV2Nodes + "$Elements\n1\n3 11 2 0 1 1 2 3 4 5 1 2 3 4 5\n$EndElements\n";
  const std::string msg = errorReading("quadratic.msh", text);
  EXPECT_CONTAINS(msg, at("quadratic.msh", lineOf(text, "3 11 2")));
  EXPECT_CONTAINS(msg, "element 3 has Gmsh type 11 (10-node second-order tetrahedron), which is not supported");
}

TEST_F(MeshMalformed, GmshPrismIsRejectedInEveryVersion) {
  std::string text = kV2Head + kV2Nodes + "$Elements\n1\n1 6 0 1 2 3 4 5 1\n$EndElements\n";
  EXPECT_CONTAINS(errorReading("prism2.msh", text), at("prism2.msh", lineOf(text, "1 6 0")) + "element 1 has Gmsh type 6 (6-node prism)");
  text = "$NOD\n1\n1 0 0 0\n$ENDNOD\n$ELM\n1\n4 6 1 1 6 1 1 1 1 1 1\n$ENDELM\n";
  EXPECT_CONTAINS(errorReading("prism1.msh", text), at("prism1.msh", lineOf(text, "4 6 1")) + "element 4 has Gmsh type 6");
  text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 1 1 1\n3 1 0 1\n1\n0 0 0\n$EndNodes\n"
         "$Elements\n1 1 6 6\n3 1 6 1\n6 1 1 1 1 1 1\n$EndElements\n";
  EXPECT_CONTAINS(errorReading("prism4.msh", text), at("prism4.msh", lineOf(text, "6 1 1 1")) + "element 6 has Gmsh type 6");
}

TEST_F(MeshMalformed, GmshWrongNodeCountOnAnElementLine) {
  std::string text = kV2Head + kV2Nodes + "$Elements\n1\n1 4 2 0 1 1 2 3\n$EndElements\n";
  EXPECT_CONTAINS(errorReading("short.msh", text), at("short.msh", lineOf(text, "1 4 2 0 1 1 2 3")));
  text = "$NOD\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$ENDNOD\n$ELM\n1\n1 4 1 1 3 1 2 3\n$ENDELM\n";
  const std::string msg = errorReading("v1.msh", text);
  EXPECT_CONTAINS(msg, at("v1.msh", lineOf(text, "1 4 1 1 3")));
  EXPECT_CONTAINS(msg, "declares 3 nodes");
}

TEST_F(MeshMalformed, GmshTruncatedFile) {
  const std::string text = kV2Head + kV2Nodes + "$Elements\n3\n1 4 2 0 1 1 2 3 4\n2 4 2 0 1 2 3 4 5\n";
  const std::string msg = errorReading("cut.msh", text);
  EXPECT_CONTAINS(msg, at("cut.msh", lineOf(text, "2 4 2 0 1 2 3 4 5")));
  EXPECT_CONTAINS(msg, "file ends inside $Elements after 2 of the 3 elements");
}

TEST_F(MeshMalformed, GmshNonNumericToken) {
  const std::string text = kV2Head + "$Nodes\n2\n1 0 0 0\n2 1 zero 0\n$EndNodes\n";
  const std::string msg = errorReading("word.msh", text);
  EXPECT_CONTAINS(msg, at("word.msh", lineOf(text, "zero")));
  EXPECT_CONTAINS(msg, "'zero'");
  const std::string tag = kV2Head + "$Nodes\n1\n1.5 0 0 0\n$EndNodes\n";
  EXPECT_CONTAINS(errorReading("tag.msh", tag), at("tag.msh", lineOf(tag, "1.5")) + "expected an integer for the node tag");
}

TEST_F(MeshMalformed, GmshMissingSections) {
  EXPECT_CONTAINS(errorReading("no_elements.msh", kV2Head + kV2Nodes), "no_elements.msh:");
  EXPECT_CONTAINS(errorReading("no_elements.msh", kV2Head + kV2Nodes), "missing $Elements section");
  EXPECT_CONTAINS(errorReading("no_nodes.msh", kV2Head + "$Elements\n0\n$EndElements\n"), "missing $Nodes section");
  EXPECT_CONTAINS(errorReading("no_format.msh", kV2Nodes), at("no_format.msh", 1) + "$Nodes before $MeshFormat");
  EXPECT_CONTAINS(errorReading("empty.msh", ""), "empty.msh: not a Gmsh mesh");
  const std::string open = kV2Head + "$PhysicalNames\n1\n3 1 \"x\"\n" + kV2Nodes;
  EXPECT_CONTAINS(errorReading("open.msh", open), "file ends inside $PhysicalNames (opened on line 4; no $EndPhysicalNames)");
}

TEST_F(MeshMalformed, GmshBinaryAndUnknownVersions) {
  std::string text = "$MeshFormat\n4.1 1 8\n\x01\x00\x00\x00\n$EndMeshFormat\n";
  EXPECT_CONTAINS(errorReading("binary.msh", text), at("binary.msh", 2) + "binary .msh is not supported; save as ASCII");
  text = "$MeshFormat\n3.0 0 8\n$EndMeshFormat\n";
  EXPECT_CONTAINS(errorReading("v3.msh", text), at("v3.msh", 2) + "Gmsh format version 3.0 is not supported");
}

TEST_F(MeshMalformed, GmshDuplicateNodeTag) {
  const std::string text = kV2Head + "$Nodes\n3\n1 0 0 0\n2 1 0 0\n1 0 1 0\n$EndNodes\n$Elements\n0\n$EndElements\n";
  EXPECT_CONTAINS(errorReading("dup.msh", text), at("dup.msh", lineOf(text, "1 0 1 0")) + "node 1 is defined twice (first on line 6)");
}

TEST_F(MeshMalformed, Gmsh4BlockCounts) {
  // The header promises 3 nodes, the only block holds 2.
  std::string text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 3 1 3\n3 1 0 2\n1\n2\n0 0 0\n1 0 0\n$EndNodes\n";
  std::string msg = errorReading("blocks.msh", text);
  EXPECT_CONTAINS(msg, at("blocks.msh", lineOf(text, "1 3 1 3")));
  EXPECT_CONTAINS(msg, "declares 3 nodes but the blocks hold 2");
  // A block promising 3 coordinate lines that has 2.
  text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 3 1 3\n3 1 0 3\n1\n2\n3\n0 0 0\n1 0 0\n$EndNodes\n";
  msg = errorReading("block.msh", text);
  EXPECT_CONTAINS(msg, at("block.msh", lineOf(text, "$EndNodes")));
  EXPECT_CONTAINS(msg, "declares 3 coordinate lines but only 2");
  // An element block with an unknown node tag.
  text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n"
         "$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 5\n$EndElements\n";
  EXPECT_CONTAINS(errorReading("tag4.msh", text), at("tag4.msh", lineOf(text, "1 1 2 3 5")) + "element 1 refers to node 5");
}

const std::string kVtkHead =
    "# vtk DataFile Version 3.0\n"
    "test\n"
    "ASCII\n"
    "DATASET UNSTRUCTURED_GRID\n"
    "POINTS 4 float\n"
    "0 0 0 1 0 0 0 1 0 0 0 1\n";

TEST_F(MeshMalformed, VtkCellListSizeMismatch) {
  std::string text = kVtkHead + "CELLS 1 6\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
  EXPECT_CONTAINS(errorReading("size.vtk", text), at("size.vtk", lineOf(text, "CELLS")) + "CELLS declares a list size of 6 but its 1 cells hold 5");
  text = kVtkHead + "CELLS 2 5\n4 0 1 2 3\n4 0 1 2 3\nCELL_TYPES 2\n10 10\n";
  EXPECT_CONTAINS(errorReading("size2.vtk", text), at("size2.vtk", lineOf(text, "4 0 1 2 3\n4") + 1) + "CELLS (line 7) declares a list size of 5");
  text = kVtkHead + "CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 2\n10 10\n";
  EXPECT_CONTAINS(errorReading("types.vtk", text), at("types.vtk", lineOf(text, "CELL_TYPES")) + "CELL_TYPES declares 2 cells but CELLS");
}

TEST_F(MeshMalformed, VtkIndexOutOfRange) {
  const std::string text = kVtkHead + "CELLS 2 10\n4 0 1 2 3\n4 0 1 2 4\nCELL_TYPES 2\n10 10\n";
  EXPECT_CONTAINS(errorReading("range.vtk", text),
                  at("range.vtk", lineOf(text, "4 0 1 2 4")) + "cell 1 refers to point 4, but the file has 4 points");
}

TEST_F(MeshMalformed, VtkUnsupportedCellType) {
  const std::string text = kVtkHead + "CELLS 2 14\n4 0 1 2 3\n8 0 1 2 3 0 1 2 3\nCELL_TYPES 2\n10\n12\n";
  EXPECT_CONTAINS(errorReading("hex.vtk", text), at("hex.vtk", lineOf(text, "12\n")) + "cell 1 has VTK type 12 (hexahedron), which is not supported");
}

TEST_F(MeshMalformed, VtkTruncatedAndNonNumeric) {
  std::string text = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n0 0 0 1 0 0\n";
  EXPECT_CONTAINS(errorReading("cut.vtk", text), at("cut.vtk", 6) + "file ends inside POINTS after 6 of the 12 coordinates");
  text = kVtkHead + "CELLS 1 5\n4 0 1 two 3\nCELL_TYPES 1\n10\n";
  EXPECT_CONTAINS(errorReading("word.vtk", text), at("word.vtk", lineOf(text, "two")) + "expected an integer in CELLS, found 'two'");
  text = kVtkHead + "CELLS 1 5\n4 0 1 2 3\n";
  EXPECT_CONTAINS(errorReading("notypes.vtk", text), at("notypes.vtk", lineOf(text, "CELLS")) + "CELLS without CELL_TYPES");
}

TEST_F(MeshMalformed, VtkUnsupportedVariants) {
  EXPECT_CONTAINS(errorReading("binary.vtk", "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\n"),
                  at("binary.vtk", 3) + "binary legacy .vtk is not supported");
  EXPECT_CONTAINS(errorReading("poly.vtk", "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\n"),
                  at("poly.vtk", 4) + "DATASET POLYDATA is not supported");
  EXPECT_CONTAINS(errorReading("other.vtk", "solid cube\n"), at("other.vtk", 1) + "not a legacy VTK file");
  EXPECT_CONTAINS(errorReading("nopoints.vtk", "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n"),
                  "nopoints.vtk:4: no POINTS section");
}

std::string vtu(const std::string& rootAttributes, const std::string& points, const std::string& cells) {
  return "<?xml version=\"1.0\"?>\n"
         "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\"" +
         rootAttributes +
         ">\n"
         "<UnstructuredGrid>\n"
         "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n"
         "<Points>\n" +
         points +
         "</Points>\n"
         "<Cells>\n" +
         cells +
         "</Cells>\n"
         "</Piece>\n"
         "</UnstructuredGrid>\n"
         "</VTKFile>\n";
}

const std::string kVtuPoints = "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 0 0 1</DataArray>\n";
const std::string kVtuCells =
    "<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>\n"
    "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n"
    "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray>\n";

TEST_F(MeshMalformed, VtuBaselineIsValid) {
  const fs::path path = dir_ / "ok.vtu";
  std::ofstream(path) << vtu("", kVtuPoints, kVtuCells);
  EXPECT_EQ(viscera::io::readVtu(path.string()).tets.cols(), 1);
}

TEST_F(MeshMalformed, VtuCompressedAndAppendedAreRejected) {
  EXPECT_CONTAINS(errorReading("zlib.vtu", vtu(" compressor=\"vtkLZ4DataCompressor\"", kVtuPoints, kVtuCells)),
                  at("zlib.vtu", 2) + "compressed .vtu (compressor=\"vtkLZ4DataCompressor\") is not supported");
  const std::string appended = vtu("", "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>\n", kVtuCells);
  const std::string text = appended.substr(0, appended.find("</VTKFile>")) + "<AppendedData encoding=\"raw\">_\x01\x02<\x03</AppendedData>\n</VTKFile>\n";
  EXPECT_CONTAINS(errorReading("appended.vtu", text), at("appended.vtu", lineOf(text, "appended")) + "the points DataArray uses appended data");
}

TEST_F(MeshMalformed, VtuCountsAndIndices) {
  std::string text = vtu("", "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0</DataArray>\n", kVtuCells);
  EXPECT_CONTAINS(errorReading("count.vtu", text), at("count.vtu", lineOf(text, "Float64")) + "the points DataArray holds 9 values but 12 are expected");
  std::string cells = kVtuCells;
  cells.replace(cells.find("0 1 2 3"), 7, "0 1 2 9");
  text = vtu("", kVtuPoints, cells);
  EXPECT_CONTAINS(errorReading("range.vtu", text), at("range.vtu", lineOf(text, "connectivity")) + "cell 0 refers to point 9, but the piece has 4 points");
  cells = kVtuCells;
  cells.replace(cells.find(">10<"), 4, ">12<");
  text = vtu("", kVtuPoints, cells);
  EXPECT_CONTAINS(errorReading("hex.vtu", text), at("hex.vtu", lineOf(text, "types")) + "cell 0 has VTK type 12 (hexahedron)");
  cells = kVtuCells;
  cells.replace(cells.find(">4<"), 3, ">3<");
  text = vtu("", kVtuPoints, cells);
  EXPECT_CONTAINS(errorReading("offsets.vtu", text), at("offsets.vtu", lineOf(text, "offsets")) + "the offsets end at 3 but the connectivity holds 4");
  text = vtu("", "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n0 0 0\n1 0 x\n0 1 0 0 0 1</DataArray>\n", kVtuCells);
  EXPECT_CONTAINS(errorReading("word.vtu", text), at("word.vtu", lineOf(text, "1 0 x")) + "expected a finite number in the points DataArray, found 'x'");
}

TEST_F(MeshMalformed, VtuBadBinary) {
  // "AAAA" decodes to a 3-byte, too-short UInt32 header; "*" is not base64; a header promising 8 bytes with 4 following.
  std::string text = vtu("", "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">AAA*</DataArray>\n", kVtuCells);
  EXPECT_CONTAINS(errorReading("char.vtu", text), at("char.vtu", lineOf(text, "binary")) + "invalid character '*' in the base64 data");
  text = vtu("", "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">AAA</DataArray>\n", kVtuCells);
  EXPECT_CONTAINS(errorReading("short.vtu", text), "truncated base64 data in the points DataArray");
  text = vtu("", "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">CAAAAAAAAAA=</DataArray>\n", kVtuCells);
  EXPECT_CONTAINS(errorReading("header.vtu", text), at("header.vtu", lineOf(text, "binary")) + "the binary points DataArray declares 8 bytes but holds 4");
}

TEST_F(MeshMalformed, VtuBrokenXml) {
  std::string text = vtu("", kVtuPoints, kVtuCells);
  text.replace(text.find("</Points>"), 9, "</Pointz>");
  EXPECT_CONTAINS(errorReading("tags.vtu", text), at("tags.vtu", lineOf(text, "</Pointz>")) + "</Pointz> does not match <Points> opened on line 5");
  text = vtu("", kVtuPoints, kVtuCells);
  text = text.substr(0, text.find("<DataArray type=\"UInt8\""));
  EXPECT_CONTAINS(errorReading("cut.vtu", text), "file ends inside <Cells> (opened on line 8)");
  text = vtu("", kVtuPoints, kVtuCells);
  text.replace(text.find("UnstructuredGrid\" version"), 16, "PolyData");
  EXPECT_CONTAINS(errorReading("poly.vtu", text), at("poly.vtu", 2) + "VTKFile type 'PolyData' is not supported");
}

}  // namespace
