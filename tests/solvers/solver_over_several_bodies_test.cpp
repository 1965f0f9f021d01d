// SOFA's solver over several bodies: an EulerImplicitSolver in a node with no body of its own
// integrates the deformable bodies below it (each with a mass in its node) as one system. Two
// bodies that do not touch are two independent systems, so with the linear solve converged the
// joint step moves each exactly as its own solver would (the check: a run where each body has its
// solver in its node, to round-off). A body with a solver of its own keeps it; a direct linear
// solver factorises the joint matrix, and a solver built around one body's matrix is refused.
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

const char* kSolver = R"(<EulerImplicitSolver rayleighMass="0.1" rayleighStiffness="0.1"/>
    <CGLinearSolver iterations="400" tolerance="1e-15" threshold="1e-30"/>)";

// A bar of tetrahedra fixed at one end, sagging under gravity, with `solver` in its node.
std::string bar(const std::string& name, double y, double young, const std::string& solver) {
  return R"(<Node name=")" + name + R"(">
    )" + solver + R"(
    <RegularGridTopology name="grid" n="5 2 2" min="0 )" + std::to_string(y) + R"( 0" max="4 )" + std::to_string(y + 1) + R"( 1"/>
    <TetrahedronSetTopologyContainer name="tets"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tets"/>
    <MechanicalObject name=")" + name + R"(_dofs"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField method="large" youngModulus=")" + std::to_string(young) + R"(" poissonRatio="0.3"/>
    <BoxROI name="end" box="-0.1 -10 -10 0.1 10 10"/>
    <FixedConstraint indices="@end.indices"/>
  </Node>)";
}

// Two bars, both integrated by `top` in the root when it is set, else each by its own solver.
std::string scene(const std::string& top, const std::string& linear = "") {
  const std::string own = top.empty() ? kSolver : "";
  std::string s = R"(<Node name="root" dt="0.01" gravity="0 0 -10">
  )" + top + linear + bar("soft", 0, 2e3, own) + bar("stiff", 3, 2e4, own) + "\n</Node>";
  return s;
}

std::map<std::string, Eigen::Matrix3Xd> run(const std::string& text, int steps) {
  auto sc = buildScene(io::parseSceneText(text, "bodies.xml"));
  Simulation sim(*sc);
  for (int i = 0; i < steps; ++i) {
    auto bad = sim.step();
    EXPECT_FALSE(bad) << (bad ? bad->str() : "");
  }
  std::map<std::string, Eigen::Matrix3Xd> out;
  for (const MechanicalObject* m : sc->all<MechanicalObject>()) out[m->name()] = m->x(sim.state());
  return out;
}

}  // namespace

TEST(SolverOverSeveralBodies, MovesEachAsItsOwnSolverWould) {
  const auto own = run(scene(""), 50);
  const auto joint = run(scene(kSolver), 50);
  ASSERT_EQ(own.size(), 2u);
  ASSERT_EQ(joint.size(), 2u);
  for (const auto& [name, x] : own) {
    const Eigen::Matrix3Xd& y = joint.at(name);
    // The bars sag (the tip of the soft one by ~0.1): the comparison is not of two rest states.
    EXPECT_GT((x - run(scene(""), 0).at(name)).cwiseAbs().maxCoeff(), 1e-3) << name;
    // Converged solves of the same two systems: equal but for the solves' round-off.
    EXPECT_LE((x - y).cwiseAbs().maxCoeff(), 1e-9) << name;
  }
}

TEST(SolverOverSeveralBodies, ABodyWithItsOwnSolverKeepsIt) {
  // The stiff bar carries its own solver: the root's integrates the soft one only, and the result
  // is the same again.
  std::string text = scene(kSolver);
  const std::string stiffNode = R"(<Node name="stiff">)";
  text.replace(text.find(stiffNode), stiffNode.size(), stiffNode + kSolver);
  const auto mixed = run(text, 50);
  const auto own = run(scene(""), 50);
  for (const auto& [name, x] : own) EXPECT_LE((x - mixed.at(name)).cwiseAbs().maxCoeff(), 1e-9) << name;
}

// A direct solver factorises the joint matrix (the bodies' matrices side by side): the same
// motion again, to round-off. A solver built around one body's matrix (a preconditioner made from
// it, a factorisation kept from the first step) is refused over several.
TEST(SolverOverSeveralBodies, ADirectSolverFactorisesTheJointMatrix) {
  const auto own = run(scene(""), 50);
  const auto direct = run(scene(R"(<EulerImplicitSolver rayleighMass="0.1" rayleighStiffness="0.1"/><SparseLDLSolver/>)"), 50);
  for (const auto& [name, x] : own) EXPECT_LE((x - direct.at(name)).cwiseAbs().maxCoeff(), 1e-9) << name;
  const std::string top = R"(<EulerImplicitSolver/><PrecomputedLinearSolver/>)";
  try {
    auto sc = buildScene(io::parseSceneText(scene(top), "bodies.xml"));
    sc->init();
    FAIL() << "a precomputed solver over two bodies was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("2 deformable bodies"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("PrecomputedLinearSolver"), std::string::npos) << e.what();
  }
}
