// Visual surfaces in scenes: OglModel sources (inline, file with placement, loader, boundary of the
// tetrahedra), BarycentricMapping and IdentityMapping during a run, the .vtp series and .pvd
// index a VTKExporter in the visual node writes (parsed back), and bad input with its location.
#include <gtest/gtest.h>
#include <pugixml.hpp>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/mapping/VisualModel.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"
#include "io/surface/SurfaceMesh.h"
#include "tests/support/TempDir.h"

namespace fs = std::filesystem;
using namespace viscera;
using viscera::test_support::TempDir;

namespace {

// A 4 x 3 x 3 node grid over [0,3] x [0,2] x [0,2] (72 tetrahedra), clamped at x = 0 and sagging
// under gravity along -z; VISUAL is replaced by the content of its child node "Visual".
const char* kScene = R"(<Node name="root" dt="0.01" gravity="0 0 -9.81">
  <Node name="body">
    <EulerImplicitSolver rayleighStiffness="0.1" rayleighMass="0.1"/>
    <CGLinearSolver iterations="200" tolerance="1e-12" threshold="1e-30"/>
    <RegularGridTopology name="grid" n="4 3 3" min="0 0 0" max="3 2 2"/>
    <MechanicalObject name="dofs"/>
    <TetrahedronSetTopologyContainer name="tetra"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tetra" swapping="true"/>
    <UniformMass totalMass="10"/>
    <TetrahedronFEMForceField youngModulus="5000" poissonRatio="0.3"/>
    <BoxROI name="left" box="-0.1 -0.1 -0.1 0.1 2.1 2.1"/>
    <FixedConstraint indices="@left.indices"/>
    <Node name="Visual">
VISUAL
    </Node>
  </Node>
</Node>
)";

std::string sceneWith(const std::string& visual) {
  std::string text = kScene;
  text.replace(text.find("VISUAL"), 6, visual);
  return text;
}

// 1-based line of the first occurrence of `needle` in `text`.
int lineOf(const std::string& text, const std::string& needle) {
  const size_t at = text.find(needle);
  return at == std::string::npos ? 0 : 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
}

// A sheet of 7 x 5 vertices over the top face (x = 0, 0.5, .., 3; y = 0, 0.5, .., 2), two
// triangles per cell. Columns with even i lie on the top face z = 2 (those with even j on grid
// nodes); odd columns lie 0.04 above it, outside the tetrahedra.
struct Sheet {
  std::string position, triangles;
  int vertices = 35, faces = 48;
  static int index(int i, int j) { return i + 7 * j; }
  Sheet() {
    std::ostringstream p, t;
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 7; ++i) p << 0.5 * i << " " << 0.5 * j << " " << (i % 2 ? 2.04 : 2.0) << " ";
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 6; ++i)
        t << index(i, j) << " " << index(i + 1, j) << " " << index(i + 1, j + 1) << " " << index(i, j) << " "
          << index(i + 1, j + 1) << " " << index(i, j + 1) << " ";
    position = p.str();
    triangles = t.str();
  }
};

template <class T>
T* find(const Node& n, const std::string& name) {
  for (const auto& c : n.components())
    if (auto* t = dynamic_cast<T*>(c.get()); t && c->name() == name) return t;
  for (const auto& ch : n.children())
    if (T* t = find<T>(*ch, name)) return t;
  return nullptr;
}

// The component of type T called `name` anywhere in the scene.
template <class T>
T& named(const Node& root, const std::string& name) {
  T* t = find<T>(root, name);
  if (!t) throw std::out_of_range("no component " + name);
  return *t;
}

// Builds and initialises a scene written to `dir`/scene.xml (relative files resolve there),
// with outputs in `dir`/out; returns the error message, or "" when it initialises.
struct SceneRun {
  std::unique_ptr<Scene> scene;
  std::unique_ptr<Simulation> sim;
  std::string error;
  SceneRun(const TempDir& dir, const std::string& text) {
    try {
      scene = buildScene(io::parseSceneText(text, dir / "scene.xml"));
      scene->setOutputDirectory(dir / "out");
      sim = std::make_unique<Simulation>(*scene);
    } catch (const Error& e) {
      error = e.what();
    }
  }
  void steps(int n) {
    sim->begin();
    for (int i = 0; i < n; ++i) ASSERT_FALSE(sim->step()) << "step " << i;
    sim->end();
  }
  std::string notes() const {
    std::string all;
    for (const auto& n : scene->notes()) all += n + "\n";
    return all;
  }
};

// Decodes one uncompressed VTK XML binary array: base64 of [UInt64 byte count][bytes].
std::vector<uint8_t> decodeArray(const std::string& text) {
  static const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::vector<uint8_t> raw;
  uint32_t acc = 0;
  int bits = 0;
  for (char c : text) {
    const size_t v = alphabet.find(c);
    if (v == std::string::npos) continue;  // whitespace and '=' padding
    acc = (acc << 6) | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      raw.push_back(static_cast<uint8_t>((acc >> bits) & 0xFF));
    }
  }
  uint64_t count = 0;
  std::memcpy(&count, raw.data(), 8);
  EXPECT_EQ(count, raw.size() - 8);
  return std::vector<uint8_t>(raw.begin() + 8, raw.end());
}

template <class T>
std::vector<T> values(const pugi::xml_node& array) {
  const std::vector<uint8_t> bytes = decodeArray(array.child_value());
  std::vector<T> out(bytes.size() / sizeof(T));
  std::memcpy(out.data(), bytes.data(), out.size() * sizeof(T));
  return out;
}

pugi::xml_node arrayNamed(const pugi::xml_node& parent, const char* name) {
  return parent.find_child_by_attribute("DataArray", "Name", name);
}

TEST(VisualScene, BarycentricSurfaceFollowsTheBodyAndIsWrittenAsVtpSeries) {
  TempDir dir;
  const Sheet sheet;
  const std::string text = sceneWith(R"(      <OglModel name="skin" color="0.8 0.5 0.5" position=")" + sheet.position + R"(" triangles=")" +
                                     sheet.triangles + R"("/>
      <BarycentricMapping input="@.." output="@skin"/>
      <VTKExporter filename="skin" exportEveryNumberOfSteps="2" compress="false" precision="float64"/>)");
  SceneRun run(dir, text);
  ASSERT_EQ(run.error, "");
  // The 15 vertices of the odd columns lie 0.04 above the top face.
  const std::string notes = run.notes();
  EXPECT_NE(notes.find("scene.xml:" + std::to_string(lineOf(text, "<BarycentricMapping")) + ":"), std::string::npos) << notes;
  EXPECT_NE(notes.find("15 of 35 points of 'skin' lie outside the tetrahedra (up to 0.04 m away)"), std::string::npos) << notes;
  run.steps(6);

  const auto& skin = named<VisualModel>(run.scene->root(), "skin");
  const auto& dofs = named<MechanicalObject>(run.scene->root(), "dofs");
  ASSERT_EQ(skin.size(), sheet.vertices);
  // The body sagged; a surface vertex placed on a grid node moves with that node (its
  // coordinates are 1 there and 0 elsewhere, up to round-off of 1e-16 relative).
  const State& state = run.sim->state();
  EXPECT_GT((dofs.x(state) - dofs.x0).colwise().norm().maxCoeff(), 1e-3);
  for (int j = 0; j < 5; j += 2)
    for (int i = 0; i < 7; i += 2) {
      const int node = i / 2 + 4 * (j / 2 + 3 * 2);
      EXPECT_LT((skin.x(state).col(Sheet::index(i, j)) - dofs.x(state).col(node)).norm(), 1e-12) << i << " " << j;
    }

  // Frames at steps 0, 2, 4, 6 and their index.
  const fs::path out = dir / "out";
  std::vector<std::string> vtp;
  for (const auto& e : fs::directory_iterator(out))
    if (e.path().extension() == ".vtp") vtp.push_back(e.path().filename().string());
  std::sort(vtp.begin(), vtp.end());
  EXPECT_EQ(vtp, (std::vector<std::string>{"skin_000000.vtp", "skin_000002.vtp", "skin_000004.vtp", "skin_000006.vtp"}));
  pugi::xml_document pvd;
  ASSERT_TRUE(pvd.load_file((out / "skin.pvd").c_str()));
  std::vector<pugi::xml_node> sets;
  for (auto d : pvd.child("VTKFile").child("Collection").children("DataSet")) sets.push_back(d);
  ASSERT_EQ(sets.size(), 4u);
  for (size_t k = 0; k < sets.size(); ++k) {
    EXPECT_EQ(std::string(sets[k].attribute("file").value()), vtp[k]);
    // Times are step counts times dt, written with round-trip precision.
    EXPECT_NEAR(sets[k].attribute("timestep").as_double(), 0.02 * static_cast<double>(k), 1e-15);
  }

  // The last frame parsed back: counts, the displacement array, and the values as written.
  pugi::xml_document doc;
  ASSERT_TRUE(doc.load_file((out / "skin_000006.vtp").c_str()));
  const pugi::xml_node file = doc.child("VTKFile");
  EXPECT_STREQ(file.attribute("type").value(), "PolyData");
  const pugi::xml_node piece = file.child("PolyData").child("Piece");
  EXPECT_EQ(piece.attribute("NumberOfPoints").as_int(), sheet.vertices);
  EXPECT_EQ(piece.attribute("NumberOfPolys").as_int(), sheet.faces);
  EXPECT_EQ(piece.attribute("NumberOfVerts").as_int(), 0);
  const pugi::xml_node disp = arrayNamed(piece.child("PointData"), "displacement");
  ASSERT_TRUE(disp);
  EXPECT_EQ(disp.attribute("NumberOfComponents").as_int(), 3);
  const pugi::xml_node points = piece.child("Points").child("DataArray");
  EXPECT_EQ(points.attribute("NumberOfComponents").as_int(), 3);
  const auto xs = values<double>(points);
  const auto ds = values<double>(disp);
  ASSERT_EQ(xs.size(), 3u * sheet.vertices);
  ASSERT_EQ(ds.size(), 3u * sheet.vertices);
  const Eigen::Matrix3Xd d = skin.x(state) - skin.x0;
  for (int i = 0; i < skin.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      // Float64 in the file: bit-exact.
      EXPECT_EQ(xs[3 * i + k], skin.x(state)(k, i));
      EXPECT_EQ(ds[3 * i + k], d(k, i));
    }
  const auto conn = values<int64_t>(arrayNamed(piece.child("Polys"), "connectivity"));
  const auto offsets = values<int64_t>(arrayNamed(piece.child("Polys"), "offsets"));
  ASSERT_EQ(conn.size(), 3u * sheet.faces);
  ASSERT_EQ(offsets.size(), static_cast<size_t>(sheet.faces));
  EXPECT_EQ(offsets.back(), 3 * sheet.faces);
  for (int t = 0; t < sheet.faces; ++t)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(conn[3 * t + k], skin.triangles(k, t));
  // The first frame is the rest shape: zero displacement up to the round-off of sum w_i x_i.
  pugi::xml_document first;
  ASSERT_TRUE(first.load_file((out / "skin_000000.vtp").c_str()));
  for (double v : values<double>(arrayNamed(first.child("VTKFile").child("PolyData").child("Piece").child("PointData"), "displacement")))
    EXPECT_LT(std::abs(v), 1e-14);
}

TEST(VisualScene, BoundaryOfTheTetrahedraWithIdentityMapping) {
  TempDir dir;
  // No file: the boundary of the body's tetrahedra over all 36 nodes; the unnamed exporter takes
  // the model's name.
  SceneRun run(dir, sceneWith(R"(      <OglModel name="surf"/>
      <IdentityMapping input="@../dofs" output="@surf"/>
      <VTKExporter exportEveryNumberOfSteps="3"/>)"));
  ASSERT_EQ(run.error, "");
  run.steps(3);
  const auto& surf = named<VisualModel>(run.scene->root(), "surf");
  const auto& dofs = named<MechanicalObject>(run.scene->root(), "dofs");
  // 3 x 2 x 2 cells: 32 boundary squares, two triangles each.
  EXPECT_EQ(surf.triangles.cols(), 64);
  ASSERT_EQ(surf.size(), 36);
  const State& state = run.sim->state();
  EXPECT_EQ(surf.x(state), dofs.x(state));
  EXPECT_GT((surf.x(state) - surf.x0).norm(), 1e-3);
  EXPECT_TRUE(fs::exists(dir / "out/surf_000000.vtp"));
  EXPECT_TRUE(fs::exists(dir / "out/surf_000003.vtp"));
  pugi::xml_document pvd;
  ASSERT_TRUE(pvd.load_file((dir / "out/surf.pvd").c_str()));
  EXPECT_EQ(std::distance(pvd.child("VTKFile").child("Collection").children("DataSet").begin(),
                          pvd.child("VTKFile").child("Collection").children("DataSet").end()),
            2);
}

TEST(VisualScene, ExporterBesideTheMechanicalObjectWritesTheVolume) {
  TempDir dir;
  // A visual model in the body's own node does not turn the body's exporter into a surface one.
  std::string text = sceneWith("");
  const std::string anchor = R"(<FixedConstraint indices="@left.indices"/>)";
  text.replace(text.find(anchor), anchor.size(), anchor + R"(
    <OglModel name="surf"/>
    <IdentityMapping input="@dofs" output="@surf"/>
    <VTKExporter filename="body"/>)");
  SceneRun run(dir, text);
  ASSERT_EQ(run.error, "");
  run.steps(1);
  EXPECT_TRUE(fs::exists(dir / "out/body_000001.vtu"));
  EXPECT_FALSE(fs::exists(dir / "out/body_000001.vtp"));
}

TEST(VisualScene, SurfaceFileWithPlacement) {
  TempDir dir;
  // A tetrahedron's surface (four vertices, four triangles) inside the body once placed:
  // scale3d first, then translation (rotation 0).
  std::ofstream(dir / "tip.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n";
  SceneRun run(dir, sceneWith(R"(      <OglModel name="tip" filename="tip.obj" scale3d="0.5 0.5 0.5" translation="1 0.5 0.5"/>
      <BarycentricMapping/>)"));
  ASSERT_EQ(run.error, "");
  const auto& tip = named<VisualModel>(run.scene->root(), "tip");
  ASSERT_EQ(tip.size(), 4);
  EXPECT_EQ(tip.triangles.cols(), 4);
  Eigen::Matrix3Xd expected(3, 4);
  expected << 1, 1.5, 1, 1,  //
      0.5, 0.5, 1, 0.5,      //
      0.5, 0.5, 0.5, 1;
  EXPECT_LT((tip.x0 - expected).cwiseAbs().maxCoeff(), 1e-15);
  // All inside: no note about extrapolated points.
  EXPECT_EQ(run.notes().find("lie outside"), std::string::npos) << run.notes();
}

TEST(VisualScene, SurfaceFromALoader) {
  TempDir dir;
  // A loader's position and triangles (the Gmsh cube has two surface triangles); mapped by
  // identity onto the loader's body.
  fs::copy_file(std::string(VISCERA_SOURCE_DIR) + "/tests/data/meshes/cube_v2.msh", dir / "cube.msh");
  const std::string text = R"(<Node name="root" dt="0.01" gravity="0 0 -9.81">
  <Node name="body">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="50" tolerance="1e-12" threshold="1e-30"/>
    <MeshGmshLoader name="loader" filename="cube.msh"/>
    <MechanicalObject name="dofs"/>
    <TetrahedronSetTopologyContainer name="topo" src="@loader"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3"/>
    <BoxROI name="clamp" box="-0.1 -0.1 -0.1 1.1 1.1 0.1"/>
    <FixedConstraint indices="@clamp.indices"/>
    <Node name="Visual">
      <VisualModel name="skin" src="@../loader"/>
      <IdentityMapping/>
    </Node>
  </Node>
</Node>
)";
  SceneRun run(dir, text);
  ASSERT_EQ(run.error, "");
  run.steps(2);
  const auto& skin = named<VisualModel>(run.scene->root(), "skin");
  EXPECT_EQ(skin.size(), 8);
  EXPECT_EQ(skin.triangles.cols(), 2);
  EXPECT_EQ(skin.x(run.sim->state()), named<MechanicalObject>(run.scene->root(), "dofs").x(run.sim->state()));
}

// ---------------------------------------------------------------------------------------------
// Bad input: errors at init with the scene location, and nothing written.

struct BadCase {
  std::string visual;  // content of the visual node
  std::string anchor;  // text on the line the error must point at
  std::vector<std::string> expected;
};

void expectError(const BadCase& c) {
  TempDir dir;
  const std::string text = sceneWith(c.visual);
  SceneRun run(dir, text);
  ASSERT_NE(run.error, "") << c.visual;
  EXPECT_NE(run.error.find("scene.xml:" + std::to_string(lineOf(text, c.anchor)) + ":"), std::string::npos) << run.error;
  for (const auto& e : c.expected) EXPECT_NE(run.error.find(e), std::string::npos) << run.error;
  EXPECT_FALSE(fs::exists(dir / "out")) << "outputs written before the error";
}

TEST(VisualSceneErrors, MissingSurfaceFile) {
  expectError({R"(      <OglModel name="skin" filename="nowhere.obj"/>
      <BarycentricMapping input="@.." output="@skin"/>
      <VTKExporter filename="skin"/>)",
               "<OglModel", {"OglModel.filename", "nowhere.obj", "does not exist"}});
}

// The output is a visual model or a mapped MechanicalObject, never the input itself.
TEST(VisualSceneErrors, OutputIsNotAVisualModelOrAMappedState) {
  expectError({R"(      <OglModel name="skin"/>
      <BarycentricMapping input="@.." output="@../dofs"/>)",
               "<BarycentricMapping", {"BarycentricMapping.output", "is the input itself"}});
  expectError({R"(      <OglModel name="skin"/>
      <BarycentricMapping input="@.." output="@../grid"/>)",
               "<BarycentricMapping",
               {"BarycentricMapping.output", "'grid' (RegularGridTopology) is neither a visual model"}});
}

TEST(VisualSceneErrors, InputIsNotAMechanicalObject) {
  expectError({R"(      <OglModel name="skin"/>
      <BarycentricMapping input="@../grid" output="@skin"/>)",
               "<BarycentricMapping", {"BarycentricMapping.input", "'grid' (RegularGridTopology) is not a MechanicalObject"}});
}

TEST(VisualSceneErrors, IdentityMappingSizesDiffer) {
  expectError({R"(      <OglModel name="skin" position="0 0 2  1 0 2  0 1 2" triangles="0 1 2"/>
      <IdentityMapping input="@.." output="@skin"/>)",
               "<IdentityMapping", {"IdentityMapping.output", "'skin' has 3 vertices but 'dofs' has 36 nodes"}});
}

TEST(VisualSceneErrors, PointFarOutside) {
  // The default reach is the mean edge length (about 1.3 here); the fourth vertex is 8 above.
  expectError({R"(      <OglModel name="skin" position="0 0 2  1 0 2  0 1 2  1 1 10" triangles="0 1 2  1 3 2"/>
      <BarycentricMapping input="@.." output="@skin"/>)",
               "<BarycentricMapping",
               {"BarycentricMapping.maxDistance", "1 of 4 points of 'skin' are farther than", "point 3 at (1, 1, 10) is 8 m"}});
  // A reach given explicitly.
  expectError({R"(      <OglModel name="skin" position="0 0 2  1 0 2  0 1 2.5" triangles="0 1 2"/>
      <BarycentricMapping input="@.." output="@skin" maxDistance="0.25"/>)",
               "maxDistance=", {"1 of 3 points", "farther than 0.25 m", "is 0.5 m from the nearest"}});
}

TEST(VisualSceneErrors, TwoMappingsOnOneSurface) {
  expectError({R"(      <OglModel name="skin"/>
      <IdentityMapping input="@.." output="@skin"/>
      <BarycentricMapping name="second" input="@.." output="@skin"/>)",
               "name=\"second\"", {"BarycentricMapping.output", "'skin' is already the output of IdentityMapping"}});
}

TEST(VisualSceneErrors, SurfaceExporterFields) {
  expectError({R"(      <OglModel name="skin"/>
      <IdentityMapping/>
      <VTKExporter fields="displacement velocity"/>)",
               "<VTKExporter", {"VTKExporter.fields", "'velocity' is not a field of the visual surface 'skin'"}});
}

TEST(VisualSceneErrors, TrianglesOutOfRange) {
  expectError({R"(      <OglModel name="skin" position="0 0 2  1 0 2  0 1 2" triangles="0 1 3"/>
      <BarycentricMapping/>)",
               "<OglModel", {"OglModel.triangles", "triangle 0 refers to vertex 3, but there are 3 vertices"}});
}

}  // namespace

// SOFA's exporter form on the body: pointsDataFields="dofs.position dofs.rest_position" adds those
// arrays (exact to float64), and a file name with SOFA's .vtk extension names a .vtu series.
TEST(VolumeExport, SofaPointFieldsAndFileName) {
  TempDir dir;
  std::string text = sceneWith("");
  const std::string exporter =
      R"(<VTKExporter filename="body.vtk" pointsDataFields="dofs.position dofs.rest_position" compress="false" precision="float64"/>)";
  text.replace(text.find("<Node name=\"Visual\">"), 0, exporter);
  SceneRun run(dir, text);
  ASSERT_EQ(run.error, "");
  run.steps(2);
  pugi::xml_document doc;
  ASSERT_TRUE(doc.load_file((fs::path(dir / "out") / "body_000002.vtu").c_str()));
  const pugi::xml_node pd = doc.child("VTKFile").child("UnstructuredGrid").child("Piece").child("PointData");
  const auto& dofs = named<MechanicalObject>(run.scene->root(), "dofs");
  const auto x = values<double>(arrayNamed(pd, "position"));
  const auto x0 = values<double>(arrayNamed(pd, "rest_position"));
  ASSERT_EQ(x.size(), 3u * dofs.size());
  ASSERT_EQ(x0.size(), 3u * dofs.size());
  const Eigen::Matrix3Xd& now = dofs.x(run.sim->state());
  for (int i = 0; i < dofs.size(); ++i)
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(x[3 * i + a], now(a, i));
      EXPECT_EQ(x0[3 * i + a], dofs.x0(a, i));
    }
  EXPECT_TRUE(arrayNamed(pd, "displacement"));  // the default fields stay

  for (const auto& [fields, message] :
       {std::pair<std::string, std::string>{"other.position", "only fields of the exported MechanicalObject 'dofs'"},
        {"dofs.stress", "unknown field 'stress'"}}) {
    std::string bad = sceneWith("");
    bad.replace(bad.find("<Node name=\"Visual\">"), 0, "<VTKExporter pointsDataFields=\"" + fields + "\"/>");
    SceneRun failed(dir, bad);
    EXPECT_NE(failed.error.find("VTKExporter.pointsDataFields: '" + fields + "': " + message), std::string::npos) << failed.error;
  }
}

// SOFA's surface exporters: OBJ frames of the visual surface as it moves (read back: the vertices
// where the model has them, to the 6 significant digits OBJ text keeps), and STL frames of a fixed
// surface given by links.
TEST(SurfaceExport, ObjFramesFollowTheVisualModelAndStlTakesLinkedSurfaces) {
  TempDir dir;
  // A closed tetrahedron surface moved with the body (its vertices are grid nodes).
  const std::string visual = R"(<OglModel name="skin" position="0 0 2  3 0 2  0 2 2  0 0 0" triangles="0 2 1  0 1 3  1 2 3  0 3 2"/>
      <BarycentricMapping input="@.." output="@skin"/>
      <VisualModelOBJExporter filename="skin" exportAtBegin="true" exportEveryNumberOfSteps="2"/>
      <TriangleSetTopologyContainer name="rest" position="0 0 2  3 0 2  0 2 2  0 0 0" triangles="0 2 1  0 1 3  1 2 3  0 3 2"/>
      <STLExporter filename="fixed" exportAtEnd="true" position="@rest.position" triangle="@rest.triangles" binaryformat="false"/>)";
  SceneRun run(dir, sceneWith(visual));
  ASSERT_EQ(run.error, "");
  run.steps(4);
  const fs::path out = dir / "out";
  for (int step : {0, 2, 4}) {
    char name[32];
    std::snprintf(name, sizeof name, "skin_%06d.obj", step);
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  EXPECT_FALSE(fs::exists(out / "skin_000001.obj"));
  const auto& skin = named<VisualModel>(run.scene->root(), "skin");
  const io::SurfaceMesh last = io::readSurface((out / "skin_000004.obj").string());
  ASSERT_EQ(last.points.cols(), 4);
  EXPECT_LT((last.points - skin.x(run.sim->state())).cwiseAbs().maxCoeff(), 1e-5);
  EXPECT_GT((skin.x(run.sim->state()) - skin.x0).cwiseAbs().maxCoeff(), 1e-4);  // it moved
  const io::SurfaceMesh fixed = io::readSurface((out / "fixed_000004.stl").string());
  EXPECT_EQ(fixed.triangles.cols(), 4);
  EXPECT_LT((fixed.points.rowwise().maxCoeff() - Eigen::Vector3d(3, 2, 2)).norm(), 1e-6);  // the fixed surface
  // A link to the moving model is refused: it would be exported frozen.
  std::string bad = sceneWith(R"(<OglModel name="skin" position="0 0 2  3 0 2  0 2 2  0 0 0" triangles="0 2 1  0 1 3  1 2 3  0 3 2"/>
      <BarycentricMapping input="@.." output="@skin"/>
      <STLExporter position="@skin.position" triangle="@skin.triangles"/>)");
  SceneRun refused(dir, bad);
  EXPECT_NE(refused.error.find("STLExporter.position: links to 'skin', which moves"), std::string::npos) << refused.error;
}
