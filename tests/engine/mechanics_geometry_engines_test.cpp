// Engines that compute geometry, checked against values worked out by hand: the volumes of a cube
// (its surface and its grid cells) and of one tetrahedron, TransformEngine's placement and its
// inverse, an ITK affine transform file read by TransformPosition, and the edge-set and point-set
// containers SOFA scenes put springs and points in.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <set>
#include <string>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Roles.h"
#include "io/scene/SceneReader.h"
#include "tests/support/ErrorOf.h"
#include "tests/support/TempDir.h"

using namespace viscera;

namespace {

std::unique_ptr<Scene> build(const std::string& body, const std::string& file = "engines.xml") {
  auto scene = buildScene(io::parseSceneText("<Node name=\"root\" gravity=\"0 0 0\">" + body + "</Node>", file));
  scene->init();
  return scene;
}

std::vector<double> fieldOf(Scene& s, const std::string& component, const std::string& field) {
  for (Component* c : s.all<Component>())
    if (c->name() == component) {
      FieldValue f;
      EXPECT_TRUE(c->field(field, f)) << component << "." << field;
      return f.values;
    }
  ADD_FAILURE() << "no component " << component;
  return {};
}

// The 8 corners of [0,2]^3 and its 12 outward triangles.
const char* kCube = R"(position="0 0 0  2 0 0  2 2 0  0 2 0  0 0 2  2 0 2  2 2 2  0 2 2"
  triangles="0 2 1  0 3 2  4 5 6  4 6 7  0 1 5  0 5 4  1 2 6  1 6 5  2 3 7  2 7 6  3 0 4  3 4 7")";

}  // namespace

TEST(GeometryEngines, VolumesOfACubeAndATetrahedron) {
  auto surface = build(std::string(R"(<TriangleSetTopologyContainer name="surface" )") + kCube +
                       R"(/><MechanicalObject position="@surface.position"/><VolumeFromTriangles name="v"/>)");
  EXPECT_NEAR(fieldOf(*surface, "v", "volume").at(0), 8.0, 1e-12);
  // The 3 x 3 x 3 node grid over [0,1] x [0,2] x [0,3]: eight hexahedra of volume 6 / 8.
  auto grid = build(R"(<RegularGridTopology n="3 3 3" min="0 0 0" max="1 2 3"/><MechanicalObject/>
                       <VolumeFromVolumetricElements name="v"/>)");
  EXPECT_NEAR(fieldOf(*grid, "v", "volume").at(0), 6.0, 1e-12);
  auto tet = build(R"(<MechanicalObject position="0 0 0  3 0 0  0 2 0  0 0 1"/>
                      <TetrahedronSetTopologyContainer tetrahedra="0 1 2 3"/><VolumeFromVolumetricElements name="v"/>)");
  EXPECT_NEAR(fieldOf(*tet, "v", "volume").at(0), 1.0, 1e-12);  // 3 * 2 * 1 / 6
  EXPECT_NE(test_support::errorOf([] {
              build(R"(<MechanicalObject position="0 0 0"/><PointSetTopologyContainer position="0 0 0"/>
                       <VolumeFromTriangles update="true"/>)");
            }).find("VolumeFromTriangles.update: the volume is computed once"),
            std::string::npos);
}

// Scale, then 90 degrees about z, then the translation; the inverse engine takes the output back.
TEST(GeometryEngines, TransformEnginePlacesPointsAndItsInverseUndoesIt) {
  auto s = build(R"(<TransformEngine name="t" input_position="1 0 0  0 1 2" scale3d="2 3 4" rotation="0 0 90" translation="10 0 0"/>
                    <TransformEngine name="back" input_position="@t.output_position" scale3d="2 3 4" rotation="0 0 90"
                                     translation="10 0 0" inverse="true"/>)");
  const auto out = fieldOf(*s, "t", "output_position");
  // (1,0,0) -> (2,0,0) -> (0,2,0) -> (10,2,0); (0,1,2) -> (0,3,8) -> (-3,0,8) -> (7,0,8).
  const std::vector<double> expected{10, 2, 0, 7, 0, 8};
  ASSERT_EQ(out.size(), expected.size());
  for (size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(out[i], expected[i], 1e-12) << i;
  const auto back = fieldOf(*s, "back", "output_position");
  const std::vector<double> input{1, 0, 0, 0, 1, 2};
  ASSERT_EQ(back.size(), input.size());
  for (size_t i = 0; i < back.size(); ++i) EXPECT_NEAR(back[i], input[i], 1e-12) << i;
}

TEST(GeometryEngines, TransformPositionReadsAnItkAffineTransform) {
  test_support::TempDir dir;
  std::ofstream(dir / "t.tfm") << "#Insight Transform File V1.0\n#Transform 0\nTransform: AffineTransform_double_3_3\n"
                                  "Parameters: 0 -1 0 1 0 0 0 0 2 1 2 3\nFixedParameters: 1 1 1\n";
  auto s = build(R"(<TransformPosition name="t" method="fromFile" filename="t.tfm" input_position="2 1 1  1 1 0"/>)",
                 dir / "scene.xml");
  // y = A (x - c) + t + c with c = (1,1,1), t = (1,2,3): (2,1,1) -> A (1,0,0) = (0,1,0) -> (2,4,4);
  // (1,1,0) -> A (0,0,-1) = (0,0,-2) -> (2,3,2).
  const auto out = fieldOf(*s, "t", "output_position");
  const std::vector<double> expected{2, 4, 4, 2, 3, 2};
  ASSERT_EQ(out.size(), expected.size());
  for (size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(out[i], expected[i], 1e-12) << i;

  std::ofstream(dir / "bad.tfm") << "Parameters: 1 0 0 0 1 0 0 0 1 0 x 0\n";
  EXPECT_NE(test_support::errorOf([&] {
              build(R"(<TransformPosition filename="bad.tfm" input_position="0 0 0"/>)", dir / "scene.xml");
            }).find("bad.tfm:1:"),
            std::string::npos);
}

TEST(GeometryEngines, EdgeSetsCarrySpringsAndPointSetsGivePositions) {
  auto s = build(R"(<EdgeSetTopologyContainer name="edges" position="0 0 0  1 0 0  2 0 0  3 0 0" edges="0 1  1 2  2 3  0 2"/>
                    <MechanicalObject name="dofs"/>
                    <MeshSpringForceField linesStiffness="10"/>)");
  std::vector<std::pair<int, int>> pairs;
  for (ForceField* f : s->all<ForceField>()) f->stiffnessPattern(pairs);
  EXPECT_EQ(pairs.size(), 4u);
  EXPECT_NE(test_support::errorOf([] {
              build(R"(<EdgeSetTopologyContainer position="0 0 0  1 0 0" edges="0 2"/>)");
            }).find("EdgeSetTopologyContainer.edges: refer to node 2, but there are 2 points"),
            std::string::npos);
  auto points = build(R"(<PointSetTopologyContainer position="0 0 0  1 2 3"/><MechanicalObject name="dofs"/>)");
  EXPECT_EQ(fieldOf(*points, "dofs", "position"), (std::vector<double>{0, 0, 0, 1, 2, 3}));
}

// SOFA's round grids: every node of the cylinder lies within its radius of the axis and between
// its end discs, the outer ring of nodes on the radius; every node of the sphere grid within the
// radius, the cube's surface nodes on it.
TEST(GeometryEngines, CylinderAndSphereGridsLieOnTheirShapes) {
  auto s = build(R"(<Node name="c"><CylinderGridTopology name="cyl" n="5 5 4" radius="2" length="3" axis="0 1 0" center="1 0 0"/></Node>
                    <Node name="s"><SphereGridTopology name="ball" n="5 5 5" radius="2"/></Node>)");
  const auto c = fieldOf(*s, "cyl", "position");
  ASSERT_EQ(c.size(), 3u * 100);
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 5; ++i) {
        const size_t p = 3 * static_cast<size_t>(i + 5 * (j + 5 * k));
        const double radial = std::hypot(c[p] - 1, c[p + 2]);
        EXPECT_LE(radial, 2 + 1e-12);
        if (i == 0 || j == 0 || i == 4 || j == 4) EXPECT_NEAR(radial, 2, 1e-12) << i << " " << j << " " << k;
        EXPECT_NEAR(c[p + 1], k * 1.0, 1e-12);  // along the axis, length 3 over 3 cells
      }
  const auto b = fieldOf(*s, "ball", "position");
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 5; ++i) {
        const size_t p = 3 * static_cast<size_t>(i + 5 * (j + 5 * k));
        const double r = std::sqrt(b[p] * b[p] + b[p + 1] * b[p + 1] + b[p + 2] * b[p + 2]);
        EXPECT_LE(r, 2 + 1e-12);
        if (i == 0 || j == 0 || k == 0 || i == 4 || j == 4 || k == 4) EXPECT_NEAR(r, 2, 1e-12);
      }
}

namespace {

// An OBJ of axis-aligned boxes (outward triangles), each given by its two corners.
void writeBoxes(const std::string& path, const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& boxes) {
  std::ofstream out(path);
  int base = 1;
  for (const auto& [lo, hi] : boxes) {
    for (int k = 0; k < 8; ++k)
      out << "v " << (k & 1 ? hi.x() : lo.x()) << " " << (k & 2 ? hi.y() : lo.y()) << " " << (k & 4 ? hi.z() : lo.z()) << "\n";
    static const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    for (const auto& t : f) out << "f " << base + t[0] << " " << base + t[1] << " " << base + t[2] << "\n";
    base += 8;
  }
}

}  // namespace

// Two prongs in one cell of the coarse grid: the plain sparse grid glues them into one hexahedron;
// SOFA's ramification keeps one hexahedron per prong, sharing no node. A single block is the same
// either way.
TEST(GeometryEngines, RamificationKeepsSeparatePartsApart) {
  test_support::TempDir dir;
  writeBoxes(dir / "fork.obj", {{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.2, 1, 1)},
                                {Eigen::Vector3d(0.8, 0, 0), Eigen::Vector3d(1, 1, 1)}});
  writeBoxes(dir / "block.obj", {{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 2, 1)}});
  auto s = build(R"(<Node name="a"><SparseGridTopology name="plain" n="2 2 2" fileTopology="fork.obj"/></Node>
                    <Node name="b"><SparseGridRamificationTopology name="fork" n="2 2 2" fileTopology="fork.obj" nbVirtualFinerLevels="2"/></Node>
                    <Node name="c"><SparseGridTopology name="blockPlain" n="3 5 3" fileTopology="block.obj"/></Node>
                    <Node name="d"><SparseGridRamificationTopology name="block" n="3 5 3" fileTopology="block.obj" nbVirtualFinerLevels="2"/></Node>)",
                 dir / "scene.xml");
  EXPECT_EQ(fieldOf(*s, "plain", "hexahedra").size(), 8u);
  const auto fork = fieldOf(*s, "fork", "hexahedra");
  ASSERT_EQ(fork.size(), 16u);
  std::set<double> nodes(fork.begin(), fork.end());
  EXPECT_EQ(nodes.size(), 16u);
  EXPECT_EQ(fieldOf(*s, "fork", "position").size(), 3u * 16);
  EXPECT_EQ(fieldOf(*s, "block", "hexahedra").size(), fieldOf(*s, "blockPlain", "hexahedra").size());
  EXPECT_EQ(fieldOf(*s, "block", "position").size(), fieldOf(*s, "blockPlain", "position").size());

  // Points mapped onto the fork follow the prong they lie in: each hangs on the 8 nodes of its
  // own part's hexahedron.
  auto mapped = build(R"(<Node name="body"><SparseGridRamificationTopology name="fork" n="2 2 2" fileTopology="fork.obj" nbVirtualFinerLevels="2"/>
      <MechanicalObject/>
      <Node name="points"><MechanicalObject position="0.1 0.5 0.5  0.9 0.5 0.5"/><BarycentricMapping/></Node></Node>)",
                      dir / "scene.xml");
  const auto hexa = fieldOf(*mapped, "fork", "hexahedra");
  const Mapping& map = *mapped->all<Mapping>().front();
  for (int p = 0; p < 2; ++p) {
    std::vector<std::pair<int, double>> w;
    ASSERT_TRUE(map.pointWeights(p, w));
    std::set<int> used;
    for (const auto& [node, weight] : w) used.insert(node);
    const std::set<int> part(hexa.begin() + 8 * p, hexa.begin() + 8 * (p + 1));  // part p is hexahedron p
    EXPECT_EQ(used, part) << "point " << p;
  }
}
