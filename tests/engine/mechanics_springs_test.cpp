// MeshSpringForceField: the springs each element kind makes, forces as the gradient of the energy
// and the stiffness as the derivative of the force (finite differences); the surfaces SOFA scenes
// give their volumes (Tetra2TriangleTopologicalMapping, the boundary of a grid's hexahedra).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <string>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Roles.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/topology/GridSplit.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

std::unique_ptr<Scene> build(const std::string& body) {
  auto scene = buildScene(io::parseSceneText("<Node name=\"root\" gravity=\"0 0 0\">" + body + "</Node>", "springs.xml"));
  scene->init();
  return scene;
}

ForceField& springs(Scene& s) {
  for (auto* f : s.all<ForceField>())
    if (dynamic_cast<Component*>(f)->typeName() == "MeshSpringForceField") return *f;
  throw std::runtime_error("no springs");
}

size_t springCount(const std::string& attrs) {
  auto scene = build(R"(<RegularGridTopology name="grid" n="2 2 2"/><MechanicalObject/>
                        <MeshSpringForceField )" + attrs + "/>");
  std::vector<std::pair<int, int>> pairs;
  springs(*scene).stiffnessPattern(pairs);
  return pairs.size();
}

}  // namespace

TEST(MeshSprings, EachKindOfElementGivesItsPairs) {
  EXPECT_EQ(springCount(R"(stiffness="10")"), 28u);       // every pair of a hexahedron's 8 nodes
  EXPECT_EQ(springCount(R"(linesStiffness="10")"), 12u);  // its edges
  EXPECT_EQ(springCount(R"(quadsStiffness="10")"), 24u);  // edges and face diagonals
  EXPECT_EQ(springCount(R"(cubesStiffness="10")"), 28u);
  auto tets = build(R"(<MechanicalObject position="0 0 0 1 0 0 0 1 0 0 0 1"/>
                       <TetrahedronSetTopologyContainer tetrahedra="0 1 2 3"/>
                       <MeshSpringForceField tetrasStiffness="10"/>)");
  std::vector<std::pair<int, int>> pairs;
  springs(*tets).stiffnessPattern(pairs);
  EXPECT_EQ(pairs.size(), 6u);
}

TEST(MeshSprings, ForceIsMinusTheEnergyGradientAndStiffnessItsDerivative) {
  auto scene = build(R"(<RegularGridTopology name="grid" n="2 2 2"/><MechanicalObject/>
                        <MeshSpringForceField stiffness="50"/>)");
  ForceField& ff = springs(*scene);
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  Simulation sim(*scene);
  State& s = sim.state();
  std::srand(7);
  const Eigen::Matrix3Xd x = mo.x0 + 0.1 * Eigen::Matrix3Xd::Random(3, 8);
  const Eigen::Matrix3Xd v = Eigen::Matrix3Xd::Zero(3, 8);
  Eigen::Matrix3Xd f = v;
  ff.addForce(s, x, v, f);
  const double h = 1e-6;
  for (int i = 0; i < 8; ++i)
    for (int c = 0; c < 3; ++c) {
      Eigen::Matrix3Xd xp = x, xm = x;
      xp(c, i) += h;
      xm(c, i) -= h;
      const double grad = (ff.potentialEnergy(xp) - ff.potentialEnergy(xm)) / (2 * h);
      EXPECT_NEAR(f(c, i), -grad, 1e-6 * (1 + std::abs(grad))) << i << " " << c;
    }
  // K dx against the change of the force (linearised at x by addForce above).
  const Eigen::Matrix3Xd dx = 1e-6 * Eigen::Matrix3Xd::Random(3, 8);
  Eigen::Matrix3Xd f2 = v, f1 = v, df = v;
  ff.addForce(s, x + dx, v, f2);
  ff.addForce(s, x, v, f1);  // linearise at x
  ff.addDForce(s, dx, df, 1.0);
  EXPECT_LT((f2 - f1 - df).cwiseAbs().maxCoeff(), 1e-9);
  // Internal forces: they sum to zero.
  EXPECT_LT(f.rowwise().sum().norm(), 1e-10);
}

TEST(SofaSurfaces, TheBoundaryOfAGridIsClosedAndOutward) {
  // Two cells along x: 10 boundary quads, 20 triangles, enclosing the volume 2.
  const HexList hexa = gridHexahedra({3, 2, 2});
  const Eigen::Matrix3Xd X = gridPoints({3, 2, 2}, Eigen::Vector3d::Zero(), Eigen::Vector3d(2, 1, 1));
  const auto tris = hexahedronBoundaryTriangles(hexa, X);
  ASSERT_EQ(tris.cols(), 20);
  double volume = 0;
  for (int t = 0; t < tris.cols(); ++t)
    volume += X.col(tris(0, t)).dot(X.col(tris(1, t)).cross(X.col(tris(2, t)))) / 6;
  EXPECT_NEAR(volume, 2.0, 1e-12);
}

TEST(SofaSurfaces, Tetra2TriangleMappingFillsTheBoundary) {
  auto scene = build(R"(<RegularGridTopology name="grid" n="2 2 2"/><MechanicalObject name="dofs"/>
    <TetrahedronSetTopologyContainer name="tets"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tets"/>
    <Node name="surface">
      <TriangleSetTopologyContainer name="container"/>
      <Tetra2TriangleTopologicalMapping input="@../tets" output="@container"/>
    </Node>)");
  FieldValue tris;
  Component* container = nullptr;
  for (auto* c : scene->all<Component>())
    if (c->name() == "container") container = c;
  ASSERT_TRUE(container && container->field("triangles", tris));
  EXPECT_EQ(tris.values.size(), 12u * 3);  // the cube's six faces, two triangles each
}

namespace {

// The position of node `i` of the first MechanicalObject after `steps` steps of `text`.
Eigen::Vector3d after(const std::string& text, int steps, int i) {
  auto scene = buildScene(io::parseSceneText(text, "listed.xml"));
  Simulation sim(*scene);
  for (int k = 0; k < steps; ++k) EXPECT_FALSE(sim.step());
  return scene->all<MechanicalObject>().front()->x(sim.state()).col(i);
}

}  // namespace

// A node hanging from a fixed one on a SpringForceField: at equilibrium the spring carries the
// weight, so it is stretched by m g / k beyond its rest length.
TEST(ListedSprings, AHangingMassStretchesTheSpringByItsWeightOverK) {
  const Eigen::Vector3d x = after(R"(<Node name="root" gravity="0 -9.81 0">
    <StaticSolver newton_iterations="30"/>
    <MechanicalObject position="0 0 0  0 -1 0"/>
    <UniformMass vertexMass="0.5"/>
    <FixedConstraint indices="0"/>
    <SpringForceField spring="0 1 200 0 0.8"/>
  </Node>)", 1, 1);
  EXPECT_NEAR(x.y(), -(0.8 + 0.5 * 9.81 / 200), 1e-10);
  EXPECT_NEAR(x.x(), 0, 1e-12);
}

// SOFA's newer static form: the iteration settings in a NewtonRaphsonSolver the StaticSolver links
// to (here with a backtracking line search); the equilibrium is the same m g / k stretch.
TEST(ListedSprings, NewtonRaphsonSettingsReachTheSameEquilibrium) {
  const Eigen::Vector3d x = after(R"(<Node name="root" gravity="0 -9.81 0">
    <NewtonRaphsonSolver name="newton" maxNbIterationsNewton="30" absoluteResidualStoppingThreshold="1e-12"
                         relativeInitialStoppingThreshold="0" relativeSuccessiveStoppingThreshold="0"
                         maxNbIterationsLineSearch="4"/>
    <StaticSolver newtonSolver="@newton"/>
    <SparseLDLSolver/>
    <MechanicalObject position="0 0 0  0.3 -2 0"/>
    <UniformMass vertexMass="0.5"/>
    <FixedConstraint indices="0"/>
    <SpringForceField spring="0 1 200 0 0.8"/>
  </Node>)", 1, 1);
  // It starts off to the side; at equilibrium the spring hangs straight down.
  EXPECT_NEAR(x.y(), -(0.8 + 0.5 * 9.81 / 200), 1e-10);
  EXPECT_NEAR(x.x(), 0, 1e-10);
}

TEST(ListedSprings, NewtonRaphsonSettingsNeedTheirStaticSolver) {
  const std::string body = R"(<MechanicalObject position="0 0 0"/><UniformMass vertexMass="1"/>)";
  auto errorOf = [](const std::string& text) {
    try {
      auto scene = buildScene(io::parseSceneText(text, "newton.xml"));
      scene->init();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(errorOf(R"(<Node name="root"><NewtonRaphsonSolver name="n"/><EulerImplicitSolver/><SparseLDLSolver/>)" + body +
                    "</Node>")
                .find("NewtonRaphsonSolver 'n': is used by a StaticSolver that links to it"),
            std::string::npos);
  EXPECT_NE(errorOf(R"(<Node name="root"><NewtonRaphsonSolver name="n"/><StaticSolver newtonSolver="@n" newton_iterations="3"/><SparseLDLSolver/>)" +
                    body + "</Node>")
                .find("StaticSolver.newton_iterations: is set on the linked NewtonRaphsonSolver 'n'; set it there"),
            std::string::npos);
}

// A node resting on a PlaneForceField (held in x and y: the plane gives no stiffness along it)
// sinks until the penalty carries its weight: m g / k.
TEST(PlaneForceField, ANodeRestsAtItsWeightOverKBelowThePlane) {
  const Eigen::Vector3d x = after(R"(<Node name="root" gravity="0 0 -10">
    <StaticSolver newton_iterations="30"/>
    <MechanicalObject position="0.3 0.2 0.49"/>
    <UniformMass vertexMass="2"/>
    <PartialFixedConstraint indices="0" fixedDirections="1 1 0"/>
    <PlaneForceField normal="0 0 2" d="0.5" stiffness="1000"/>
  </Node>)", 1, 0);
  EXPECT_NEAR(x.z(), 0.5 - 2 * 10 / 1000.0, 1e-10);
}

// SOFA's first-order implicit Euler: (M - h K) v = f, x += h v. For a free node under gravity
// v = g after every step (no inertia is carried over), so x moves by h g a step.
TEST(ListedSprings, FirstOrderEulerTakesTheVelocityFromTheForce) {
  const Eigen::Vector3d x = after(R"(<Node name="root" gravity="0 -9.81 0" dt="0.1">
    <EulerImplicitSolver firstOrder="true"/><CGLinearSolver iterations="20" tolerance="1e-12" threshold="1e-20"/>
    <MechanicalObject position="0 0 0"/>
    <UniformMass vertexMass="3"/>
  </Node>)", 4, 0);
  EXPECT_NEAR(x.y(), 4 * 0.1 * -9.81, 1e-9);
}

// A solved state with neither mass nor force stays where it is (as in SOFA), with a note; one with
// a force but no mass is an error naming the state.
TEST(MechanicalSystem, NothingActingLeavesTheStateWhereItIs) {
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" gravity="0 -9.81 0">
    <EulerImplicitSolver/><CGLinearSolver iterations="10" tolerance="1e-12" threshold="1e-20"/>
    <MechanicalObject name="dofs" position="0 0 0  1 2 3"/>
  </Node>)", "inert.xml"));
  Simulation sim(*scene);
  for (int k = 0; k < 5; ++k) ASSERT_FALSE(sim.step());
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  EXPECT_EQ(mo.x(sim.state()), mo.xInit);
  std::string notes;
  for (const auto& n : scene->notes()) notes += n + "\n";
  EXPECT_NE(notes.find("inert.xml:3:5: note: nothing acts on MechanicalObject 'dofs'"), std::string::npos) << notes;
  try {
    auto bad = buildScene(io::parseSceneText(R"(<Node name="root"><EulerImplicitSolver/><CGLinearSolver/>
      <MechanicalObject name="dofs" position="0 0 0  1 0 0"/><SpringForceField spring="0 1 10 0 1"/></Node>)", "bad.xml"));
    bad->init();
    ADD_FAILURE() << "a force without a mass was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no mass acts on MechanicalObject 'dofs'"), std::string::npos) << e.what();
  }
}

// BDFOdeSolver on a mass on a spring (omega = 10 rad/s), against x(t) = L + A cos(omega t): halving
// the step divides the error at t = 0.5 s by 2^k for order k (1 and 2; order 2 starts with one
// first-order step, which keeps its second order).
TEST(BDFOdeSolver, ConvergesAtItsOrderOnAnOscillator) {
  auto errorAt = [](int order, double dt) {
    const int steps = static_cast<int>(std::lround(0.5 / dt));
    auto scene = buildScene(io::parseSceneText(R"(<Node name="root" gravity="0 0 0" dt=")" + std::to_string(dt) + R"(">
      <BDFOdeSolver order=")" + std::to_string(order) + R"("/>
      <NewtonRaphsonSolver maxNbIterationsNewton="5" absoluteResidualStoppingThreshold="1e-13"
                           relativeInitialStoppingThreshold="0" relativeSuccessiveStoppingThreshold="0"/>
      <SparseLDLSolver/>
      <MechanicalObject position="0 0 0  1.1 0 0"/>
      <UniformMass vertexMass="1"/>
      <FixedConstraint indices="0"/>
      <SpringForceField spring="0 1 100 0 1"/>
    </Node>)", "bdf.xml"));
    Simulation sim(*scene);
    for (int k = 0; k < steps; ++k) EXPECT_FALSE(sim.step());
    const double x = scene->all<MechanicalObject>().front()->x(sim.state())(0, 1);
    return std::abs(x - (1 + 0.1 * std::cos(10 * 0.5)));
  };
  for (int order : {1, 2}) {
    const double coarse = errorAt(order, 0.002), fine = errorAt(order, 0.001);
    const double ratio = coarse / fine;
    EXPECT_NEAR(ratio, std::pow(2.0, order), 0.25 * std::pow(2.0, order)) << "order " << order << ": " << coarse << " -> " << fine;
  }
}

// SOFA's mesh springs take the given stiffness per unit rest length: a node hanging 2 below a
// fixed one on an edge with linesStiffness k stretches it by m g L / k (a spring of k / L).
TEST(MeshSprings, StiffnessIsPerUnitRestLength) {
  const Eigen::Vector3d x = after(R"(<Node name="root" gravity="0 -9.81 0">
    <StaticSolver newton_iterations="30"/>
    <MechanicalObject position="0 0 0  0 -2 0"/>
    <EdgeSetTopologyContainer edges="0 1"/>
    <UniformMass vertexMass="0.5"/>
    <FixedConstraint indices="0"/>
    <PartialFixedConstraint indices="1" fixedDirections="1 0 1"/>  <!-- a spring at rest has no stiffness across it -->
    <MeshSpringForceField linesStiffness="300"/>
  </Node>)", 1, 1);
  EXPECT_NEAR(x.y(), -(2 + 0.5 * 9.81 * 2 / 300), 1e-10);
}

// Rayleigh stiffness damping under BDF takes energy out: after 2 s the damped oscillator's
// amplitude is below the undamped one's (BDF's own dissipation is in both).
TEST(BDFOdeSolver, RayleighStiffnessDampingDampsTheOscillator) {
  auto amplitude = [](double rK) {
    auto scene = buildScene(io::parseSceneText(R"(<Node name="root" gravity="0 0 0" dt="0.005">
      <BDFOdeSolver order="2" rayleighStiffness=")" + std::to_string(rK) + R"("/>
      <NewtonRaphsonSolver maxNbIterationsNewton="5" absoluteResidualStoppingThreshold="1e-13"
                           relativeInitialStoppingThreshold="0" relativeSuccessiveStoppingThreshold="0"/>
      <SparseLDLSolver/>
      <MechanicalObject position="0 0 0  1.1 0 0"/>
      <UniformMass vertexMass="1"/>
      <FixedConstraint indices="0"/>
      <SpringForceField spring="0 1 100 0 1"/>
    </Node>)", "bdf_damped.xml"));
    Simulation sim(*scene);
    double peak = 0;
    for (int k = 0; k < 400; ++k) {
      EXPECT_FALSE(sim.step());
      if (k >= 300) peak = std::max(peak, std::abs(scene->all<MechanicalObject>().front()->x(sim.state())(0, 1) - 1));
    }
    return peak;
  };
  const double free = amplitude(0), damped = amplitude(0.02);
  EXPECT_LT(free, 0.1);
  EXPECT_GT(free, 0.08);               // BDF2 itself loses little over 2 s
  EXPECT_LT(damped, 0.7 * free);       // exp(-rK w^2 t / 2) = exp(-2) ~ 0.14 of it
}

// Newmark's average acceleration (beta 1/4, gamma 1/2) keeps the energy of a linear undamped
// oscillator: after 500 steps, 1/2 m v^2 + 1/2 k u^2 is its initial value (to round-off); with
// gamma 0.6 (and beta (gamma + 1/2)^2 / 4, unconditionally stable) it loses energy.
TEST(NewmarkImplicitSolver, AverageAccelerationKeepsTheOscillatorsEnergy) {
  auto energyAfter = [](const std::string& gamma, const std::string& beta, const std::string& damping = "") {
    auto scene = buildScene(io::parseSceneText(R"(<Node name="root" gravity="0 0 0" dt="0.01">
      <NewmarkImplicitSolver gamma=")" + gamma + R"(" beta=")" + beta + R"(" )" + damping + R"(/>
      <SparseLDLSolver/>
      <MechanicalObject position="0 0 0  1.1 0 0"/>
      <UniformMass vertexMass="2"/>
      <FixedConstraint indices="0"/>
      <SpringForceField spring="0 1 100 0 1"/>
    </Node>)", "newmark.xml"));
    Simulation sim(*scene);
    for (int k = 0; k < 500; ++k) EXPECT_FALSE(sim.step());
    const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
    const double u = mo.x(sim.state())(0, 1) - 1, v = mo.v(sim.state())(0, 1);
    return 0.5 * 2 * v * v + 0.5 * 100 * u * u;
  };
  const double start = 0.5 * 100 * 0.1 * 0.1;
  EXPECT_NEAR(energyAfter("0.5", "0.25"), start, 1e-10 * start);
  EXPECT_LT(energyAfter("0.6", "0.3025"), 0.9 * start);
  // Rayleigh damping (mass, then stiffness) takes energy out of the energy-keeping scheme:
  // exp(-rM t) = exp(-1) and exp(-rK w^2 t) = exp(-2.5) of it over the 5 s.
  EXPECT_LT(energyAfter("0.5", "0.25", R"(rayleighMass="0.2")"), 0.5 * start);
  EXPECT_LT(energyAfter("0.5", "0.25", R"(rayleighStiffness="0.01")"), 0.2 * start);
}

namespace {

// Every node's position after `steps` steps, MechanicalObjects in scene order, nodes in order.
Eigen::Matrix3Xd allNodesAfter(const std::string& text, int steps) {
  auto scene = buildScene(io::parseSceneText(text, "interaction.xml"));
  Simulation sim(*scene);
  for (int k = 0; k < steps; ++k) EXPECT_FALSE(sim.step());
  std::vector<Eigen::Vector3d> cols;
  for (MechanicalObject* m : scene->all<MechanicalObject>())
    for (int i = 0; i < m->size(); ++i) cols.push_back(m->x(sim.state()).col(i));
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(cols.size()));
  for (size_t i = 0; i < cols.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = cols[i];
  return out;
}

// A chain of four nodes hanging from a fixed point: written as one object (the reference, solved
// by the single-body path) and as springs between objects under one solver (the joint path).
std::string oneObjectChain(const std::string& linear) {
  return R"(<Node name="root" gravity="0 -9.81 0" dt="0.01">
    <EulerImplicitSolver rayleighStiffness="0.1" rayleighMass="0.1"/>)" + linear + R"(
    <MechanicalObject position="0 0 0  0.3 -1 0  0.5 -2 0.2  1 -2.5 0  1.2 -3 0.4"/>
    <UniformMass vertexMass="0.5"/>
    <FixedConstraint indices="0"/>
    <SpringForceField spring="0 1 200 0.5 1  1 2 150 0.5 1  2 3 300 0 0.8  3 4 100 1 0.6  1 3 50 0 1.5"/>
  </Node>)";
}
std::string twoObjectChain(const std::string& linear) {
  return R"(<Node name="root" gravity="0 -9.81 0" dt="0.01">
    <EulerImplicitSolver rayleighStiffness="0.1" rayleighMass="0.1"/>)" + linear + R"(
    <Node name="anchor"><MechanicalObject name="dofs" position="0 0 0"/></Node>
    <Node name="upper">
      <MechanicalObject name="dofs" position="0.3 -1 0  0.5 -2 0.2"/>
      <UniformMass vertexMass="0.5"/>
      <SpringForceField spring="0 1 150 0.5 1"/>
    </Node>
    <Node name="lower">
      <MechanicalObject name="dofs" position="1 -2.5 0  1.2 -3 0.4"/>
      <UniformMass vertexMass="0.5"/>
      <SpringForceField spring="0 1 100 1 0.6"/>
    </Node>
    <SpringForceField object1="@anchor/dofs" object2="@upper/dofs" spring="0 0 200 0.5 1"/>
    <SpringForceField object1="@upper/dofs" object2="@lower/dofs" spring="1 0 300 0 0.8  0 0 50 0 1.5"/>
  </Node>)";
}

}  // namespace

// Springs between objects under one EulerImplicitSolver move them as the same springs inside one
// object: the joint system (the bodies side by side, the couplings' blocks between them, an end
// on an object without mass held still) is the single body's, reordered. With a direct solver
// and with a converged conjugate gradient, assembled or matrix-free, the chains agree after 200
// steps to 1e-9 (round-off and the CG tolerance; the chain swings by about 1).
TEST(InteractionSprings, ObjectsCoupledBySpringsMoveAsOneObject) {
  for (const std::string linear : {R"(<SparseLDLSolver/>)", R"(<CGLinearSolver iterations="200" tolerance="1e-14" threshold="1e-30"/>)",
                                   R"(<CGLinearSolver iterations="200" tolerance="1e-14" threshold="1e-30" assembled="false"/>)"}) {
    const Eigen::Matrix3Xd one = allNodesAfter(oneObjectChain(linear), 200);
    const Eigen::Matrix3Xd two = allNodesAfter(twoObjectChain(linear), 200);
    ASSERT_EQ(two.cols(), one.cols()) << linear;
    EXPECT_LT((two - one).cwiseAbs().maxCoeff(), 1e-9) << linear;
    EXPECT_GT((one.col(4) - Eigen::Vector3d(1.2, -3, 0.4)).norm(), 0.5) << linear;  // it moved
    EXPECT_EQ(two.col(0), Eigen::Vector3d::Zero()) << linear;                      // the anchor held
  }
}

TEST(InteractionSprings, ClearErrors) {
  auto message = [](const std::string& text) {
    try {
      auto scene = buildScene(io::parseSceneText(text, "interaction.xml"));
      Simulation sim(*scene);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  // Ends integrated by two solvers.
  std::string m = message(R"(<Node name="root">
    <Node name="a"><EulerImplicitSolver/><SparseLDLSolver/><MechanicalObject name="dofs" position="0 0 0"/><UniformMass vertexMass="1"/></Node>
    <Node name="b"><EulerImplicitSolver/><SparseLDLSolver/><MechanicalObject name="dofs" position="1 0 0"/><UniformMass vertexMass="1"/></Node>
    <SpringForceField object1="@a/dofs" object2="@b/dofs" spring="0 0 10 0 1"/></Node>)");
  EXPECT_NE(m.find("two solvers"), std::string::npos) << m;
  // A node that object2 does not have.
  m = message(R"(<Node name="root"><EulerImplicitSolver/><SparseLDLSolver/>
    <Node name="a"><MechanicalObject name="dofs" position="0 0 0"/><UniformMass vertexMass="1"/></Node>
    <Node name="b"><MechanicalObject name="dofs" position="1 0 0"/><UniformMass vertexMass="1"/></Node>
    <SpringForceField object1="@a/dofs" object2="@b/dofs" spring="0 3 10 0 1"/></Node>)");
  EXPECT_NE(m.find("object2"), std::string::npos) << m;
  EXPECT_NE(m.find("spring"), std::string::npos) << m;
  // Only EulerImplicitSolver takes springs between objects (here to an anchor).
  m = message(R"(<Node name="root">
    <Node name="anchor"><MechanicalObject name="dofs" position="0 0 0"/></Node>
    <Node name="b"><EulerExplicitSolver/><MechanicalObject name="dofs" position="1 0 0"/><UniformMass vertexMass="1"/></Node>
    <SpringForceField object1="@anchor/dofs" object2="@b/dofs" spring="0 0 10 0 1"/></Node>)");
  EXPECT_NE(m.find("EulerImplicitSolver"), std::string::npos) << m;
  // A contact correction computes the body's compliance without the springs to other objects.
  m = message(R"(<Node name="root"><FreeMotionAnimationLoop/><GenericConstraintSolver/>
    <Node name="anchor"><MechanicalObject name="dofs" position="0 0 0"/></Node>
    <Node name="b"><EulerImplicitSolver/><SparseLDLSolver/><MechanicalObject name="dofs" position="1 0 0"/><UniformMass vertexMass="1"/>
      <LinearSolverConstraintCorrection/></Node>
    <SpringForceField name="tie" object1="@anchor/dofs" object2="@b/dofs" spring="0 0 10 0 1"/></Node>)");
  EXPECT_NE(m.find("tied to another object"), std::string::npos) << m;
  EXPECT_NE(m.find("tie"), std::string::npos) << m;
  // A rigid body's frame is not a spring end.
  m = message(R"(<Node name="root"><EulerImplicitSolver/><SparseLDLSolver/>
    <Node name="a"><MechanicalObject name="dofs" position="0 0 0"/><UniformMass vertexMass="1"/></Node>
    <Node name="r"><MechanicalObject name="frame" template="Rigid3d" position="1 0 0 0 0 0 1"/><UniformMass totalMass="1"/></Node>
    <SpringForceField object1="@a/dofs" object2="@r/frame" spring="0 0 10 0 1"/></Node>)");
  EXPECT_NE(m.find("Rigid3d"), std::string::npos) << m;
}

// Springs whose object1 and object2 are the same object are that object's own, wherever they are
// placed and whatever solver moves it: the same motion, to the bit, as the springs in its node.
TEST(InteractionSprings, BothEndsOnOneObjectAreItsOwnSprings) {
  for (const std::string solver : {"<EulerImplicitSolver rayleighMass=\"0.1\"/><SparseLDLSolver/>", "<RungeKutta4Solver/>"}) {
    const std::string inside = R"(<Node name="root" gravity="0 -9.81 0" dt="0.01">
      <Node name="body">)" + solver + R"(
        <MechanicalObject name="dofs" position="0 0 0  0.3 -1 0  0.5 -2 0.2"/>
        <UniformMass vertexMass="0.5"/>
        <FixedConstraint indices="0"/>
        <SpringForceField spring="0 1 200 0.5 1  1 2 150 0.5 1"/>
      </Node></Node>)";
    std::string outside = inside;
    outside.replace(outside.find("<SpringForceField"), std::string("<SpringForceField").size(),
                    "</Node><SpringForceField object1=\"@body/dofs\" object2=\"@body/dofs\"");
    outside.replace(outside.rfind("</Node></Node>"), 14, "</Node>");
    const Eigen::Matrix3Xd a = allNodesAfter(inside, 100), b = allNodesAfter(outside, 100);
    EXPECT_TRUE(a == b) << solver << "\n" << a << "\n" << b;
    EXPECT_GT((a.col(2) - Eigen::Vector3d(0.5, -2, 0.2)).norm(), 0.1) << solver;
  }
}

// SOFA's older name, StiffSpringForceField, is the same component.
TEST(InteractionSprings, StiffSpringForceFieldIsTheOlderName) {
  const std::string linear = "<SparseLDLSolver/>";
  std::string older = twoObjectChain(linear);
  for (size_t p = older.find("<SpringForceField"); p != std::string::npos; p = older.find("<SpringForceField", p + 6))
    older.replace(p, 17, "<StiffSpringForceField");
  ASSERT_NE(older.find("StiffSpringForceField"), std::string::npos);
  EXPECT_TRUE(allNodesAfter(older, 50) == allNodesAfter(twoObjectChain(linear), 50));
}
