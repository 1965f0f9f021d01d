// SphereROI and IndexValueMapper giving part of a block its own Young's modulus, as SOFA scenes
// write heterogeneous tissue: the selection is checked against the rule computed here from the
// mesh (a tetrahedron whose four vertices lie in the sphere), and the linked modulus must give the
// same motion as the same per-element list written out by hand.
#include <gtest/gtest.h>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "engine/Simulation.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

namespace {

using namespace viscera;

std::string block(const std::string& engines, const std::string& young) {
  return R"(<Node name="root" dt="0.01" gravity="0 0 -9.81">
  <Node name="block">
    <EulerImplicitSolver rayleighStiffness="0.1" rayleighMass="1"/>
    <CGLinearSolver iterations="200" tolerance="1e-14" threshold="1e-30"/>
    <RegularGridTopology name="grid" n="5 4 4" min="0 0 0" max="4 3 3"/>
    <MechanicalObject name="dofs"/>
    <TetrahedronSetTopologyContainer name="tetra"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tetra" swapping="true"/>
    <UniformMass totalMass="1"/>
    )" + engines + R"(
    <TetrahedronFEMForceField name="fem" youngModulus=")" + young + R"(" poissonRatio="0.3"/>
    <BoxROI name="bottom" box="-1 -1 -1 5 4 0.1"/>
    <FixedConstraint indices="@bottom.indices"/>
  </Node>
</Node>)";
}

const char* kEngines = R"(<SphereROI name="roi" centers="2 1.5 2" radii="1.3"/>
    <IndexValueMapper name="soft" indices="@roi.tetrahedronIndices" value="1000" inputValues="@all.outputValues"/>)";

// Every element at 5000 first: a mapper with no indices but one per element from an input list.
std::string allElements(int n) {
  std::string v;
  for (int e = 0; e < n; ++e) v += (e ? " " : "") + std::string("5000");
  return R"(<IndexValueMapper name="all" inputValues=")" + v + R"("/>
    )";
}

TEST(RegionEngines, SphereSelectsTheTetrahedraWithEveryVertexInside) {
  // The element list and rest positions of the plain block.
  auto plain = buildScene(io::parseSceneText(block("", "5000"), "plain.xml"));
  plain->init();
  const TetrahedronFEMForceField& fem = *plain->all<TetrahedronFEMForceField>().front();
  const Eigen::Matrix3Xd& X = fem.mstate().x0;
  const TetList& tets = fem.tetrahedra();
  std::vector<double> expected;
  const Eigen::Vector3d c(2, 1.5, 2);
  int inside = 0;
  for (Eigen::Index e = 0; e < tets.cols(); ++e) {
    bool all = true;
    for (int k = 0; k < 4; ++k) all = all && (X.col(tets(k, e)) - c).norm() <= 1.3;
    expected.push_back(all ? 1000 : 5000);
    inside += all;
  }
  ASSERT_GT(inside, 0);
  ASSERT_LT(inside, tets.cols());

  std::string list;
  for (double v : expected) list += (list.empty() ? "" : " ") + std::to_string(static_cast<int>(v));
  auto byHand = buildScene(io::parseSceneText(block("", list), "hand.xml"));
  auto linked = buildScene(io::parseSceneText(block(allElements(static_cast<int>(tets.cols())) + kEngines, "@soft.outputValues"), "linked.xml"));
  Simulation a(*byHand), b(*linked);
  for (int i = 0; i < 50; ++i) {
    ASSERT_FALSE(a.step());
    ASSERT_FALSE(b.step());
  }
  const Eigen::Matrix3Xd& xa = byHand->all<MechanicalObject>().front()->x(a.state());
  const Eigen::Matrix3Xd& xb = linked->all<MechanicalObject>().front()->x(b.state());
  EXPECT_EQ((xa - xb).cwiseAbs().maxCoeff(), 0.0);
  // And the softer region does move the block: against the plain one, the top sags more.
  Simulation p(*plain);
  for (int i = 0; i < 50; ++i) ASSERT_FALSE(p.step());
  const Eigen::Matrix3Xd& xp = plain->all<MechanicalObject>().front()->x(p.state());
  EXPECT_LT(xb.row(2).minCoeff(), xp.row(2).minCoeff() + 1e-9);
  EXPECT_GT((xb - xp).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(RegionEngines, NodesInsideAndClearErrors) {
  // A mapper without inputValues grows to the largest index with defaultValue: too short for the
  // block's elements, which the force field says.
  const std::string short_ = R"(<SphereROI name="roi" centers="2 1.5 2" radii="1.3"/>
    <IndexValueMapper name="soft" indices="@roi.tetrahedronIndices" value="1000" defaultValue="5000"/>)";
  try {
    auto s = buildScene(io::parseSceneText(block(short_, "@soft.outputValues"), "short.xml"));
    s->init();
    FAIL() << "a per-element list shorter than the elements was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("youngModulus"), std::string::npos) << e.what();
  }
  const std::string radii = R"(<SphereROI name="roi" centers="0 0 0  1 1 1" radii="1 2 3"/>)";
  try {
    auto s = buildScene(io::parseSceneText(block(radii, "5000"), "radii.xml"));
    s->init();
    FAIL() << "three radii for two centres were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("radii"), std::string::npos) << e.what();
  }
}

}  // namespace
