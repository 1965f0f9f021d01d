// Bad input through the command line: every invalid scene or mesh must be rejected with exit code 2,
// a message that points at the offending file and line and names the component and attribute, and
// nothing written to the output folder. The fixtures in tests/data/bad/ are one-edit variants of
// scene_ok.xml (grid beam) and mesh_ok.xml (a cube of five tetrahedra read from cube_ok.msh).
#include <gtest/gtest.h>

#include <cctype>
#include <string>
#include <vector>

#include "cli_helpers.h"

using namespace viscera_test;

namespace {

struct BadCase {
  std::string scene;                    // fixture in tests/data/bad/
  std::string lineFile;                 // the file whose "<path>:<line>:" the message must contain
  std::string lineNeedle;               // text on the offending line of lineFile
  std::vector<std::string> mustContain; // component and attribute names, the problem
};

// Runs the fixture and checks the common contract; returns stderr for further checks.
std::string expectRejected(const BadCase& c) {
  const std::string scene = badPath(c.scene);
  const std::string lineFile = badPath(c.lineFile);
  const int line = lineOf(lineFile, c.lineNeedle);
  EXPECT_GT(line, 0) << "fixture problem: '" << c.lineNeedle << "' not found in " << lineFile;

  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  RunResult r = runViscera({"run", scene, "--out", out.string(), "--steps", "2"});
  EXPECT_EQ(r.rc, 2) << r;
  const std::string where = lineFile + ":" + std::to_string(line) + ":";
  EXPECT_NE(r.err.find(where), std::string::npos) << "expected '" << where << "' in the message\n" << r;
  for (const auto& s : c.mustContain) EXPECT_NE(r.err.find(s), std::string::npos) << "expected '" << s << "'\n" << r;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r;
  EXPECT_TRUE(absentOrEmpty(out)) << "the output folder " << out << " was written to";
  return r.err;
}

// The line number in "<file>:<line>:" within `text`, or 0 if `file` is not followed by one.
int lineAfter(const std::string& text, const std::string& file) {
  for (size_t p = text.find(file + ":"); p != std::string::npos; p = text.find(file + ":", p + 1)) {
    size_t q = p + file.size() + 1, e = q;
    while (e < text.size() && std::isdigit(static_cast<unsigned char>(text[e]))) ++e;
    if (e > q && e < text.size() && text[e] == ':') return std::stoi(text.substr(q, e - q));
  }
  return 0;
}

// The controls: the fixtures the bad ones are edits of run fine, so each rejection below is
// caused by its one edit.
TEST(BadInput, ControlSceneRuns) {
  TempDir tmp;
  RunResult r = runViscera({"run", badPath("scene_ok.xml"), "--out", tmp / "out", "--steps", "2"});
  EXPECT_EQ(r.rc, 0) << r;
  EXPECT_TRUE(fs::exists(tmp.path() / "out" / "beam.pvd")) << r;
}

TEST(BadInput, ControlMeshSceneRuns) {
  TempDir tmp;
  RunResult r = runViscera({"run", badPath("mesh_ok.xml"), "--out", tmp / "out", "--steps", "2"});
  EXPECT_EQ(r.rc, 0) << r;
  EXPECT_TRUE(fs::exists(tmp.path() / "out" / "cube.pvd")) << r;
}

TEST(BadInput, MalformedXml) {
  std::string err = expectRejected({"malformed_xml.xml", "malformed_xml.xml", "</Nod>", {"malformed XML"}});
  // Exactly one error line, no stack of follow-up messages.
  EXPECT_EQ(lines(err).size(), 1u) << err;
}

TEST(BadInput, UnknownComponent) {
  std::string err = expectRejected({"unknown_component.xml", "unknown_component.xml", "<DiagonalMas ", {"'DiagonalMas'"}});
  EXPECT_NE(err.find("DiagonalMass"), std::string::npos) << "expected a suggestion\n" << err;
}

TEST(BadInput, UnknownAttribute) {
  std::string err = expectRejected(
      {"unknown_attribute.xml", "unknown_attribute.xml", "poisonRatio=", {"TetrahedronFEMForceField.poisonRatio", "unknown attribute"}});
  EXPECT_NE(err.find("poissonRatio"), std::string::npos) << "expected the list of known attributes\n" << err;
}

TEST(BadInput, PoissonRatioOfOneHalf) {
  expectRejected({"poisson_half.xml", "poisson_half.xml", "poissonRatio=\"0.5\"", {"TetrahedronFEMForceField.poissonRatio", "0.5"}});
}

TEST(BadInput, PoissonRatioAboveOneHalf) {
  expectRejected({"poisson_above_half.xml", "poisson_above_half.xml", "poissonRatio=\"0.7\"", {"TetrahedronFEMForceField.poissonRatio"}});
}

TEST(BadInput, YoungModulusZero) {
  expectRejected({"young_zero.xml", "young_zero.xml", "youngModulus=\"0\"", {"TetrahedronFEMForceField.youngModulus"}});
}

TEST(BadInput, YoungModulusNegative) {
  expectRejected({"young_negative.xml", "young_negative.xml", "youngModulus=\"-1000\"", {"TetrahedronFEMForceField.youngModulus"}});
}

TEST(BadInput, TimeStepZero) {
  expectRejected({"dt_zero.xml", "dt_zero.xml", "dt=\"0\"", {"Node.dt"}});
}

TEST(BadInput, TimeStepNegative) {
  expectRejected({"dt_negative.xml", "dt_negative.xml", "dt=\"-0.01\"", {"Node.dt"}});
}

TEST(BadInput, MissingMeshFile) {
  expectRejected({"missing_mesh.xml", "missing_mesh.xml", "filename=\"no_such_mesh.msh\"", {"MeshGmshLoader.filename", "no_such_mesh.msh"}});
}

TEST(BadInput, MeshWithWrongNodeCount) {
  // $Nodes declares 9 nodes and lists 8: the message points into the mesh file (the $Nodes header
  // or the line where the 9th node was expected) and at the loader in the scene.
  std::string err = expectRejected({"mesh_bad_node_count.xml", "mesh_bad_node_count.xml", "filename=\"cube_bad_node_count.msh\"",
                                     {"MeshGmshLoader.filename", "9"}});
  const std::string mesh = badPath("cube_bad_node_count.msh");
  const int line = lineAfter(err, mesh);
  ASSERT_GT(line, 0) << "expected '" << mesh << ":<line>:'\n" << err;
  EXPECT_GE(line, lineOf(mesh, "$Nodes")) << err;
  EXPECT_LE(line, lineOf(mesh, "$EndNodes")) << err;
}

TEST(BadInput, MeshWithWrongElementCount) {
  std::string err = expectRejected({"mesh_bad_element_count.xml", "mesh_bad_element_count.xml", "filename=\"cube_bad_element_count.msh\"",
                                     {"MeshGmshLoader.filename", "6"}});
  const std::string mesh = badPath("cube_bad_element_count.msh");
  const int line = lineAfter(err, mesh);
  ASSERT_GT(line, 0) << "expected '" << mesh << ":<line>:'\n" << err;
  EXPECT_GE(line, lineOf(mesh, "$Elements")) << err;
  EXPECT_LE(line, lineOf(mesh, "$EndElements")) << err;
}

TEST(BadInput, MeshIndexOutOfRange) {
  // The element line in the mesh file, and the loader in the scene.
  expectRejected({"mesh_index_out_of_range.xml", "cube_index_out_of_range.msh", " 99", {"node 99"}});
  expectRejected({"mesh_index_out_of_range.xml", "mesh_index_out_of_range.xml", "filename=\"cube_index_out_of_range.msh\"",
                  {"MeshGmshLoader.filename"}});
}

TEST(BadInput, MeshDegenerateTetrahedron) {
  // The check runs on the whole mesh, after reading: the scene's loader line and the mesh file are named.
  std::string err = expectRejected({"mesh_degenerate.xml", "mesh_degenerate.xml", "filename=\"cube_degenerate.msh\"",
                                     {"MeshGmshLoader.filename", "cube_degenerate.msh", "degenerate"}});
  EXPECT_NE(err.find("tetrahedron 4"), std::string::npos) << err;  // the fifth, 0-based
}

TEST(BadInput, MeshInvertedTetrahedronAmongPositiveOnes) {
  std::string err = expectRejected({"mesh_inverted.xml", "mesh_inverted.xml", "filename=\"cube_inverted.msh\"",
                                     {"MeshGmshLoader.filename", "cube_inverted.msh", "inverted"}});
  EXPECT_NE(err.find("tetrahedron 2"), std::string::npos) << err;  // the third, 0-based
}

TEST(BadInput, LinkToMissingComponent) {
  expectRejected({"missing_link.xml", "missing_link.xml", "@nothere.indices", {"FixedConstraint.indices", "nothere"}});
}

TEST(BadInput, IncompatibleUnit) {
  expectRejected({"unit_incompatible.xml", "unit_incompatible.xml", "youngModulus=\"5 mm\"",
                  {"TetrahedronFEMForceField.youngModulus", "'mm'"}});
}

TEST(BadInput, UnknownUnit) {
  expectRejected({"unit_unknown.xml", "unit_unknown.xml", "youngModulus=\"5 psi\"", {"TetrahedronFEMForceField.youngModulus", "psi"}});
}

TEST(BadInput, CheckRejectsTheSameInput) {
  // `viscera check` validates as `run` does.
  for (const char* f : {"poisson_half.xml", "missing_link.xml", "mesh_inverted.xml", "unit_unknown.xml"}) {
    RunResult r = runViscera({"check", badPath(f)});
    EXPECT_EQ(r.rc, 2) << f << "\n" << r;
    EXPECT_NE(r.err.find(badPath(f) + ":"), std::string::npos) << r;
  }
}

TEST(BadInput, MissingSceneFile) {
  TempDir tmp;
  const std::string scene = tmp / "does_not_exist.xml";
  RunResult r = runViscera({"run", scene, "--out", tmp / "out", "--steps", "2"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find(scene), std::string::npos) << r;
  EXPECT_TRUE(absentOrEmpty(tmp.path() / "out"));
}

}  // namespace
