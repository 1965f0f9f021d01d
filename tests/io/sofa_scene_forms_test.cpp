// SOFA scenes as SOFA users write them: <include>, files found along SOFA's data search path, the
// legacy attribute names SOFA still reads (dx dy dz, rx ry rz, scale, nx ny nz, xmin ... zmax),
// MechanicalObject src="@loader", surface loaders, dt/gravity on sub-nodes, positional links and
// spheres mapped on a body.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/Roles.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "tests/support/ErrorOf.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using viscera::test_support::errorOf;
using viscera::test_support::TempDir;

namespace {

void write(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream(path) << text;
}

const MechanicalObject& object(const Scene& s, const std::string& name) {
  for (auto* m : s.all<MechanicalObject>())
    if (m->name() == name) return *m;
  throw std::runtime_error("no MechanicalObject " + name);
}

bool hasNote(const Scene& s, const std::string& part) {
  for (const auto& n : s.notes())
    if (n.find(part) != std::string::npos) return true;
  return false;
}

const char* kTopologyFragment = R"(<Node name="Group">
  <TetrahedronSetTopologyContainer name="Container" src="@" tags=" "/>
  <TetrahedronSetGeometryAlgorithms name="GeomAlgo" template="Vec3"/>
</Node>)";

const char* kTetMesh = R"(# vtk DataFile Version 2.0
one tetrahedron
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 4 double
0 0 0
1 0 0
0 1 0
0 0 1
CELLS 1 5
4 0 1 2 3
CELL_TYPES 1
10
)";

}  // namespace

TEST(SofaSceneForms, IncludeOfAGroupMergesIntoTheNodeAndTakesTheIncludesAttributes) {
  TempDir dir;
  write(dir / "Objects/TetrahedronSetTopology.xml", kTopologyFragment);
  write(dir / "mesh/tet.vtk", kTetMesh);
  write(dir / "scene.scn", R"(<Node name="root">
  <Node name="body">
    <MeshVTKLoader name="loader" filename="mesh/tet.vtk"/>
    <include href="Objects/TetrahedronSetTopology.xml" src="@loader"/>
    <MechanicalObject name="dofs" src="@loader" dx="10" scale="2"/>
  </Node>
</Node>)");
  const SceneDesc desc = io::readScene(dir / "scene.scn");
  // The fragment's children sit in "body" beside the loader; its `src="@"` took the include's value.
  const ElementDesc& container = desc.element("body/Container");
  EXPECT_EQ(container.find("src")->value, "@loader");
  auto scene = buildScene(desc);
  scene->init();
  const MechanicalObject& mo = object(*scene, "dofs");
  ASSERT_EQ(mo.size(), 4);
  // scale 2 (one factor for all axes), then dx 10.
  EXPECT_DOUBLE_EQ(mo.xInit(0, 1), 12.0);
  EXPECT_DOUBLE_EQ(mo.xInit(1, 2), 2.0);
  EXPECT_DOUBLE_EQ(mo.xInit(2, 3), 2.0);
  EXPECT_DOUBLE_EQ(mo.xInit(0, 0), 10.0);
}

TEST(SofaSceneForms, IncludeOfANamedNodeAddsARenamedChildAndNotesUnmatchedAttributes) {
  TempDir dir;
  write(dir / "Objects/Ball.xml", R"(<Node name="Ball">
  <MechanicalObject name="dofs" position="0 0 0" dy="0"/>
  <UniformMass totalMass="1"/>
</Node>)");
  write(dir / "scene.scn", R"(<Node name="root">
  <include name="Ball 1" href="Objects/Ball.xml" dy="-10" contactStiffness="5"/>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  scene->init();
  ASSERT_EQ(scene->root().children().size(), 1u);
  EXPECT_EQ(scene->root().children()[0]->name(), "Ball 1");
  EXPECT_DOUBLE_EQ(object(*scene, "dofs").xInit(1, 0), -10.0);
  EXPECT_TRUE(hasNote(*scene, "include.contactStiffness matches no attribute")) << scene->notes().size();
}

// SOFA's "_Merge_" include: the included root's attributes go to the including node and each named
// child merges into the child of the same tag and name (as SOFA's Demos/include_test.scn merges a
// force field into caduceus.scn's snake); "_Group_" gives the children; `node__a` replaces a only
// in elements named node.
TEST(SofaSceneForms, IncludeMergesGroupsAndReplacesPerNode) {
  TempDir dir;
  write(dir / "body.scn", R"(<Node name="root" dt="0.02">
  <Node name="Snake"><MechanicalObject name="dofs" position="0 0 0"/></Node>
  <Node name="Floor"><MechanicalObject name="floor" position="0 0 0"/></Node>
</Node>)");
  write(dir / "extra.xml", R"(<Node name="_Merge_" gravity="0 0 -9.8">
  <Node name="Snake"><UniformMass name="mass" totalMass="2"/><MechanicalObject name="dofs" dy="1"/></Node>
  <Node name="Other"/>
</Node>)");
  write(dir / "group.xml", R"(<Node name="whatever"><UniformMass name="a" totalMass="1"/><UniformMass name="b" totalMass="1"/></Node>)");
  write(dir / "scene.scn", R"(<Node name="root">
  <include href="body.scn" name="_Merge_" floor__position="1 2 3"/>
  <include href="extra.xml"/>
  <Node name="g"><include href="group.xml" name="_Group_" totalMass="5"/></Node>
</Node>)");
  const SceneDesc desc = io::readScene(dir / "scene.scn");
  EXPECT_EQ(desc.root.find("name")->value, "root");
  EXPECT_EQ(desc.root.find("dt")->value, "0.02");
  EXPECT_EQ(desc.root.find("gravity")->value, "0 0 -9.8");
  ASSERT_EQ(desc.root.children.size(), 4u);  // Snake, Floor, Other, g
  const ElementDesc& snake = desc.element("Snake");
  ASSERT_EQ(snake.children.size(), 2u);  // the MechanicalObject merged, the mass added
  EXPECT_EQ(snake.children[0].find("position")->value, "0 0 0");
  EXPECT_EQ(snake.children[0].find("dy")->value, "1");
  EXPECT_EQ(snake.children[1].tag, "UniformMass");
  EXPECT_EQ(desc.element("Floor/floor").find("position")->value, "1 2 3");
  EXPECT_EQ(desc.element("Snake/dofs").find("position")->value, "0 0 0");  // only in "floor"
  const ElementDesc& g = desc.element("g");
  ASSERT_EQ(g.children.size(), 2u);
  EXPECT_EQ(g.children[1].find("totalMass")->value, "5");
}

TEST(SofaSceneForms, IncludeErrorsNameTheFileAndLine) {
  TempDir dir;
  write(dir / "a.xml", R"(<Node name="A"><include href="b.xml"/></Node>)");
  write(dir / "b.xml", R"(<Node name="B"><include href="a.xml"/></Node>)");
  write(dir / "scene.scn", "<Node name=\"root\">\n  <include href=\"a.xml\"/>\n</Node>");
  std::string e = errorOf([&] { io::readScene(dir / "scene.scn"); });
  EXPECT_NE(e.find("includes itself"), std::string::npos) << e;
  write(dir / "scene.scn", "<Node name=\"root\">\n  <include href=\"missing.xml\"/>\n</Node>");
  e = errorOf([&] { io::readScene(dir / "scene.scn"); });
  EXPECT_NE(e.find("scene.scn:2:"), std::string::npos) << e;
  EXPECT_NE(e.find("'missing.xml' is neither in"), std::string::npos) << e;
  write(dir / "scene.scn", "<Node name=\"root\">\n  <include/>\n</Node>");
  e = errorOf([&] { io::readScene(dir / "scene.scn"); });
  EXPECT_NE(e.find("include.href: required"), std::string::npos) << e;
}

TEST(SofaSceneForms, FilesAreFoundAlongTheDataSearchPath) {
  TempDir dir;
  // SOFA's source tree: share/mesh beside examples/.
  write(dir / "share/mesh/tet.vtk", kTetMesh);
  write(dir / "elsewhere/meshes/other.vtk", kTetMesh);
  const std::string scene = R"(<Node name="root">
  <MeshVTKLoader name="loader" filename="FILE"/>
  <MechanicalObject name="dofs" src="@loader"/>
</Node>)";
  auto load = [&](const std::string& file) {
    std::string text = scene;
    text.replace(text.find("FILE"), 4, file);
    write(dir / "examples/Component/scene.scn", text);
    auto s = buildScene(io::readScene(dir / "examples/Component/scene.scn"));
    s->init();
    return object(*s, "dofs").size();
  };
  EXPECT_EQ(load("tet.vtk"), 4);       // share/mesh, by default
  EXPECT_EQ(load("mesh/tet.vtk"), 4);  // share/
  // SOFA_DATA_PATH and --data-path (setDataPath) add folders.
  std::string e = errorOf([&] { load("meshes/other.vtk"); });
  EXPECT_NE(e.find("does not exist"), std::string::npos) << e;
  ::setenv("SOFA_DATA_PATH", (dir / "elsewhere").c_str(), 1);
  EXPECT_EQ(load("meshes/other.vtk"), 4);
  ::unsetenv("SOFA_DATA_PATH");
  io::setDataPath({dir / "elsewhere"});
  EXPECT_EQ(load("meshes/other.vtk"), 4);
  io::setDataPath({});
}

TEST(SofaSceneForms, LegacyGridNamesAndSubNodeSettings) {
  TempDir dir;
  write(dir / "scene.scn", R"(<Node name="root" dt="0.01" gravity="0 -9.81 0">
  <Node name="body" dt="0.5" gravity="0 0 -1">
    <RegularGridTopology name="grid" nx="3" ny="2" nz="2" xmin="-1" xmax="1" ymin="0" ymax="1" zmin="0" zmax="2"/>
    <MechanicalObject name="dofs" rx="90"/>
  </Node>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  scene->init();
  const MechanicalObject& mo = object(*scene, "dofs");
  ASSERT_EQ(mo.size(), 12);
  // Node 1 is (0, 0, 0) before the rotation of 90 degrees about x; the last node (1, 1, 2) goes to (1, -2, 1).
  EXPECT_NEAR(mo.xInit(0, 11), 1.0, 1e-12);
  EXPECT_NEAR(mo.xInit(1, 11), -2.0, 1e-12);
  EXPECT_NEAR(mo.xInit(2, 11), 1.0, 1e-12);
  // The root's dt and gravity hold for the whole scene, as in SOFA, with a note.
  EXPECT_DOUBLE_EQ(scene->dt(), 0.01);
  EXPECT_DOUBLE_EQ(scene->gravity().y(), -9.81);
  EXPECT_TRUE(hasNote(*scene, "Node.gravity on node 'body' is ignored"));
  EXPECT_TRUE(hasNote(*scene, "Node.dt on node 'body' is ignored"));
  // A legacy part and its vector together, or a part that is not one number, are errors.
  write(dir / "scene.scn", R"(<Node name="root"><MechanicalObject position="0 0 0" scale="2" scale3d="1 1 1"/></Node>)");
  std::string e = errorOf([&] { buildScene(io::readScene(dir / "scene.scn")); });
  EXPECT_NE(e.find("give either scale"), std::string::npos) << e;
  write(dir / "scene.scn", R"(<Node name="root"><MechanicalObject position="0 0 0" dx="1 2"/></Node>)");
  e = errorOf([&] { buildScene(io::readScene(dir / "scene.scn")); });
  EXPECT_NE(e.find("MechanicalObject.dx: expects one number"), std::string::npos) << e;
}

TEST(SofaSceneForms, SurfaceLoadersFeedAMechanicalObject) {
  TempDir dir;
  write(dir / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
  write(dir / "scene.scn", R"(<Node name="root">
  <MeshOBJLoader name="surface" filename="tri.obj" handleSeams="1" translation="0 0 5"/>
  <MechanicalObject name="dofs" src="@surface"/>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  scene->init();
  const MechanicalObject& mo = object(*scene, "dofs");
  ASSERT_EQ(mo.size(), 4);
  EXPECT_DOUBLE_EQ(mo.xInit(2, 3), 6.0);
  // handleSeams (texture seams) is accepted with a note.
  EXPECT_TRUE(hasNote(*scene, "MeshOBJLoader.handleSeams does not change the physics"));
}

TEST(SofaSceneForms, IndexRangesExpandInIntegerLists) {
  TempDir dir;
  write(dir / "scene.scn", R"(<Node name="root">
  <MechanicalObject name="dofs" position="0 0 0 1 0 0 2 0 0 3 0 0 4 0 0 5 0 0"/>
  <UniformMass totalMass="6"/>
  <FixedConstraint name="fixed" indices="0-2 5"/>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  scene->init();
  const ProjectiveConstraint* fixed = scene->all<ProjectiveConstraint>().front();
  EXPECT_EQ(fixed->fixedNodes(), (std::vector<int>{0, 1, 2, 5}));
  write(dir / "scene.scn", R"(<Node name="root"><MechanicalObject position="0 0 0"/><FixedConstraint indices="3-1"/></Node>)");
  std::string e = errorOf([&] { buildScene(io::readScene(dir / "scene.scn")); });
  EXPECT_NE(e.find("range '3-1' ends before it starts"), std::string::npos) << e;
  write(dir / "scene.scn", R"(<Node name="root"><MechanicalObject position="0 0 0"/><FixedConstraint indices="0-99999999999"/></Node>)");
  e = errorOf([&] { buildScene(io::readScene(dir / "scene.scn")); });
  EXPECT_NE(e.find("more than 10000000 values"), std::string::npos) << e;
}

TEST(SofaSceneForms, HostileFormsAreClearErrors) {
  TempDir dir;
  auto problem = [&](const std::string& text) {
    write(dir / "scene.scn", text);
    return errorOf([&] {
      auto s = buildScene(io::readScene(dir / "scene.scn"));
      s->init();
    });
  };
  // A range whose length overflows a 64-bit count is refused, not expanded.
  std::string e = problem(R"(<Node name="root"><MechanicalObject position="0 0 0"/><FixedConstraint indices="1 0-9223372036854775806"/></Node>)");
  EXPECT_NE(e.find("more than 10000000 values"), std::string::npos) << e;
  // A vector with a unit cannot take SOFA's parts as well.
  e = problem(R"(<Node name="root"><MechanicalObject position="0 0 0" translation="0 10 20 mm" dx="5"/></Node>)");
  EXPECT_NE(e.find("MechanicalObject.translation: give three plain numbers"), std::string::npos) << e;
  // A bad part is reported at that part.
  e = problem("<Node name=\"root\">\n<MechanicalObject position=\"0 0 0\" dx=\"1\"\n dz=\"abc\"/></Node>");
  EXPECT_NE(e.find("scene.scn:3:"), std::string::npos) << e;
  EXPECT_NE(e.find("MechanicalObject.dz: expects one number"), std::string::npos) << e;
  // An include that is a folder names the include's line.
  std::filesystem::create_directories(dir / "folder.xml");
  e = problem("<Node name=\"root\">\n  <include href=\"folder.xml\"/>\n</Node>");
  EXPECT_NE(e.find("scene.scn:2:"), std::string::npos) << e;
  // A collision surface whose points are not the body's nodes.
  write(dir / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 2 2 2\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
  e = problem(R"(<Node name="root">
  <MechanicalObject name="dofs" position="0 0 0 1 0 0 0 1 0 0 0 1"/>
  <MeshOBJLoader name="surface" filename="tri.obj"/>
  <TriangleSetTopologyContainer name="tris" src="@surface"/>
  <TriangleCollisionModel/>
</Node>)");
  EXPECT_NE(e.find("whose 5 points are not the nodes of MechanicalObject 'dofs' (4)"), std::string::npos) << e;
}

// SOFA's liver scenes: spheres from a .sph file, found through positional links ("@[-1]": the
// object written just before), on a MechanicalObject that a BarycentricMapping moves with the body.
TEST(SofaSceneForms, SpheresMappedOnABodyFollowItThroughPositionalLinks) {
  TempDir dir;
  write(dir / "tet.vtk", kTetMesh);
  // Sphere 0 at the tetrahedron's centroid; sphere 1 at node 3.
  write(dir / "body.sph", "sph 1.0\nnums 2\n# a comment\nsphe 1 0.25 0.25 0.25 0.1\nsphe 1 0 0 1 0.2\n");
  const std::string body = R"(<Node name="root" dt="0.01" gravity="0 0 -10">
  <CollisionPipeline/><DiscreteIntersection/><CollisionResponse/>
  <Node name="body">
    <EulerImplicitSolver/><CGLinearSolver iterations="100" tolerance="1e-12" threshold="1e-12"/>
    <MeshVTKLoader name="loader" filename="tet.vtk"/>
    <TetrahedronSetTopologyContainer src="@loader"/>
    <MechanicalObject name="dofs" src="@loader"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField youngModulus="100" poissonRatio="0.3"/>
    <FixedConstraint indices="0 1 2"/>
    <Node name="Surf">
      SURF
    </Node>
  </Node>
</Node>)";
  auto sceneWith = [&](const std::string& surf) {
    std::string text = body;
    text.replace(text.find("SURF"), 4, surf);
    write(dir / "scene.scn", text);
    auto s = buildScene(io::readScene(dir / "scene.scn"));
    s->init();
    return s;
  };
  const std::string surf = R"(<SphereLoader filename="body.sph"/>
      <VisualStyle displayFlags="showCollisionModels"/>
      <MechanicalObject name="spheres" position="@[-2].position"/>
      <SphereCollisionModel name="model" listRadius="@[-3].listRadius"/>
      <BarycentricMapping input="@../dofs" output="@spheres"/>)";
  auto scene = sceneWith(surf);
  EXPECT_TRUE(hasNote(*scene, "a model does not collide with itself"));
  Simulation sim(*scene);
  for (int i = 0; i < 5; ++i) ASSERT_FALSE(sim.step());
  const MechanicalObject& dofs = object(*scene, "dofs");
  const MechanicalObject& spheres = object(*scene, "spheres");
  const State& s = sim.state();
  ASSERT_EQ(spheres.size(), 2);
  EXPECT_GT(std::abs(dofs.x(s)(2, 3) - 1.0), 1e-4);  // the free node has moved
  // Barycentric coordinates (1/4 each) and node 3 itself, for positions and velocities.
  EXPECT_LT((spheres.x(s).col(0) - dofs.x(s).rowwise().mean()).norm(), 1e-12);
  EXPECT_LT((spheres.v(s).col(0) - dofs.v(s).rowwise().mean()).norm(), 1e-12);
  EXPECT_LT((spheres.x(s).col(1) - dofs.x(s).col(3)).norm(), 1e-12);
  EXPECT_LT((spheres.v(s).col(1) - dofs.v(s).col(3)).norm(), 1e-12);

  // A positional link that reaches past the node's first object, or names a skipped one.
  std::string e = errorOf([&] { sceneWith(R"(<SphereLoader filename="body.sph"/><MechanicalObject position="@[-2].position"/>)"); });
  EXPECT_NE(e.find("link '@[-2].position': there are only 1 objects before this one"), std::string::npos) << e;
  e = errorOf([&] { sceneWith(R"(<VisualStyle/><MechanicalObject position="@[-1].position"/>)"); });
  EXPECT_NE(e.find("it names the <VisualStyle>, which is ignored here"), std::string::npos) << e;
  // One radius per sphere.
  e = errorOf([&] {
    sceneWith(R"(<SphereLoader filename="body.sph"/><MechanicalObject name="spheres" position="@[-1].position"/>
      <SphereCollisionModel listRadius="1 2 3"/><BarycentricMapping input="@../dofs" output="@spheres"/>)");
  });
  EXPECT_NE(e.find("listRadius: has 3 radii for the 2 nodes"), std::string::npos) << e;
  // A force on the mapped state would not reach the body: refused.
  e = errorOf([&] {
    sceneWith(R"(<SphereLoader filename="body.sph"/><MechanicalObject name="spheres" position="@[-1].position"/>
      <UniformMass totalMass="1"/><BarycentricMapping input="@../dofs" output="@spheres"/>)");
  });
  EXPECT_NE(e.find("forces and constraints on a mapped state are not carried back"), std::string::npos) << e;
  // Spheres on a deformable body beside an instrument: contact with a deformable body's spheres is refused.
  e = errorOf([&] {
    sceneWith(surf + R"(<Node name="other"><MechanicalObject template="Rigid3d" position="0 0 3 0 0 0 1"/><SphereCollisionModel radius="1"/></Node>)");
  });
  EXPECT_NE(e.find("contact between deformable bodies is not handled"), std::string::npos) << e;
  // Sphere files: the line of a bad entry, and a count that does not match.
  write(dir / "body.sph", "sph 1.0\nsphe 1 0 0 0\n");
  e = errorOf([&] { sceneWith(surf); });
  EXPECT_NE(e.find("body.sph:2:"), std::string::npos) << e;
  EXPECT_NE(e.find("5 numbers"), std::string::npos) << e;
  write(dir / "body.sph", "sph 1.0\nnums 3\nsphe 1 0 0 0 1\n");
  e = errorOf([&] { sceneWith(surf); });
  EXPECT_NE(e.find("\"nums\" announces 3 spheres but the file has 1"), std::string::npos) << e;
}

// BarycentricMapping on a grid without tetrahedra (SOFA's free-form deformation): each point
// follows the trilinear interpolation of the cell it lies in (a point outside follows the nearest
// cell, extrapolated), for positions and velocities; checked against trilinear weights computed
// here from the grid's node order.
TEST(SofaSceneForms, PointsFollowAGridThroughTrilinearCoordinates) {
  TempDir dir;
  write(dir / "scene.scn", R"(<Node name="root" dt="0.01" gravity="0 0 -10">
  <Node name="body">
    <EulerImplicitSolver/><CGLinearSolver iterations="200" tolerance="1e-12" threshold="1e-20"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <RegularGridTopology nx="3" ny="3" nz="3" xmin="0" xmax="2" ymin="0" ymax="2" zmin="0" zmax="2"/>
    <BoxConstraint box="-0.1 -0.1 -0.1 2.1 2.1 0.1"/>
    <RegularGridSpringForceField stiffness="50" damping="0.1"/>
    <Node name="mapped">
      <MechanicalObject name="points" position="0.5 0.5 0.5  1.5 0.25 1.8  2.2 1 1"/>
      <BarycentricMapping input="@../dofs" output="@points"/>
    </Node>
  </Node>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  scene->init();
  EXPECT_TRUE(hasNote(*scene, "1 of 3 points of 'points' lie outside the hexahedra"));
  Simulation sim(*scene);
  for (int i = 0; i < 20; ++i) ASSERT_FALSE(sim.step());
  const MechanicalObject& dofs = object(*scene, "dofs");
  const MechanicalObject& points = object(*scene, "points");
  const State& s = sim.state();
  // Node (i, j, k) of the 3 x 3 x 3 grid is i + 3 (j + 3 k); cell (ci, cj, ck), local u in [0, 1]^3.
  auto trilinear = [&](const Eigen::Matrix3Xd& x, int ci, int cj, int ck, Eigen::Vector3d u) {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int c = 0; c < 8; ++c) {
      const int a = c & 1, b = (c >> 1) & 1, d = (c >> 2) & 1;
      const double w = (a ? u[0] : 1 - u[0]) * (b ? u[1] : 1 - u[1]) * (d ? u[2] : 1 - u[2]);
      p += w * x.col((ci + a) + 3 * ((cj + b) + 3 * (ck + d)));
    }
    return p;
  };
  EXPECT_GT((dofs.x(s) - dofs.x0).norm(), 1e-3);  // the body has sagged
  EXPECT_LT((points.x(s).col(0) - trilinear(dofs.x(s), 0, 0, 0, Eigen::Vector3d(0.5, 0.5, 0.5))).norm(), 1e-12);
  EXPECT_LT((points.x(s).col(1) - trilinear(dofs.x(s), 1, 0, 1, Eigen::Vector3d(0.5, 0.25, 0.8))).norm(), 1e-12);
  EXPECT_LT((points.v(s).col(1) - trilinear(dofs.v(s), 1, 0, 1, Eigen::Vector3d(0.5, 0.25, 0.8))).norm(), 1e-12);
  // Outside, beyond x = 2: the nearest cell's coordinates run past 1.
  EXPECT_LT((points.x(s).col(2) - trilinear(dofs.x(s), 1, 0, 0, Eigen::Vector3d(1.2, 1.0, 1.0))).norm(), 1e-9);
}

// Sphere sets on two deformable bodies are accepted while apart; when they touch, the step fails
// and names both (contact between deformable bodies is not handled).
TEST(SofaSceneForms, SpheresOnTwoBodiesStopTheRunWhenTheyTouch) {
  TempDir dir;
  auto body = [](const std::string& name, double x) {
    const std::string p = std::to_string(x);
    return "<Node name=\"" + name + "\"><EulerImplicitSolver/><CGLinearSolver/>"
           "<MechanicalObject name=\"" + name + "_dofs\" position=\"" + p + " 0 0\"/><UniformMass totalMass=\"1\"/>"
           "<SphereCollisionModel name=\"" + name + "_spheres\" radius=\"0.5\"/></Node>";
  };
  write(dir / "apart.scn", "<Node name=\"root\" gravity=\"0 0 0\"><CollisionPipeline/><DiscreteIntersection/>" +
                               body("a", 0) + body("b", 3) + "</Node>");
  auto scene = buildScene(io::readScene(dir / "apart.scn"));
  scene->init();
  Simulation apart(*scene);
  EXPECT_FALSE(apart.step());
  write(dir / "touch.scn", "<Node name=\"root\" gravity=\"0 0 0\"><CollisionPipeline/><DiscreteIntersection/>" +
                               body("a", 0) + body("b", 0.8) + "</Node>");
  scene = buildScene(io::readScene(dir / "touch.scn"));
  scene->init();
  Simulation touch(*scene);
  const auto failed = touch.step();
  ASSERT_TRUE(failed);
  EXPECT_NE(failed->reason.find("spheres of 'a_spheres' and 'b_spheres' touch"), std::string::npos) << failed->reason;
}

// MeshTopology holds whatever a mesh has: from a surface file its points and triangles (a collision
// surface can come from it), from explicit lists hexahedra as well (a grid-like body).
TEST(SofaSceneForms, MeshTopologyHoldsTrianglesQuadsAndHexahedra) {
  TempDir dir;
  write(dir / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
  write(dir / "scene.scn", R"(<Node name="root">
  <MeshTopology name="surface" filename="tri.obj"/>
  <MechanicalObject name="dofs" src="@surface"/>
  <Node name="cube">
    <MeshTopology name="hexa" position="0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1" hexahedra="0 1 2 3 4 5 6 7"/>
    <MechanicalObject name="cubeDofs"/>
    <UniformMass totalMass="8"/>
    <HexahedronFEMForceField youngModulus="100" poissonRatio="0.3"/>
  </Node>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  scene->init();
  EXPECT_EQ(object(*scene, "dofs").size(), 4);
  EXPECT_EQ(object(*scene, "cubeDofs").size(), 8);
  FieldValue tris;
  const Component* surface = nullptr;
  for (const auto& c : scene->root().components())
    if (c->name() == "surface") surface = c.get();
  ASSERT_TRUE(surface && surface->field("triangles", tris));
  EXPECT_EQ(tris.values.size(), 12u);
  // An index past the points is an error naming the attribute.
  write(dir / "scene.scn", R"(<Node name="root"><MeshTopology position="0 0 0 1 0 0 0 1 0" triangles="0 1 3"/></Node>)");
  const std::string e = errorOf([&] { buildScene(io::readScene(dir / "scene.scn"))->init(); });
  EXPECT_NE(e.find("MeshTopology.triangles"), std::string::npos) << e;
  EXPECT_NE(e.find("refers to node 3, but there are 3 points"), std::string::npos) << e;
}

// On a grid, points are located in the grid's own geometry, before the MechanicalObject's placement
// (as SOFA's grid mapper): a body moved by translation carries a surface written at the grid.
TEST(SofaSceneForms, GridMappingLocatesPointsBeforeThePlacement) {
  TempDir dir;
  write(dir / "scene.scn", R"(<Node name="root" gravity="0 0 0">
  <Node name="body">
    <EulerImplicitSolver/><CGLinearSolver/>
    <MechanicalObject name="dofs" translation="10 0 0"/>
    <UniformMass totalMass="1"/>
    <RegularGridTopology n="2 2 2" min="0 0 0" max="1 1 1"/>
    <Node name="mapped">
      <MechanicalObject name="points" position="0.5 0.25 0.75"/>
      <BarycentricMapping/>
    </Node>
  </Node>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  Simulation sim(*scene);
  ASSERT_FALSE(sim.step());
  EXPECT_LT((object(*scene, "points").x(sim.state()).col(0) - Eigen::Vector3d(10.5, 0.25, 0.75)).norm(), 1e-12);
}

// SparseGridTopology keeps the grid cells a closed surface meets or encloses. For the octahedron
// |x| + |y| + |z| <= 3 on a 13 x 13 x 13 node grid over its bounding box grown by 1 % a side (as
// SOFA grows it: cells of 0.51 over [-3.06, 3.06]^3), a cell meets the solid iff the L1 norm of
// its point nearest the centre is at most 3: every such cell is kept (the ones the surface crosses
// and the enclosed ones), none other. Numbering follows SOFA: nodes sorted by position (x, then y,
// then z), the cells the surface crosses before the enclosed ones.
TEST(SofaSceneForms, SparseGridKeepsTheCellsASurfaceMeetsOrEncloses) {
  TempDir dir;
  write(dir / "octa.obj", "v 3 0 0\nv -3 0 0\nv 0 3 0\nv 0 -3 0\nv 0 0 3\nv 0 0 -3\n"
                          "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n");
  write(dir / "scene.scn", R"(<Node name="root">
  <SparseGridTopology name="grid" n="13 13 13" fileTopology="octa.obj"/>
  <MechanicalObject name="dofs"/>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  scene->init();
  const Topology* grid = scene->all<Topology>().front();
  const MechanicalObject& dofs = object(*scene, "dofs");
  ASSERT_EQ(dofs.size(), grid->points().cols());
  const double w = 6.12 / 12, origin = -3.06;
  // L1 norms of a cell's points nearest to and farthest from the centre.
  auto nearestL1 = [&](const Eigen::Vector3d& lo) {
    double s = 0;
    for (int a = 0; a < 3; ++a) s += lo[a] >= 0 ? lo[a] : (lo[a] + w <= 0 ? -(lo[a] + w) : 0.0);
    return s;
  };
  auto farthestL1 = [&](const Eigen::Vector3d& lo) {
    double s = 0;
    for (int a = 0; a < 3; ++a) s += std::max(std::abs(lo[a]), std::abs(lo[a] + w));
    return s;
  };
  auto cellOf = [&](const Eigen::Vector3d& lo) {
    std::array<int, 3> c{};
    for (int a = 0; a < 3; ++a) c[a] = static_cast<int>(std::lround((lo[a] - origin) / w));
    return c;
  };
  std::set<std::array<int, 3>> kept;
  bool enclosedSeen = false;
  for (const auto& h : grid->hexahedra()) {
    const Eigen::Vector3d lo = grid->points().col(h[0]);
    EXPECT_LE(nearestL1(lo), 3.0) << lo.transpose();
    EXPECT_NEAR((grid->points().col(h[6]) - lo).norm(), std::sqrt(3.0) * w, 1e-12);  // corners in order
    kept.insert(cellOf(lo));
    const bool enclosed = farthestL1(lo) < 3.0;  // the surface does not reach into it
    EXPECT_TRUE(enclosed || !enclosedSeen) << "a crossed cell after an enclosed one at " << lo.transpose();
    enclosedSeen = enclosedSeen || enclosed;
  }
  EXPECT_TRUE(enclosedSeen);
  int meeting = 0;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j)
      for (int k = 0; k < 12; ++k)
        if (nearestL1(Eigen::Vector3d(origin + i * w, origin + j * w, origin + k * w)) < 3.0) {
          ++meeting;
          EXPECT_TRUE(kept.count({i, j, k})) << i << " " << j << " " << k;
        }
  EXPECT_EQ(static_cast<int>(grid->hexahedra().size()), meeting);
  for (Eigen::Index v = 1; v < grid->points().cols(); ++v) {
    const Eigen::Vector3d a = grid->points().col(v - 1), b = grid->points().col(v);
    EXPECT_TRUE(std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3)) << "node " << v;
  }
}

// SOFA's collision node under a body: a TriangleCollisionModel on a mapped MechanicalObject acts on
// the body through the mapping. With the mapped points at the body's own nodes (IdentityMapping)
// the run equals the one with the model on the body itself, to round-off.
TEST(SofaSceneForms, ACollisionSurfaceOnAMappedStateActsOnTheBody) {
  auto sceneWith = [](const std::string& surface) {
    return R"(<Node name="root" dt="0.05" gravity="0 0 0">
  <CollisionPipeline/><MinProximityIntersection alarmDistance="0.3" contactDistance="0.05"/>
  <CollisionResponse response="PenalityContactForceField"/>
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d" position="1 1 1.6 0 0 0 1"/>
    <LinearMovementConstraint keyTimes="0 1" movements="0 0 0 0 0 0  0 0 -0.5 0 0 0"/>
    <SphereCollisionModel radius="0.5"/>
  </Node>
  <Node name="body">
    <EulerImplicitSolver/><SparseLDLSolver/>
    <RegularGridTopology name="grid" n="3 3 2" min="0 0 0" max="2 2 1"/>
    <TetrahedronSetTopologyContainer name="tets"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tets"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField youngModulus="100" poissonRatio="0.3"/>
    <BoxROI name="bottom" box="-1 -1 -1 3 3 0.1"/><FixedConstraint indices="@bottom.indices"/>
    )" + surface + R"(
  </Node>
</Node>)";
  };
  auto run = [&](const std::string& surface) {
    auto scene = buildScene(io::parseSceneText(sceneWith(surface), "mapped_surface.xml"));
    Simulation sim(*scene);
    for (int i = 0; i < 20; ++i) EXPECT_FALSE(sim.step());
    return object(*scene, "dofs").x(sim.state());
  };
  const Eigen::Matrix3Xd direct = run(R"(<TriangleCollisionModel contactStiffness="100"/>)");
  const Eigen::Matrix3Xd mapped = run(R"(<Node name="surf"><MechanicalObject name="surfDofs" src="@../grid"/>
      <TriangleCollisionModel contactStiffness="100"/><IdentityMapping input="@../dofs" output="@surfDofs"/></Node>)");
  const Eigen::Matrix3Xd x0 = [&] {
    auto s = buildScene(io::parseSceneText(sceneWith(""), "rest.xml"));
    s->init();
    return object(*s, "dofs").x0;
  }();
  EXPECT_GT((direct - x0).norm(), 1e-3);  // the sphere pressed the body
  EXPECT_LT((mapped - direct).norm(), 1e-9 * (direct - x0).norm());
}

// Two blocks meet under the penalty response: the moving one stops short of passing through and
// pushes the other on. Each contact force between the two bodies is computed where the step starts
// and acts, equal and opposite, on both (as SOFA applies an interaction between two solvers), so
// the total momentum is kept to round-off. The stiffness is within the held force's stability
// limit (k h^2 / m = 0.14 per contact): a stiffer one makes energy, in SOFA as here.
TEST(SofaSceneForms, SurfacesOfTwoBodiesCollideUnderThePenaltyResponse) {
  auto block = [](const std::string& name, double x, double vx) {
    return "<Node name=\"" + name + "\"><EulerImplicitSolver/><SparseLDLSolver/>"
           "<RegularGridTopology name=\"grid\" n=\"2 2 2\" min=\"" + std::to_string(x) + " 0 0\" max=\"" + std::to_string(x + 1) + " 1 1\"/>"
           "<TetrahedronSetTopologyContainer name=\"tets\"/><Hexa2TetraTopologicalMapping input=\"@grid\" output=\"@tets\"/>"
           "<MechanicalObject name=\"" + name + "_dofs\" velocity=\"" + std::to_string(vx) + " 0 0\"/><UniformMass totalMass=\"1\"/>"
           "<TetrahedronFEMForceField youngModulus=\"100\" poissonRatio=\"0.3\"/>"
           "<TriangleCollisionModel name=\"" + name + "_surface\" contactStiffness=\"3\"/></Node>";
  };
  const std::string text = "<Node name=\"root\" dt=\"0.01\" gravity=\"0 0 0\"><CollisionPipeline/>"
                           "<MinProximityIntersection alarmDistance=\"0.1\" contactDistance=\"0.05\"/>" +
                           block("left", 0, 1) + block("right", 2, 0) + "</Node>";
  auto scene = buildScene(io::parseSceneText(text, "two_blocks.xml"));
  Simulation sim(*scene);
  const MechanicalObject &left = object(*scene, "left_dofs"), &right = object(*scene, "right_dofs");
  // Equal masses on equal node counts: the momentum is the sum of the mean velocities, 1 before.
  auto momentum = [&] { return left.v(sim.state()).row(0).mean() + right.v(sim.state()).row(0).mean(); };
  int touched = 0;
  for (int i = 1; i <= 250; ++i) {
    ASSERT_FALSE(sim.step()) << "step " << i;
    if (right.v(sim.state()).row(0).mean() > 1e-9 && !touched) touched = i;
    ASSERT_NEAR(momentum(), 1.0, 1e-9) << "step " << i;
  }
  EXPECT_GT(touched, 50) << "the blocks touch after the gap of 1 closes";
  const double pl = left.v(sim.state()).row(0).mean(), pr = right.v(sim.state()).row(0).mean();
  EXPECT_GT(pr, 0.5) << "the right block was pushed";
  EXPECT_LT(pl, 0.5) << "the left block was stopped";
  const double energy = 0.5 * (left.v(sim.state()).squaredNorm() + right.v(sim.state()).squaredNorm()) / 8;
  EXPECT_LT(energy, 0.5) << "no energy is made (0.5 before the contact)";
  // No node of the left block passed the right block's near face (less the contact distance).
  EXPECT_LT(left.x(sim.state()).row(0).maxCoeff(), right.x(sim.state()).row(0).minCoeff());
}

// Far past the held force's stability limit (k h^2 / m = 1.6e4) the blocks blow apart, and the
// failed step says why.
TEST(SofaSceneForms, AFailedStepNamesTheHeldContactsBetweenBodies) {
  auto block = [](const std::string& name, double x, double vx) {
    return "<Node name=\"" + name + "\"><EulerImplicitSolver/><SparseLDLSolver/>"
           "<RegularGridTopology name=\"grid\" n=\"2 2 2\" min=\"" + std::to_string(x) + " 0 0\" max=\"" + std::to_string(x + 1) + " 1 1\"/>"
           "<TetrahedronSetTopologyContainer name=\"tets\"/><Hexa2TetraTopologicalMapping input=\"@grid\" output=\"@tets\"/>"
           "<MechanicalObject velocity=\"" + std::to_string(vx) + " 0 0\"/><UniformMass totalMass=\"1\"/>"
           "<TetrahedronFEMForceField youngModulus=\"100\" poissonRatio=\"0.3\"/>"
           "<TriangleCollisionModel contactStiffness=\"1000\"/></Node>";
  };
  const std::string text = "<Node name=\"root\" dt=\"0.01\" gravity=\"0 0 0\"><CollisionPipeline/>"
                           "<MinProximityIntersection alarmDistance=\"0.1\" contactDistance=\"0.05\"/>" +
                           block("left", 0, 1) + block("right", 1.02, 0) + "</Node>";
  auto scene = buildScene(io::parseSceneText(text, "stiff_blocks.xml"));
  Simulation sim(*scene);
  std::optional<Diverged> bad;
  for (int i = 1; i <= 200 && !bad; ++i) bad = sim.step();
  ASSERT_TRUE(bad) << "the blocks did not blow apart";
  // The four vertices of each facing face against the other's face: 8 contacts, each pair once.
  EXPECT_NE(bad->reason.find("8 penalty contact(s) between two integrated bodies held their force"), std::string::npos) << bad->reason;
  EXPECT_NE(bad->reason.find("lower contactStiffness or the time step"), std::string::npos) << bad->reason;
}

// SOFA's rigid mass written whole, "mass volume [inertia per unit mass]" (rows split by commas or
// not): the mass, and the inertia as mass x matrix; the volume is not used.
TEST(SofaSceneForms, ARigidMassWrittenWholeGivesMassAndInertia) {
  auto body = [](const std::string& vertexMass) {
    auto scene = buildScene(io::parseSceneText(R"(<Node name="root"><Node name="b"><EulerImplicitSolver/>
      <MechanicalObject template="Rigid3d" position="0 0 0 0 0 0 1"/><UniformMass vertexMass=")" + vertexMass +
                                                   R"("/></Node></Node>)", "rigid_mass.scn"));
    scene->init();
    const RigidObject& r = *scene->all<RigidObject>().front();
    return std::make_pair(r.mass, Eigen::Matrix3d(r.inertia));
  };
  for (const char* text : {"2 1 [1 0 0,0 2 0,0 0 3]", "2 0.5 [1 0 0 0 2 0 0 0 3]"}) {
    const auto [m, I] = body(text);
    EXPECT_EQ(m, 2.0) << text;
    EXPECT_TRUE(I.isApprox(Eigen::Vector3d(2, 4, 6).asDiagonal().toDenseMatrix())) << text << "\n" << I;
  }
  const std::string why = test_support::errorOf([&] { body("2 1 [1 0 0,0 2 0]"); });
  EXPECT_NE(why.find("rigid_mass.scn:2"), std::string::npos) << why;
  EXPECT_NE(why.find("UniformMass.vertexMass: SOFA's rigid mass is 'mass volume [9 numbers"), std::string::npos) << why;
}

// SOFA's GridMeshCreator: points over the unit square, x fastest, placed like a loaded mesh (scale,
// then rotation, then translation); faces cut as SOFA's patterns; each edge once, in SOFA's order.
TEST(SofaSceneForms, GridMeshCreatorMakesSofasGrid) {
  auto fields = [](const std::string& pattern) {
    auto scene = buildScene(io::parseSceneText(R"(<Node name="root"><GridMeshCreator name="grid" filename="nofile" resolution="3 2"
      trianglePattern=")" + pattern + R"(" scale="4 2 1" translation="1 0 5"/></Node>)", "grid.scn"));
    scene->init();
    Component* grid = nullptr;
    for (const auto& c : scene->root().components())
      if (c->name() == "grid") grid = c.get();
    std::map<std::string, std::vector<double>> out;
    for (const char* f : {"position", "edges", "triangles", "quads"}) {
      FieldValue v;
      EXPECT_TRUE(grid->field(f, v)) << f;
      out[f] = v.values;
    }
    return out;
  };
  auto f = fields("1");
  EXPECT_EQ(f["position"], (std::vector<double>{1, 0, 5, 3, 0, 5, 5, 0, 5, 1, 2, 5, 3, 2, 5, 5, 2, 5}));
  // Alternate: cell (0,0) cut from (0,0) to (1,1), cell (1,0) the other way.
  EXPECT_EQ(f["triangles"], (std::vector<double>{0, 1, 4, 0, 4, 3, 1, 2, 4, 2, 5, 4}));
  EXPECT_EQ(f["edges"], (std::vector<double>{0, 1, 1, 2, 1, 4, 2, 4, 2, 5, 3, 0, 4, 0, 4, 3, 5, 4}));
  EXPECT_TRUE(f["quads"].empty());
  auto q = fields("0");
  EXPECT_EQ(q["quads"], (std::vector<double>{0, 1, 4, 3, 1, 2, 5, 4}));
  EXPECT_TRUE(q["triangles"].empty());
  EXPECT_EQ(q["edges"].size(), 2u * 7);
}

// SOFA's AddDataRepository puts a folder (from the scene's) on the search path of its files, and
// its Gravity component in the root node sets the scene's gravity.
TEST(SofaSceneForms, AddDataRepositoryAndGravity) {
  TempDir dir;
  write(dir / "meshes/tet.vtk", kTetMesh);
  write(dir / "scene.scn", R"(<Node name="root" gravity="0 -9.81 0">
  <AddDataRepository path="meshes"/>
  <Gravity gravity="0 0 -3"/>
  <Node name="body"><MeshVTKLoader name="loader" filename="tet.vtk"/><MechanicalObject name="dofs" src="@loader"/></Node>
</Node>)");
  auto scene = buildScene(io::readScene(dir / "scene.scn"));
  scene->init();
  EXPECT_EQ(object(*scene, "dofs").size(), 4);
  EXPECT_EQ(scene->gravity(), Eigen::Vector3d(0, 0, -3));
  // Gravity is one for the whole scene: a sub-node's Gravity is refused.
  write(dir / "sub.scn", R"(<Node name="root"><Node name="n"><Gravity gravity="0 0 -3"/></Node></Node>)");
  std::string why;
  try {
    buildScene(io::readScene(dir / "sub.scn"));
  } catch (const Error& e) {
    why = e.what();
  }
  EXPECT_NE(why.find("sub.scn:1"), std::string::npos) << why;
  EXPECT_NE(why.find("root node"), std::string::npos) << why;
}

// An OglModel without a file takes the surface of the nearest topology above it: a grid's boundary
// (two triangles per boundary quad), or the triangles a Quad2TriangleTopologicalMapping wrote
// (here from inward quads, so the two surfaces differ).
TEST(SofaSceneForms, AVisualModelWithoutAFileTakesTheSurfaceAbove) {
  auto trianglesOf = [](const std::string& inner) {
    auto scene = buildScene(io::parseSceneText(R"(<Node name="root"><Node name="body">
      <RegularGridTopology name="grid" n="2 2 2" min="0 0 0" max="1 1 1"/><MechanicalObject/>)" + inner + R"(</Node></Node>)",
                                               "visual_surface.xml"));
    scene->init();
    FieldValue t;
    for (Component* c : scene->all<Component>())
      if (c->name() == "Visual") c->field("triangles", t);
    return t.values;
  };
  const auto grid = trianglesOf(R"(<Node name="v"><OglModel name="Visual"/><IdentityMapping/></Node>)");
  const auto split = trianglesOf(R"(<Node name="q"><QuadSetTopologyContainer name="quads"/>
      <Hexa2QuadTopologicalMapping input="@../grid" output="@quads" flipNormals="true"/>
      <Node name="t"><TriangleSetTopologyContainer name="tris"/><Quad2TriangleTopologicalMapping input="@../quads" output="@tris"/>
      <Node name="v"><OglModel name="Visual"/><IdentityMapping input="@../../.." output="@Visual"/></Node></Node></Node>)");
  EXPECT_EQ(grid.size(), 36u);
  EXPECT_EQ(split.size(), 36u);
  EXPECT_NE(grid, split);
}
