// Prescribed boundary motions (SOFA's patch-test constraints) and the selection they use:
// PairBoxROI's frame of nodes; AffineMovementProjectiveConstraint reaching R x0 + t on its time
// ramp; and the patch test itself, checked against the exact answer: with the boundary moved by an
// affine field, a linear FEM (constant strain) and springs on a regular grid are in equilibrium
// only when every interior node follows the same affine field.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <string>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"
#include "tests/support/ErrorOf.h"

using namespace viscera;

namespace {

std::unique_ptr<Scene> build(const std::string& text) {
  auto scene = buildScene(io::parseSceneText(text, "movement.xml"));
  scene->init();
  return scene;
}

std::vector<int> indicesOf(Scene& s, const std::string& name) {
  for (Component* c : s.all<Component>())
    if (c->name() == name) {
      FieldValue f;
      EXPECT_TRUE(c->field("indices", f));
      return std::vector<int>(f.values.begin(), f.values.end());
    }
  ADD_FAILURE() << "no component " << name;
  return {};
}

// u(x) = A x + b, the affine field the patch tests impose.
const Eigen::Matrix3d kA = (Eigen::Matrix3d() << 0.05, 0.02, -0.01, 0.00, -0.03, 0.04, 0.01, 0.02, 0.06).finished();
const Eigen::Vector3d kB(0.01, -0.02, 0.03);

std::string cornerMovements(bool volume) {
  std::string m;
  for (int z = 0; z < (volume ? 2 : 1); ++z)
    for (const auto& c : {Eigen::Vector3d(0, 0, z), Eigen::Vector3d(1, 0, z), Eigen::Vector3d(1, 1, z), Eigen::Vector3d(0, 1, z)}) {
      Eigen::Vector3d u = kA * c + kB;
      if (!volume) u.z() = 0;  // a flat patch moves in its plane
      m += std::to_string(u.x()) + " " + std::to_string(u.y()) + " " + std::to_string(u.z()) + "  ";
    }
  return m;
}

}  // namespace

TEST(PairBoxROI, SelectsTheFrameBetweenTheBoxesBothClosed) {
  auto s = build(R"(<Node name="root">
    <RegularGridTopology n="5 5 1" min="0 0 0" max="1 1 0"/>
    <MechanicalObject/>
    <PairBoxROI name="frame" inclusiveBox="-0.1 -0.1 0  1.1 1.1 0" includedBox="0.1 0.1 0  0.9 0.9 0"/>
    <PairBoxROI name="closed" inclusiveBox="1 1 0  0 0 0" includedBox="0.25 0.25 0  0.75 0.75 0"/>
  </Node>)");
  // The 16 nodes of the outer ring of the 5 x 5 grid.
  std::vector<int> ring;
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 5; ++i)
      if (i == 0 || j == 0 || i == 4 || j == 4) ring.push_back(i + 5 * j);
  EXPECT_EQ(indicesOf(*s, "frame"), ring);
  // Corners given in either order; nodes on a face of the inner box are inside it, so only the
  // outer ring is left again.
  EXPECT_EQ(indicesOf(*s, "closed"), ring);
}

// BoxROI's pointsInROI: the selected nodes' rest positions, in the order of its indices.
TEST(BoxROI, GivesThePositionsOfTheSelectedPoints) {
  auto s = build(R"(<Node name="root">
    <RegularGridTopology n="3 2 1" min="0 0 0" max="2 1 0"/>
    <MechanicalObject/>
    <BoxROI name="roi" box="0.5 -0.1 -0.1  2.1 1.1 0.1"/>
  </Node>)");
  EXPECT_EQ(indicesOf(*s, "roi"), (std::vector<int>{1, 2, 4, 5}));
  for (Component* c : s->all<Component>())
    if (c->name() == "roi") {
      FieldValue f;
      ASSERT_TRUE(c->field("pointsInROI", f));
      EXPECT_EQ(f.values, (std::vector<double>{1, 0, 0, 2, 0, 0, 1, 1, 0, 2, 1, 0}));
    }
}

// Every node of a small grid is moved: half-way through the ramp it is half-way to R x0 + t, and
// after the end it stays there. The positions at the end of a step are those of its start time.
TEST(AffineMovement, NodesRampToTheRotatedAndTranslatedPositions) {
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" dt="0.1" gravity="0 -9.81 0">
    <EulerImplicitSolver/><CGLinearSolver iterations="50" tolerance="1e-12" threshold="1e-20"/>
    <RegularGridTopology n="3 3 2" min="0 0 0" max="1 1 0.5"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <MeshSpringForceField linesStiffness="10"/>
    <BoxROI name="all" box="-1 -1 -1 2 2 2"/>
    <AffineMovementProjectiveConstraint indices="@all.indices" rotation="[0 -1 0,1 0 0,0 0 1]" translation="0.5 0 0"
                                        beginConstraintTime="0.2" endConstraintTime="0.6"/>
  </Node>)", "affine.xml"));
  Simulation sim(*scene);
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  Eigen::Matrix3d R;
  R << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  const Eigen::Matrix3Xd X0 = mo.xInit;
  const Eigen::Matrix3Xd XF = (R * X0).colwise() + Eigen::Vector3d(0.5, 0, 0);
  for (int k = 1; k <= 9; ++k) {
    ASSERT_FALSE(sim.step());
    const double start = 0.1 * (k - 1);  // the step's start time
    const double a = start <= 0.2 ? 0 : start >= 0.6 ? 1 : (start - 0.2) / 0.4;
    const Eigen::Matrix3Xd expected = X0 + a * (XF - X0);
    EXPECT_LT((mo.x(sim.state()) - expected).cwiseAbs().maxCoeff(), 1e-12) << "step " << k;
    EXPECT_EQ(mo.v(sim.state()).cwiseAbs().maxCoeff(), 0.0) << "step " << k;
  }
}

TEST(AffineMovement, BadInputIsNamed) {
  const std::string grid = R"(<Node name="root"><StaticSolver/><RegularGridTopology n="2 2 2"/><MechanicalObject/>
    <UniformMass totalMass="1"/>)";
  EXPECT_NE(test_support::errorOf([&] {
              build(grid + R"(<AffineMovementProjectiveConstraint indices="0 9"/></Node>)");
            }).find("AffineMovementProjectiveConstraint.indices: node 9 is out of range"),
            std::string::npos);
  EXPECT_NE(test_support::errorOf([&] {
              build(grid + R"(<AffineMovementProjectiveConstraint indices="0" rotation="[1 0 0,0 1 0]"/></Node>)");
            }).find("rotation: needs 9 numbers"),
            std::string::npos);
  EXPECT_NE(test_support::errorOf([&] {
              build(grid + R"(<AffineMovementProjectiveConstraint indices="0" endConstraintTime="0"/></Node>)");
            }).find("endConstraintTime: must be after beginConstraintTime"),
            std::string::npos);
  EXPECT_NE(test_support::errorOf([&] {
              build(grid + R"(<PatchTestMovementProjectiveConstraint indices="0 1 2 3 4 5 6 7" cornerMovements="0 0 0  0 0 0  0 0 0  0 0 0"/></Node>)");
            }).find("needs 8 displacements (x y z each) for a volume's 8 corners, got 12 numbers"),
            std::string::npos);
}

// The patch test on a 4 x 4 x 4 grid of linear tetrahedra: the boundary follows u(x) = A x + b
// (the trilinear blend of the corners' u reproduces it), so the static solution is u everywhere.
// The tolerance covers the Newton solve's round-off, far below the 1e-2 size of u.
TEST(PatchTestMovement, AFemPatchFollowsTheAffineFieldInside) {
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" dt="1" gravity="0 0 0">
    <StaticSolver newton_iterations="5"/>
    <RegularGridTopology name="grid" n="4 4 4" min="0 0 0" max="1 1 1"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3" method="small"/>
    <PairBoxROI name="boundary" inclusiveBox="-0.1 -0.1 -0.1 1.1 1.1 1.1" includedBox="0.1 0.1 0.1 0.9 0.9 0.9"/>
    <PatchTestMovementProjectiveConstraint indices="@boundary.indices" constrainedPoints="@boundary.pointsInROI"
        endConstraintTime="1" cornerMovements=")" + cornerMovements(true) + R"("/>
  </Node>)", "patch.xml"));
  Simulation sim(*scene);
  ASSERT_FALSE(sim.step());
  ASSERT_FALSE(sim.step());  // the second step starts at the end time: the boundary is in place
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  const Eigen::Matrix3Xd u = mo.x(sim.state()) - mo.xInit;
  int inside = 0;
  for (int i = 0; i < mo.size(); ++i) {
    const Eigen::Vector3d x = mo.xInit.col(i);
    EXPECT_LT((u.col(i) - (kA * x + kB)).norm(), 1e-9) << "node " << i;
    inside += (x.array() > 0.1).all() && (x.array() < 0.9).all();
  }
  EXPECT_EQ(inside, 8);
}

// The same on a flat 5 x 5 grid of springs (sides and diagonals of its quads): under an affine
// field every spring of one direction stretches alike, and an interior node's springs pair off.
TEST(PatchTestMovement, AFlatSpringGridFollowsTheAffineFieldInside) {
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" dt="1" gravity="0 0 0">
    <StaticSolver newton_iterations="20"/>
    <RegularGridTopology n="5 5 1" min="0 0 0" max="1 1 0" position="@dofs.position"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <MeshSpringForceField quadsStiffness="10"/>
    <PartialFixedConstraint indices="6 7 8 11 12 13 16 17 18" fixedDirections="0 0 1"/>  <!-- springs in a plane give no stiffness across it -->
    <PairBoxROI name="boundary" inclusiveBox="-0.1 -0.1 0 1.1 1.1 0" includedBox="0.1 0.1 0 0.9 0.9 0"/>
    <PatchTestMovementProjectiveConstraint indices="@boundary.indices" constrainedPoints="@boundary.pointsInROI"
        endConstraintTime="1" cornerMovements=")" + cornerMovements(false) + R"("/>
  </Node>)", "flat.xml"));
  Simulation sim(*scene);
  ASSERT_FALSE(sim.step());
  ASSERT_FALSE(sim.step());
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  ASSERT_EQ(mo.size(), 25);
  const Eigen::Matrix3Xd u = mo.x(sim.state()) - mo.xInit;
  for (int i = 0; i < mo.size(); ++i) {
    const Eigen::Vector3d x = mo.xInit.col(i);
    Eigen::Vector3d expected = kA * x + kB;
    expected.z() = 0;
    EXPECT_LT((u.col(i) - expected).norm(), 1e-9) << "node " << i;
  }
}

// A node driven on a sine: after each step it sits at mean + A sin(w t + phase) and moves at
// A w cos(w t + phase), t the step's start time; its spring neighbour follows it.
TEST(OscillatorMovement, ANodeFollowsItsSine) {
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" dt="0.01" gravity="0 0 0">
    <EulerImplicitSolver/><CGLinearSolver iterations="50" tolerance="1e-12" threshold="1e-20"/>
    <MechanicalObject position="0 0 0  1 0 0"/>
    <UniformMass totalMass="1"/>
    <SpringForceField spring="0 1 100 0 1"/>
    <OscillatorProjectiveConstraint oscillators="0  0.5 0 0  0.2 0.1 0  6 0.3"/>
  </Node>)", "oscillator.xml"));
  Simulation sim(*scene);
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  for (int k = 1; k <= 30; ++k) {
    ASSERT_FALSE(sim.step());
    const double t = 0.01 * (k - 1);
    const Eigen::Vector3d x = Eigen::Vector3d(0.5, 0, 0) + Eigen::Vector3d(0.2, 0.1, 0) * std::sin(6 * t + 0.3);
    const Eigen::Vector3d v = Eigen::Vector3d(0.2, 0.1, 0) * (6 * std::cos(6 * t + 0.3));
    EXPECT_LT((mo.x(sim.state()).col(0) - x).norm(), 1e-14) << "step " << k;
    EXPECT_LT((mo.v(sim.state()).col(0) - v).norm(), 1e-14) << "step " << k;
  }
  EXPECT_GT(std::abs(mo.x(sim.state())(1, 1)), 1e-4);  // the free node was pulled along
  EXPECT_NE(test_support::errorOf([] {
              build(R"(<Node name="root"><MechanicalObject position="0 0 0"/>
                <OscillatorProjectiveConstraint oscillators="3 0 0 0 1 0 0 1 0"/></Node>)");
            }).find("OscillatorProjectiveConstraint.oscillators: entry 0: node 3"),
            std::string::npos);
}

// Projections onto shapes: a free node under gravity slides in its plane (its normal coordinate
// stays 0 and its in-plane acceleration is g's in-plane part), one on a line moves only along it,
// and one projected onto a point sits there from the first step.
TEST(ShapeProjection, NodesStayOnTheirPlaneLineAndPoint) {
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" dt="0.01" gravity="1 -2 3">
    <EulerImplicitSolver/><CGLinearSolver iterations="50" tolerance="1e-14" threshold="1e-30"/>
    <MechanicalObject position="0 0 0  1 1 1  0 0.5 0.2"/>
    <UniformMass vertexMass="1"/>
    <PlaneProjectiveConstraint indices="0" origin="0 0 0" normal="0 0 2"/>
    <LineProjectiveConstraint indices="1" origin="1 1 1" direction="0 3 0"/>
    <PointProjectiveConstraint indices="2" point="4 5 6"/>
  </Node>)", "shapes.xml"));
  Simulation sim(*scene);
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  const int steps = 20;
  for (int k = 0; k < steps; ++k) ASSERT_FALSE(sim.step());
  const Eigen::Matrix3Xd& x = mo.x(sim.state());
  // Implicit Euler from rest under a constant acceleration a: x = h^2 a n (n + 1) / 2.
  const double travel = 0.01 * 0.01 * steps * (steps + 1) / 2.0;
  EXPECT_LT((x.col(0) - travel * Eigen::Vector3d(1, -2, 0)).norm(), 1e-12);
  EXPECT_LT((x.col(1) - (Eigen::Vector3d(1, 1, 1) + travel * Eigen::Vector3d(0, -2, 0))).norm(), 1e-12);
  EXPECT_EQ(x.col(2), Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(mo.v(sim.state()).col(2), Eigen::Vector3d::Zero());
  EXPECT_NE(test_support::errorOf([] {
              build(R"(<Node name="root"><MechanicalObject position="0 0 0"/>
                <PlaneProjectiveConstraint indices="0" normal="0 0 0"/></Node>)");
            }).find("PlaneProjectiveConstraint.normal: must not be zero"),
            std::string::npos);
}

// A pressure load on the top face of a tetrahedron selected by a box: each vertex of the face
// carries a third of pressure x area, and nothing else is loaded.
TEST(TrianglePressure, ATriangleCarriesPressureTimesAreaInThirds) {
  auto scene = build(R"(<Node name="root" gravity="0 0 0">
    <MechanicalObject name="dofs" position="0 0 0  2 0 1  0 2 1  2 2 1"/>
    <TriangleSetTopologyContainer name="surface" triangles="0 1 2  1 3 2"/>
    <BoxROI name="top" box="-1 -1 0.5  3 3 1.5" triangles="@surface.triangles"/>
    <TrianglePressureForceField triangleList="@top.triangleIndices" pressure="0 0 -3"/>
  </Node>)");
  EXPECT_EQ(indicesOf(*scene, "top"), (std::vector<int>{1, 2, 3}));
  ForceField& ff = *scene->all<ForceField>().front();
  State s;
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, 4);
  ff.addForce(s, mo.x0, mo.x0, f);
  // Only triangle 1 (1 3 2) is inside: area 2, so each of its vertices gets (0, 0, -3 * 2 / 3).
  EXPECT_EQ(f.col(0), Eigen::Vector3d::Zero());
  for (int i : {1, 2, 3}) EXPECT_LT((f.col(i) - Eigen::Vector3d(0, 0, -2)).norm(), 1e-14) << i;
}

// Under BDFOdeSolver too: the affine movement reaches its targets exactly, and a node projected on
// a plane stays on it (what drivers and corrections set is the state the next step starts from).
TEST(AffineMovement, AndProjectionsHoldUnderBDF) {
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" dt="0.1" gravity="0 -9.81 0">
    <BDFOdeSolver order="2"/><NewtonRaphsonSolver maxNbIterationsNewton="5" absoluteResidualStoppingThreshold="1e-12"/>
    <SparseLDLSolver/>
    <RegularGridTopology n="3 3 2" min="0 0 0" max="1 1 0.5"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <MeshSpringForceField linesStiffness="10"/>
    <BoxROI name="left" box="-1 -1 -1 0.1 2 2"/>
    <AffineMovementProjectiveConstraint indices="@left.indices" translation="0.5 0 0" beginConstraintTime="0" endConstraintTime="0.4"/>
    <PlaneProjectiveConstraint indices="8" normal="0 1 0" origin="0 1 0"/>
  </Node>)", "bdf_moves.xml"));
  Simulation sim(*scene);
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  const std::vector<int> left = indicesOf(*scene, "left");
  ASSERT_FALSE(left.empty());
  for (int k = 1; k <= 8; ++k) {
    ASSERT_FALSE(sim.step());
    const double a = std::min(1.0, 0.1 * (k - 1) / 0.4);
    for (int i : left)
      EXPECT_LT((mo.x(sim.state()).col(i) - (mo.xInit.col(i) + Eigen::Vector3d(0.5 * a, 0, 0))).norm(), 1e-12) << "step " << k;
    EXPECT_NEAR(mo.x(sim.state())(1, 8), 1.0, 1e-12) << "step " << k;
  }
  EXPECT_NE(test_support::errorOf([] {
              build(R"(<Node name="root"><MechanicalObject position="0 0 0  1 0 0"/><StaticSolver/><UniformMass totalMass="1"/>
                <FixedConstraint indices="1"/><AffineMovementProjectiveConstraint indices="1" translation="1 0 0"/></Node>)");
            }).find("node 1 of 'MechanicalObject' is also held by FixedConstraint"),
            std::string::npos);
}
