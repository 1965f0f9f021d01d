// Bilateral constraints (SOFA's BilateralLagrangianConstraint) against closed forms: a rigid body
// hung from a fixed point by a point mapped from it swings as the compound pendulum; a particle held
// at an offset from an anchor stays there under gravity; two free particles joined by the
// constraint share their momentum in one step.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

std::unique_ptr<Scene> load(const std::string& text) { return buildScene(io::parseSceneText(text, "bilateral.xml")); }

// The MechanicalObject in the node named `node`.
const MechanicalObject& stateIn(const Scene& s, const std::string& node) {
  for (MechanicalObject* m : s.all<MechanicalObject>())
    if (m->node().name() == node) return *m;
  throw std::runtime_error("no MechanicalObject in a node named " + node);
}

// A free particle of mass m at p with velocity v, solved in its own node.
std::string particle(const std::string& name, double m, const std::string& p, const std::string& v = "0 0 0") {
  return R"(
  <Node name=")" + name + R"(">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10" tolerance="1e-12" threshold="1e-20"/>
    <MechanicalObject name="dofs" position=")" + p + R"(" velocity=")" + v + R"("/>
    <UniformMass name="mass" totalMass=")" + std::to_string(m) + R"("/>
    <UncoupledConstraintCorrection/>
  </Node>)";
}

const char* kLoop = R"(
  <FreeMotionAnimationLoop/>
  <GenericConstraintSolver tolerance="1e-12" maxIterations="100"/>)";

}  // namespace

// A rigid body of mass 1 and inertia 1 (SOFA's default: the mass times the identity) hangs by the
// point 1 from its centre from an anchor that nothing moves. Started 0.05 rad from the vertical,
// it swings with the compound pendulum's period 2 pi sqrt((I + m d^2) / (m g d)) = 2.810 s
// (d = 1, g = 10); implicit Euler at h = 1 ms changes the period by O((h omega)^2), far below the
// 0.3 % allowed for reading it from zero crossings. The held point stays on the anchor (the
// rotation over a step is applied exactly, the constraint linearised: 1e-6 allowed).
TEST(BilateralConstraint, ARigidBodyHungByAPointSwingsAsTheCompoundPendulum) {
  const double theta0 = 0.05, d = 1.0, g = 10.0;
  const double cx = d * std::sin(theta0), cz = -d * std::cos(theta0);
  const std::string text = R"(<Node name="root" dt="0.001" gravity="0 0 -10">)" + std::string(kLoop) + R"(
  <Node name="anchor">
    <MechanicalObject name="point" position="0 0 0"/>
  </Node>
  <Node name="body">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject template="Rigid3d" position=")" + std::to_string(cx) + " 0 " + std::to_string(cz) + R"( 0 0 0 1"/>
    <UniformMass totalMass="1"/>
    <UncoupledConstraintCorrection/>
    <Node name="hook">
      <MechanicalObject name="point" position=")" + std::to_string(-cx) + " 0 " + std::to_string(-cz) + R"("/>
      <RigidMapping/>
    </Node>
  </Node>
  <BilateralLagrangianConstraint object1="@anchor/point" object2="@body/hook/point" first_point="0" second_point="0"/>
</Node>)";
  auto scene = load(text);
  Simulation sim(*scene);
  const RigidObject& body = *scene->all<RigidObject>().front();
  const MechanicalObject* hook = &stateIn(*scene, "hook");
  std::vector<double> crossings;
  double last = cx, worstHold = 0, worstArm = 0;
  for (int i = 1; i <= 7000; ++i) {
    ASSERT_FALSE(sim.step()) << "step " << i;
    const Eigen::Vector3d c = body.live(sim.state()).p;
    worstHold = std::max(worstHold, hook->x(sim.state()).col(0).norm());
    worstArm = std::max(worstArm, std::abs(c.norm() - d));
    if ((last > 0) != (c.x() > 0)) crossings.push_back(1e-3 * (i - 1 + last / (last - c.x())));
    last = c.x();
  }
  const double period = 2 * M_PI * std::sqrt((1.0 + 1.0 * d * d) / (1.0 * g * d));
  ASSERT_GE(crossings.size(), 4u);
  // Zero crossings come every half period.
  EXPECT_NEAR((crossings.back() - crossings.front()) / (crossings.size() - 1), period / 2, 0.003 * period / 2);
  EXPECT_LT(worstHold, 1e-6);
  EXPECT_LT(worstArm, 1e-6);
}

// Point 2 - point 1 = rest_vector: a particle held 1 below an anchor stays there under gravity,
// at rest (the constraint takes its weight each step).
TEST(BilateralConstraint, AParticleHeldAtAnOffsetStaysThere) {
  const std::string text = R"(<Node name="root" dt="0.01" gravity="0 0 -10">)" + std::string(kLoop) + R"(
  <Node name="anchor">
    <MechanicalObject name="dofs" position="0.3 0.2 2"/>
  </Node>)" + particle("bob", 2.0, "0.3 0.2 1") + R"(
  <BilateralLagrangianConstraint object1="@anchor/dofs" object2="@bob/dofs" rest_vector="0 0 -1"/>
</Node>)";
  auto scene = load(text);
  Simulation sim(*scene);
  const MechanicalObject* bob = &stateIn(*scene, "bob");
  for (int i = 0; i < 100; ++i) ASSERT_FALSE(sim.step()) << "step " << i;
  EXPECT_LT((bob->x(sim.state()).col(0) - Eigen::Vector3d(0.3, 0.2, 1)).norm(), 1e-12);
  EXPECT_LT(bob->v(sim.state()).col(0).norm(), 1e-10);
}

// Two free particles joined where they are (no gravity), the first (mass 1) moving at 1 m/s: after
// one step both move at the common velocity 1 / (1 + 3) (momentum conserved, the constraint
// holding their offset), and keep it. The objects are linked by their nodes, as SOFA allows.
TEST(BilateralConstraint, TwoFreeParticlesShareTheirMomentum) {
  const std::string text = R"(<Node name="root" dt="0.01" gravity="0 0 0">)" + std::string(kLoop) +
                           particle("a", 1.0, "0 0 0", "1 0 0") + particle("b", 3.0, "0.5 0.5 0") + R"(
  <BilateralLagrangianConstraint object1="@a" object2="@b" rest_vector="0.5 0.5 0"/>
</Node>)";
  auto scene = load(text);
  Simulation sim(*scene);
  const MechanicalObject *a = &stateIn(*scene, "a"), *b = &stateIn(*scene, "b");
  for (int i = 0; i < 10; ++i) {
    ASSERT_FALSE(sim.step());
    EXPECT_NEAR(a->v(sim.state())(0, 0), 0.25, 1e-12);
    EXPECT_NEAR(b->v(sim.state())(0, 0), 0.25, 1e-12);
    EXPECT_LT((b->x(sim.state()).col(0) - a->x(sim.state()).col(0) - Eigen::Vector3d(0.5, 0.5, 0)).norm(), 1e-12);
  }
}

TEST(BilateralConstraint, BadLinksAndCountsAreErrorsNamingTheAttribute) {
  auto expectError = [](const std::string& constraint, const std::string& what) {
    const std::string text = R"(<Node name="root" dt="0.01" gravity="0 0 -10">)" + std::string(kLoop) +
                             particle("a", 1.0, "0 0 0  1 0 0") + particle("b", 1.0, "0 0 1") + constraint + "</Node>";
    try {
      auto scene = load(text);
      Simulation sim(*scene);
      ADD_FAILURE() << "no error for " << constraint;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  expectError(R"(<BilateralLagrangianConstraint object1="@a/dofs" object2="@b/dofs"/>)", "first_point");
  expectError(R"(<BilateralLagrangianConstraint object1="@a/dofs" object2="@b/dofs" first_point="0 1" second_point="0"/>)",
              "second_point");
  expectError(R"(<BilateralLagrangianConstraint object1="@a/dofs" object2="@b/dofs" first_point="2" second_point="0"/>)",
              "first_point");
  expectError(R"(<BilateralLagrangianConstraint object1="@a/dofs" object2="@b/dofs" first_point="0" second_point="0" rest_vector="1 0"/>)",
              "rest_vector");
  expectError(R"(<BilateralLagrangianConstraint object1="@a/mass" object2="@b/dofs" first_point="0" second_point="0"/>)", "object1");
}

// Without a constraint solver nothing would hold the points: an error, not a silent no-op.
TEST(BilateralConstraint, NeedsAConstraintSolver) {
  const std::string text = R"(<Node name="root" dt="0.01" gravity="0 0 -10">)" + particle("a", 1.0, "0 0 0") +
                           particle("b", 1.0, "0 0 1") + R"(
  <BilateralLagrangianConstraint object1="@a/dofs" object2="@b/dofs"/>
</Node>)";
  try {
    auto scene = load(text);
    Simulation sim(*scene);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("constraint solver"), std::string::npos) << e.what();
  }
}

// A particle held on two anchors 2 apart (no gravity, at rest 0.6 off their midpoint) cannot meet
// both: without regularisation the problem has no solution. With the solver's regularizationTerm
// eps added to W = c [I I; I I] (c = h^2 / m, the particle's compliance) the step ends at
// mid + (p0 - mid) eps / (2 c + eps); with useSVDForRegularization only W's zero eigenvalues are
// raised, and the particle lands on the midpoint.
TEST(BilateralConstraint, RegularisationSettlesConflictingConstraints) {
  auto run = [](const std::string& solverAttrs) {
    const std::string text = R"(<Node name="root" dt="0.01" gravity="0 0 0">
  <FreeMotionAnimationLoop/>
  <GenericConstraintSolver tolerance="1e-14" maxIterations="10000" )" + solverAttrs + R"(/>
  <Node name="anchors">
    <MechanicalObject name="dofs" position="-1 0 0  1 0 0"/>
  </Node>)" + particle("p", 1.0, "0.6 0 0") + R"(
  <BilateralLagrangianConstraint object1="@anchors/dofs" object2="@p/dofs" first_point="0 1" second_point="0 0"/>
</Node>)";
    auto scene = load(text);
    Simulation sim(*scene);
    EXPECT_FALSE(sim.step());
    return Eigen::Vector3d(stateIn(*scene, "p").x(sim.state()).col(0));
  };
  const double c = 0.01 * 0.01 / 1.0, eps = 1e-4;
  const Eigen::Vector3d added = run(R"(regularizationTerm="1e-4")");
  EXPECT_NEAR(added.x(), 0.6 * eps / (2 * c + eps), 1e-9);
  EXPECT_NEAR(added.tail<2>().norm(), 0, 1e-12);
  const Eigen::Vector3d svd = run(R"(regularizationTerm="1e-4" useSVDForRegularization="true")");
  EXPECT_NEAR(svd.norm(), 0, 1e-9);
}

// A hexahedral beam held at one end by bilateral constraints to anchors where its end nodes are,
// its compliance the step's own (LinearSolverConstraintCorrection, direct solver), moves exactly
// as the same beam whose end nodes are fixed (FixedConstraint): the Lagrange multipliers solve the
// same constrained implicit step, and the held nodes end each step where they started, at rest.
// Round-off is all that may differ (1e-9 of the beam's 0.1 sag allowed).
TEST(BilateralConstraint, HoldingABeamEndIsTheFixedConstraint) {
  auto beam = [](const std::string& hold) {
    return R"(<Node name="root" dt="0.01" gravity="0 0 -10">
  <FreeMotionAnimationLoop/>
  <GenericConstraintSolver tolerance="1e-14" maxIterations="1000"/>
  <Node name="beam">
    <EulerImplicitSolver rayleighStiffness="0.1" rayleighMass="0.1"/>
    <SparseLDLSolver/>
    <RegularGridTopology n="6 2 2" min="0 0 0" max="5 1 1"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="10"/>
    <HexahedronFEMForceField youngModulus="20000" poissonRatio="0.3" method="large"/>
    <BoxROI name="end" box="-0.1 -0.1 -0.1  0.1 1.1 1.1"/>
    <LinearSolverConstraintCorrection/>)" +
           hold + "</Node>";
  };
  auto fixed = load(beam(R"(<FixedConstraint indices="@end.indices"/>
  </Node>)"));
  auto held = load(beam(R"(</Node>
  <Node name="anchors">
    <MechanicalObject name="dofs" position="@beam/end.pointsInROI"/>
  </Node>
  <BilateralLagrangianConstraint object1="@anchors/dofs" object2="@beam/dofs" first_point="0 1 2 3" second_point="@beam/end.indices"/>)"));
  Simulation a(*fixed), b(*held);
  const MechanicalObject &xa = stateIn(*fixed, "beam"), &xb = stateIn(*held, "beam");
  double sag = 0, worst = 0;
  for (int i = 0; i < 50; ++i) {
    ASSERT_FALSE(a.step());
    ASSERT_FALSE(b.step());
    sag = std::max(sag, (xa.x(a.state()) - xa.x0).colwise().norm().maxCoeff());
    worst = std::max(worst, (xa.x(a.state()) - xb.x(b.state())).colwise().norm().maxCoeff());
  }
  EXPECT_GT(sag, 0.05);
  EXPECT_LT(worst, 1e-9 * sag / 0.1);
}

// Point lists given but empty (a region that selects nothing) hold nothing: they are not the
// "every point" default of lists left out.
TEST(BilateralConstraint, EmptyGivenListsHoldNothing) {
  const std::string text = R"(<Node name="root" dt="0.01" gravity="0 0 -10">)" + std::string(kLoop) + R"(
  <Node name="anchor">
    <MechanicalObject name="dofs" position="0 0 1"/>
    <BoxROI name="none" box="5 5 5 6 6 6"/>
  </Node>)" + particle("bob", 1.0, "0 0 0") + R"(
  <BilateralLagrangianConstraint object1="@anchor/dofs" object2="@bob/dofs" first_point="@anchor/none.indices" second_point="@anchor/none.indices"/>
</Node>)";
  auto scene = load(text);
  Simulation sim(*scene);
  for (int i = 0; i < 10; ++i) ASSERT_FALSE(sim.step());
  EXPECT_LT(stateIn(*scene, "bob").x(sim.state())(2, 0), -0.05);  // it fell
}
