// The warp preconditioners (SOFA's WarpPreconditioner and PrecomputedWarpPreconditioner): a matrix
// factorised at rest and turned with the nodes' rotations is the exact inverse of the corotational
// step's matrix once the body has turned rigidly, so one PCG iteration gives the direct solve; the
// nodes' rotations are the polar factor of their elements' rotations.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <memory>
#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"
#include "solvers/linear/LinearSolver.h"

using namespace viscera;

namespace {

Eigen::Matrix3d turn(double degrees, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(degrees * M_PI / 180, axis.normalized()).toRotationMatrix();
}

TEST(AverageNodeRotations, NodesOfElementsTurnedAlikeTurnAlike) {
  // Two tetrahedra sharing nodes 1-3, both turned by R: every node of them turns by R; node 5 is
  // in no element and keeps the identity.
  const int tets[8] = {0, 1, 2, 3, 1, 2, 3, 4};
  const Eigen::Matrix3d R = turn(37, {1, 2, 3});
  const Eigen::Matrix3d rots[2] = {R, R};
  const auto nodes = averageNodeRotations(6, tets, 4, rots, 2);
  ASSERT_EQ(nodes.size(), 6u);
  for (int i = 0; i < 5; ++i) EXPECT_LT((nodes[i] - R).norm(), 1e-12) << "node " << i;
  EXPECT_LT((nodes[5] - Eigen::Matrix3d::Identity()).norm(), 1e-15);
}

TEST(AverageNodeRotations, DifferentRotationsAverageToARotationBetween) {
  // Turns of 10 and 30 degrees about one axis average to 20 degrees about it (the polar factor of
  // their sum), a proper rotation.
  const int tets[8] = {0, 1, 2, 3, 0, 4, 5, 6};
  const Eigen::Vector3d axis(0, 0, 1);
  const Eigen::Matrix3d rots[2] = {turn(10, axis), turn(30, axis)};
  const auto nodes = averageNodeRotations(7, tets, 4, rots, 2);
  EXPECT_LT((nodes[0] - turn(20, axis)).norm(), 1e-12);
  EXPECT_NEAR(nodes[0].determinant(), 1.0, 1e-12);
  EXPECT_LT((nodes[1] - turn(10, axis)).norm(), 1e-12);
  EXPECT_LT((nodes[4] - turn(30, axis)).norm(), 1e-12);
}

const char* kTetrahedra = R"(<TetrahedronFEMForceField method="large" youngModulus="1000" poissonRatio="0.3"/>)";

std::string beam(const std::string& solvers, const std::string& fem = kTetrahedra) {
  return R"(<Node name="root" dt="0.01" gravity="0 0 0">
  <EulerImplicitSolver rayleighStiffness="0.1" rayleighMass="0.1"/>
  )" + solvers + R"(
  <RegularGridTopology name="grid" n="3 3 6" min="0 0 0" max="1 1 3"/>
  <MechanicalObject name="dofs"/>
  <UniformMass totalMass="2"/>
  )" + fem + R"(
</Node>)";
}

// Steps the beam once at rest (where a precomputed preconditioner factorises), then turns it
// rigidly by 50 degrees with a velocity field that deforms it, and steps once more: the positions.
Eigen::Matrix3Xd turnedStep(const std::string& solvers, const std::string& fem = kTetrahedra) {
  auto scene = buildScene(io::parseSceneText(beam(solvers, fem), "warp.xml"));
  Simulation sim(*scene);
  sim.begin();
  EXPECT_FALSE(sim.step());
  MechanicalObject& mo = *scene->all<MechanicalObject>()[0];
  MechanicalObject::Live& s = mo.live(sim.state());
  const Eigen::Matrix3d R = turn(50, {1, -2, 0.5});
  const Eigen::Vector3d shift(0.3, -0.2, 1.0);
  for (int i = 0; i < mo.size(); ++i) {
    const Eigen::Vector3d p = mo.x0.col(i);
    s.x.col(i) = R * p + shift;
    s.v.col(i) = R * Eigen::Vector3d(0.2 * p.z() * p.y(), -0.1 * p.x(), 0.3 * p.z());
  }
  EXPECT_FALSE(sim.step());
  return mo.live(sim.state()).x;
}

TEST(WarpPreconditioner, TurnedWithTheBodyOnePcgIterationIsTheDirectSolve) {
  const Eigen::Matrix3Xd direct = turnedStep(R"(<SparseLDLSolver/>)");
  const Eigen::Matrix3Xd warped = turnedStep(R"(<PCGLinearSolver iterations="1" tolerance="0" preconditioner="@warp"/>
  <PrecomputedWarpPreconditioner name="warp" linearSolver="@ldl"/>
  <SparseLDLSolver name="ldl"/>)");
  const Eigen::Matrix3Xd unturned = turnedStep(R"(<PCGLinearSolver iterations="1" tolerance="0" preconditioner="@warp"/>
  <PrecomputedWarpPreconditioner name="warp" linearSolver="@ldl" use_rotations="false"/>
  <SparseLDLSolver name="ldl"/>)");
  // The step moves nodes by about 1e-2; the turned factorisation is exact up to round-off, the
  // unturned one a poor inverse of the turned matrix (2.5e-3 off after one iteration).
  std::printf("  after one iteration: turned factorisation off by %.1e, unturned by %.1e\n",
              (warped - direct).cwiseAbs().maxCoeff(), (unturned - direct).cwiseAbs().maxCoeff());
  EXPECT_LT((warped - direct).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT((unturned - direct).cwiseAbs().maxCoeff(), 1e-5);
}

TEST(WarpPreconditioner, RefactorisedEveryStepAndTurnedBetweenFactorisations) {
  // WarpPreconditioner factorises the step's matrix itself: one iteration is the direct solve
  // with update_step 1, and with update_step 2 (turned, as the precomputed one) too.
  const Eigen::Matrix3Xd direct = turnedStep(R"(<SparseLDLSolver/>)");
  for (const char* step : {"1", "2"}) {
    const Eigen::Matrix3Xd warped = turnedStep(std::string(R"(<PCGLinearSolver iterations="1" tolerance="0" preconditioner="@warp"/>
  <RotationMatrixSystem/>
  <WarpPreconditioner name="warp" linearSolver="@ldl" update_step=")") + step + R"("/>
  <SparseLDLSolver name="ldl"/>)");
    EXPECT_LT((warped - direct).cwiseAbs().maxCoeff(), 1e-12) << "update_step " << step;
  }
}

TEST(WarpPreconditioner, HexahedraTurnItToo) {
  const char* hexahedra = R"(<HexahedronFEMForceField method="large" youngModulus="1000" poissonRatio="0.3"/>)";
  const Eigen::Matrix3Xd direct = turnedStep("<SparseLDLSolver/>", hexahedra);
  const Eigen::Matrix3Xd warped = turnedStep(R"(<PCGLinearSolver iterations="1" tolerance="0" preconditioner="@warp"/>
  <PrecomputedWarpPreconditioner name="warp" linearSolver="@ldl"/>
  <SparseLDLSolver name="ldl"/>)", hexahedra);
  EXPECT_LT((warped - direct).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(WarpPreconditioner, TurnedAtEverySolveWhateverThePcgsUpdateStep) {
  // The PCG rebuilds its other preconditioners every update_step solves; the warp turns at each.
  const Eigen::Matrix3Xd direct = turnedStep("<SparseLDLSolver/>");
  const Eigen::Matrix3Xd warped = turnedStep(R"(<PCGLinearSolver iterations="1" tolerance="0" update_step="2" preconditioner="@warp"/>
  <WarpPreconditioner name="warp" linearSolver="@ldl" update_step="5"/>
  <SparseLDLSolver name="ldl"/>)");
  EXPECT_LT((warped - direct).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(WarpPreconditioner, TheRotationMatrixSystemsRotationFinderIsTheOneUsed) {
  // Two force fields on the beam: a negligible small-strain one first (its nodes never turn), the
  // corotational one second. Named by the RotationMatrixSystem, the corotational one turns the
  // factorisation; left to the context, the first one is taken and nothing turns.
  const std::string fems = R"(<TetrahedronFEMForceField name="small" method="small" youngModulus="1e-9" poissonRatio="0.3"/>
  <TetrahedronFEMForceField name="large" method="large" youngModulus="1000" poissonRatio="0.3"/>)";
  const Eigen::Matrix3Xd direct = turnedStep("<SparseLDLSolver/>", fems);
  auto warped = [&](const std::string& system) {
    return turnedStep(R"(<PCGLinearSolver iterations="1" tolerance="0" preconditioner="@warp"/>
  )" + system + R"(
  <WarpPreconditioner name="warp" linearSolver="@ldl" update_step="5"/>
  <SparseLDLSolver name="ldl"/>)", fems);
  };
  EXPECT_LT((warped(R"(<RotationMatrixSystem rotationFinder="@large"/>)") - direct).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT((warped("<RotationMatrixSystem/>") - direct).cwiseAbs().maxCoeff(), 1e-5);
}

TEST(WarpPreconditioner, NeedsACorotationalForceFieldAndADirectSolver) {
  const std::string noFem = R"(<Node name="root" dt="0.01">
  <EulerImplicitSolver/>
  <PCGLinearSolver preconditioner="@warp"/>
  <WarpPreconditioner name="warp"/>
  <MechanicalObject position="0 0 0  1 0 0"/>
  <UniformMass totalMass="1"/>
</Node>)";
  try {
    auto scene = buildScene(io::parseSceneText(noFem, "warp.xml"));
    Simulation sim(*scene);
    FAIL() << "accepted a warp preconditioner without rotations";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("corotational force field"), std::string::npos) << e.what();
  }
  const std::string badSolver = beam(R"(<PCGLinearSolver preconditioner="@warp"/>
  <WarpPreconditioner name="warp" linearSolver="@cg"/>
  <CGLinearSolver name="cg"/>)");
  try {
    auto scene = buildScene(io::parseSceneText(badSolver, "warp.xml"));
    Simulation sim(*scene);
    FAIL() << "accepted a conjugate gradient as the factorised solver";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("linearSolver"), std::string::npos) << e.what();
  }
}

}  // namespace
