// SOFA's plasticity in TetrahedronFEMForceField, at the scene level: a step's plastic strains
// follow SOFA's rule from the positions the step started at, once per step, also when the contact
// correction linearises the body again (LinearSolverConstraintCorrection); a static solver keeps
// SOFA's tangent; a state without plastic strains does not go into a model with them.
#include <gtest/gtest.h>

#include <string>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/fem/TetKernel.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

// A block of tetrahedra falling onto a fixed sphere, its contacts corrected by `correction`.
std::string fallingBlock(const std::string& plasticity, const std::string& correction) {
  return R"(<Node name="root" dt="0.01" gravity="0 0 -10">
    <FreeMotionAnimationLoop/>
    <GenericConstraintSolver maxIterations="200" tolerance="1e-10"/>
    <CollisionPipeline/><BruteForceBroadPhase/><BVHNarrowPhase/>
    <LocalMinDistance alarmDistance="0.2" contactDistance="0.05"/>
    <CollisionResponse response="FrictionContactConstraint" responseParams="mu=0"/>
    <Node name="obstacle">
      <MechanicalObject template="Rigid3d" position="0.5 0.5 -0.45 0 0 0 1"/>
      <SphereCollisionModel radius="0.4"/>
    </Node>
    <Node name="block">
      <EulerImplicitSolver rayleighStiffness="0.1" rayleighMass="0.1"/>
      <SparseLDLSolver/>
      <RegularGridTopology name="grid" n="3 3 3" min="0 0 0" max="1 1 1"/>
      <MechanicalObject name="dofs"/>
      <TetrahedronSetTopologyContainer name="tets"/>
      <Hexa2TetraTopologicalMapping input="@grid" output="@tets"/>
      <UniformMass totalMass="1"/>
      <TetrahedronFEMForceField name="fem" method="large" youngModulus="2000" poissonRatio="0.3" )" + plasticity + R"(/>
      <TriangleCollisionModel/>
      )" + correction + R"(
    </Node>
  </Node>)";
}

template <class T>
T& one(Scene& s) {
  auto all = s.all<T>();
  if (all.size() != 1) throw std::runtime_error("expected one component");
  return *all.front();
}

}  // namespace

// Each step's plastic strains are SOFA's update from the strains at the step's start positions:
// P' = P + c (e - P) where |6 V (e - P)| exceeds the yield threshold, then capped. With the
// contact correction linearising the body a second time in the step, a second update would move
// P' by c again (c = 0.3 here: 30 % of the elastic strain). Checked element by element over the
// steps in contact, to 1e-12 of the strains.
TEST(Plasticity, StrainsCreepOncePerStepAlsoUnderContactCorrection) {
  for (const std::string correction : {"<LinearSolverConstraintCorrection/>", "<PrecomputedConstraintCorrection/>"}) {
    auto scene = buildScene(io::parseSceneText(
        fallingBlock(R"(plasticMaxThreshold="1" plasticYieldThreshold="1e-6" plasticCreep="0.3")", correction), "plastic.xml"));
    Simulation sim(*scene);
    auto& fem = one<TetrahedronFEMForceField>(*scene);
    MechanicalObject* dofs = nullptr;
    for (MechanicalObject* m : scene->all<MechanicalObject>())
      if (m->name() == "dofs") dofs = m;
    ASSERT_TRUE(dofs);
    const fem::Plasticity law = fem.plasticity();
    ASSERT_TRUE(law.on());
    int checked = 0;
    double largest = 0;
    for (int step = 0; step < 60; ++step) {
      const State before = sim.captureState();
      ASSERT_FALSE(sim.step()) << correction;
      const auto& P0 = fem.plasticStrains(before);
      const auto& P1 = fem.plasticStrains(sim.state());
      const Eigen::Matrix3Xd& x = dofs->x(before);
      for (int e = 0; e < fem.tetrahedra().cols(); ++e) {
        fem::Mat34 xe;
        for (int k = 0; k < 4; ++k) xe.col(k) = x.col(fem.tetrahedra()(k, e));
        const Eigen::Matrix3d R = fem::frameLarge(xe);
        const fem::ElementRest rest = fem::restElement(fem::Method::Large, [&] {
          fem::Mat34 X;
          for (int k = 0; k < 4; ++k) X.col(k) = dofs->x0.col(fem.tetrahedra()(k, e));
          return X;
        }(), fem::Lame::fromYoungPoisson(2000, 0.3));
        fem::Voigt expected = P0.col(e);
        fem::plasticForce(rest, fem::localPositions(fem::Method::Large, R, xe) - rest.X, law, expected);
        EXPECT_LT((P1.col(e) - expected).norm(), 1e-12 + 1e-9 * expected.norm()) << correction << " step " << step << " element " << e;
        largest = std::max(largest, P1.col(e).norm());
        ++checked;
      }
    }
    EXPECT_GT(largest, 1e-3) << correction;  // it deformed plastically
    EXPECT_GT(checked, 0);
  }
}

// Newton's exact tangent is that of the elastic force: with plasticity a static solver keeps
// SOFA's R^T K0 R; without, it takes the exact one.
TEST(Plasticity, AStaticSolverKeepsSofasTangent) {
  for (const bool plastic : {true, false}) {
    const std::string text = R"(<Node name="root" gravity="0 0 -10"><StaticSolver/><SparseLDLSolver/>
      <RegularGridTopology name="grid" n="3 2 2" min="0 0 0" max="2 1 1"/><MechanicalObject/>
      <TetrahedronSetTopologyContainer name="tets"/><Hexa2TetraTopologicalMapping input="@grid" output="@tets"/>
      <UniformMass totalMass="1"/><FixedConstraint indices="0 3 6 9"/>
      <TetrahedronFEMForceField method="large" youngModulus="2000" poissonRatio="0.3" )" +
                             std::string(plastic ? R"(plasticMaxThreshold="1")" : "") + "/></Node>";
    auto scene = buildScene(io::parseSceneText(text, "static.xml"));
    Simulation sim(*scene);
    EXPECT_EQ(one<TetrahedronFEMForceField>(*scene).exactTangent(), !plastic);
  }
}

// A state of the elastic model does not go into the plastic one: its FEM block has no plastic
// strains (the error names them, and nothing changes).
TEST(Plasticity, AStateWithoutPlasticStrainsIsRefused) {
  auto elastic = buildScene(io::parseSceneText(fallingBlock("", "<LinearSolverConstraintCorrection/>"), "a.xml"));
  auto plastic = buildScene(io::parseSceneText(fallingBlock(R"(plasticMaxThreshold="1")", "<LinearSolverConstraintCorrection/>"), "b.xml"));
  Simulation a(*elastic), b(*plastic);
  const State s = a.captureState();
  const State before = b.captureState();
  try {
    b.restoreState(s);
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("plastic strains"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(b.captureState() == before);
}
