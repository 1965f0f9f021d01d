// EulerExplicitSolver and the consistent mass matrix (MeshMatrixMass without lumping), checked
// against closed forms: the element mass matrix rho V / 20 (1 + delta_ij), free fall (exact for
// any mass matrix: M a = M g gives a = g), the symplectic Euler map of a spring, and the order
// of RungeKutta4Solver.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/MechanicalSystem.h"
#include "engine/Roles.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

// A 3 x 2 x 2 grid split into tetrahedra, with `mass` and `solver` in its node.
std::string blockScene(const std::string& solver, const std::string& mass, const std::string& gravity = "0 0 -10") {
  return R"(<Node name="root" dt="0.01" gravity=")" + gravity + R"(">
  <Node name="body">
    )" + solver + R"(
    <RegularGridTopology name="grid" n="3 2 2" min="0 0 0" max="2 1 1"/>
    <TetrahedronSetTopologyContainer name="tets"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tets"/>
    <MechanicalObject name="dofs"/>
    )" + mass + R"(
  </Node>
</Node>)";
}

std::unique_ptr<Scene> build(const std::string& text) {
  auto scene = buildScene(io::parseSceneText(text, "mass.xml"));
  scene->init();
  return scene;
}

const MechanicalObject& dofs(const Scene& s) { return *s.all<MechanicalObject>().front(); }

}  // namespace

TEST(ConsistentMass, IsTheElementMatrixOfLinearTetrahedra) {
  // One tetrahedron of volume 1/6 and density 12: m = 2, M_ii = m / 10, M_ij = m / 20.
  auto scene = build(R"(<Node name="root">
    <MechanicalObject name="dofs" position="0 0 0  1 0 0  0 1 0  0 0 1"/>
    <TetrahedronSetTopologyContainer name="tets" tetrahedra="0 1 2 3"/>
    <MeshMatrixMass massDensity="12"/>
  </Node>)");
  const Mass* mass = scene->all<Mass>().front();
  ASSERT_TRUE(mass->consistent());
  for (int k = 0; k < 4; ++k) {
    Eigen::Matrix3Xd dx = Eigen::Matrix3Xd::Zero(3, 4), out = Eigen::Matrix3Xd::Zero(3, 4);
    dx(0, k) = 1.0;
    mass->addMdx(dx, out, 1.0);
    for (int i = 0; i < 4; ++i) {
      EXPECT_NEAR(out(0, i), i == k ? 0.2 : 0.1, 1e-15) << i << " " << k;
      EXPECT_EQ(out(1, i), 0.0);
    }
  }
  // Its rows sum to the lumped masses, a quarter of the element's mass.
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(mass->nodeMass()[i], 0.5, 1e-15);
  // lumping="true" is the diagonal of those sums.
  auto lumped = build(R"(<Node name="root">
    <MechanicalObject name="dofs" position="0 0 0  1 0 0  0 1 0  0 0 1"/>
    <TetrahedronSetTopologyContainer name="tets" tetrahedra="0 1 2 3"/>
    <MeshMatrixMass massDensity="12" lumping="true"/>
  </Node>)");
  EXPECT_FALSE(lumped->all<Mass>().front()->consistent());
}

TEST(ConsistentMass, FreeFallIsExactWithEveryIntegratorAndLinearSolver) {
  // Under gravity alone M a = M g, so a = g whatever M is. Symplectic Euler and the linearised
  // implicit Euler both give x_N = x_0 + h^2 g N (N + 1) / 2; forward Euler h^2 g N (N - 1) / 2.
  const double h = 0.01, g = -10;
  const int N = 20;
  const std::string mass = R"(<MeshMatrixMass totalMass="3" lumping="false"/>)";
  const std::vector<std::pair<std::string, double>> cases = {
      {R"(<EulerExplicitSolver/><CGLinearSolver iterations="200" tolerance="1e-14" threshold="1e-30"/>)", N * (N + 1) / 2.0},
      {R"(<EulerExplicitSolver symplectic="false"/><SparseLDLSolver/>)", N * (N - 1) / 2.0},
      {R"(<EulerExplicitSolver/><CGLinearSolver assembled="false" iterations="200" tolerance="1e-14" threshold="1e-30"/>)", N * (N + 1) / 2.0},
      {R"(<EulerImplicitSolver/><SparseLDLSolver/>)", N * (N + 1) / 2.0},
      {R"(<EulerImplicitSolver rayleighMass="0"/><CGLinearSolver iterations="200" tolerance="1e-14" threshold="1e-30"/>)", N * (N + 1) / 2.0},
  };
  for (const auto& [solver, steps] : cases) {
    auto scene = build(blockScene(solver, mass));
    Simulation sim(*scene);
    for (int i = 0; i < N; ++i) ASSERT_FALSE(sim.step()) << solver;
    const MechanicalObject& m = dofs(*scene);
    const Eigen::Matrix3Xd& x = m.x(sim.state());
    for (int i = 0; i < m.size(); ++i) {
      EXPECT_NEAR(x(2, i) - m.x0(2, i), h * h * g * steps, 1e-10) << solver << " node " << i;
      EXPECT_NEAR(x(0, i), m.x0(0, i), 1e-12) << solver;
    }
  }
}

TEST(ConsistentMass, ChangesTheDynamicsOfAnElasticBodyFromTheLumpedOne) {
  // Not a closed form: the two masses must give different motions of a clamped, vibrating block
  // (else the consistent matrix would not be in use), and the same total momentum change
  // (gravity acts on the lumped masses in both).
  auto run = [](const std::string& lumping) {
    auto scene = build(blockScene(R"(<EulerImplicitSolver/><SparseLDLSolver/>)",
                                  R"(<MeshMatrixMass totalMass="3" lumping=")" + lumping + R"("/>
    <TetrahedronFEMForceField youngModulus="500" poissonRatio="0.3" method="large"/>
    <FixedConstraint indices="0 3 6 9"/>)"));
    Simulation sim(*scene);
    for (int i = 0; i < 10; ++i) EXPECT_FALSE(sim.step());
    return Eigen::Matrix3Xd(dofs(*scene).x(sim.state()) - dofs(*scene).x0);
  };
  const Eigen::Matrix3Xd consistent = run("false"), lumped = run("true");
  EXPECT_GT((consistent - lumped).norm(), 1e-6 * lumped.norm());
  EXPECT_LT((consistent - lumped).norm(), 0.5 * lumped.norm());
}

TEST(EulerExplicit, SymplecticSpringFollowsItsExactMap) {
  // One node of mass m on a spring k: symplectic Euler is the linear map
  // v' = v - h (k/m) x, x' = x + h v', i.e. [x'; v'] = [[1 - h^2 w^2, h], [-h w^2, 1]] [x; v].
  const double m = 2, k = 50, h = 0.01;
  const int N = 500;
  auto scene = build(R"(<Node name="root" dt="0.01" gravity="0 0 0">
    <EulerExplicitSolver/>
    <MechanicalObject name="dofs" position="1 0 0" rest_position="0 0 0"/>
    <UniformMass totalMass="2"/>
    <RestShapeSpringsForceField stiffness="50"/>
  </Node>)");
  Simulation sim(*scene);
  for (int i = 0; i < N; ++i) ASSERT_FALSE(sim.step());
  const double w2 = k / m;
  Eigen::Matrix2d A;
  A << 1 - h * h * w2, h, -h * w2, 1;
  Eigen::Vector2d s(1, 0);
  for (int i = 0; i < N; ++i) s = A * s;
  EXPECT_NEAR(dofs(*scene).x(sim.state())(0, 0), s[0], 1e-12);
  EXPECT_NEAR(dofs(*scene).v(sim.state())(0, 0), s[1], 1e-12);
  // The scheme keeps a modified energy: the amplitude stays within h w of 1 (it would grow
  // without bound under forward Euler).
  EXPECT_LT(std::abs(s[0]), 1.0 + h * std::sqrt(w2));
}

// RungeKutta4Solver on a spring: x(t) = cos(w t) exactly; the scheme's error at a fixed time falls
// as h^4 (halving h divides it by about 16), and a consistent mass gives the same free fall as a
// lumped one (a = g exactly, so RK4 is exact for it).
TEST(RungeKutta4, SpringErrorFallsAsTheFourthPowerOfTheStep) {
  const double w = 5.0;  // sqrt(50 / 2)
  auto errorAt1s = [&](double h) {
    auto scene = build(R"(<Node name="root" dt=")" + std::to_string(h) + R"(" gravity="0 0 0">
      <RungeKutta4Solver/>
      <MechanicalObject name="dofs" position="1 0 0" rest_position="0 0 0"/>
      <UniformMass totalMass="2"/>
      <RestShapeSpringsForceField stiffness="50"/>
    </Node>)");
    Simulation sim(*scene);
    const int n = static_cast<int>(std::lround(1.0 / h));
    for (int i = 0; i < n; ++i) EXPECT_FALSE(sim.step());
    return std::hypot(dofs(*scene).x(sim.state())(0, 0) - std::cos(w), (dofs(*scene).v(sim.state())(0, 0) + w * std::sin(w)) / w);
  };
  const double coarse = errorAt1s(0.02), fine = errorAt1s(0.01);
  EXPECT_LT(coarse, 1e-5);
  EXPECT_NEAR(coarse / fine, 16.0, 1.5) << coarse << " " << fine;

  auto scene = build(blockScene("<RungeKutta4Solver/><SparseLDLSolver/>", "<MeshMatrixMass massDensity=\"3\"/>"));
  Simulation sim(*scene);
  const Eigen::Matrix3Xd x0 = dofs(*scene).x(sim.state());
  for (int i = 0; i < 10; ++i) ASSERT_FALSE(sim.step());
  for (int i = 0; i < x0.cols(); ++i) {
    EXPECT_NEAR(dofs(*scene).x(sim.state())(2, i) - x0(2, i), -0.5 * 10 * 0.1 * 0.1, 1e-10);
    EXPECT_NEAR(dofs(*scene).v(sim.state())(2, i), -1.0, 1e-10);
  }
}

// On a grid without tetrahedra, MeshMatrixMass and HexahedronFEMForceFieldAndMass use the exact
// mass matrix of trilinear elements: for a unit cube of density rho, M_ij = rho / 216 times
// 8, 4, 2 or 1 for the same node, an edge, a face diagonal or the body diagonal (the tensor
// product of the 1-D matrix h/6 [2 1; 1 2]); its rows sum to rho / 8, the lumped mass.
TEST(ConsistentMass, IsTheExactMatrixOfTrilinearHexahedra) {
  for (const char* mass : {R"(<MeshMatrixMass massDensity="27"/>)",
                           R"(<HexahedronFEMForceFieldAndMass density="27" youngModulus="100" poissonRatio="0.3"/>)"}) {
    auto scene = build(R"(<Node name="root" gravity="0 0 -10">
      <RegularGridTopology name="grid" n="2 2 2" min="0 0 0" max="1 1 1"/>
      <MechanicalObject name="dofs"/>
      )" + std::string(mass) + R"(
    </Node>)");
    const Mass* m = scene->all<Mass>().front();
    ASSERT_TRUE(m->consistent()) << mass;
    // Node 0 is (0,0,0); 1 (1,0,0) an edge away; 3 (1,1,0) a face diagonal; 7 (1,1,1) the body diagonal.
    Eigen::Matrix3Xd dx = Eigen::Matrix3Xd::Zero(3, 8), out = Eigen::Matrix3Xd::Zero(3, 8);
    dx(2, 0) = 1.0;
    m->addMdx(dx, out, 1.0);
    const double unit = 27.0 / 216.0;
    EXPECT_NEAR(out(2, 0), 8 * unit, 1e-14) << mass;
    EXPECT_NEAR(out(2, 1), 4 * unit, 1e-14) << mass;
    EXPECT_NEAR(out(2, 3), 2 * unit, 1e-14) << mass;
    EXPECT_NEAR(out(2, 7), 1 * unit, 1e-14) << mass;
    EXPECT_EQ(out(0, 1), 0.0);
    for (int i = 0; i < 8; ++i) EXPECT_NEAR(m->nodeMass()[i], 27.0 / 8, 1e-13) << mass;
  }
  // The body falls freely as a whole (M a = M g): its FEM exerts nothing on a rigid translation.
  auto scene = build(R"(<Node name="root" dt="0.01" gravity="0 0 -10">
    <EulerImplicitSolver/><SparseLDLSolver/>
    <RegularGridTopology name="grid" n="3 2 2" min="0 0 0" max="2 1 1"/>
    <MechanicalObject name="dofs"/>
    <HexahedronFEMForceFieldAndMass density="2" youngModulus="1000" poissonRatio="0.3"/>
  </Node>)");
  Simulation sim(*scene);
  const Eigen::Matrix3Xd x0 = dofs(*scene).x(sim.state());
  for (int i = 0; i < 10; ++i) ASSERT_FALSE(sim.step());
  const Eigen::Matrix3Xd d = dofs(*scene).x(sim.state()) - x0;
  EXPECT_LT((d.row(2).array() - d(2, 0)).abs().maxCoeff(), 1e-10);
  EXPECT_NEAR(d(2, 0), -0.01 * 10 * 55 * 0.01, 1e-10);  // implicit Euler: x_n = x_0 + h^2 g n (n + 1) / 2
}

// Directional projective constraints: with every node held along z (FixedPlaneProjectiveConstraint
// over a slab holding the body) or along x and z (PartialFixedProjectiveConstraint), a body under
// gravity keeps those coordinates exactly and falls freely along the rest (implicit Euler:
// x_n = x_0 + h^2 g n (n + 1) / 2; the FEM exerts nothing on a translation), with a direct solver
// (the constrained matrix P A P + I - P) and with conjugate gradients (projected products).
TEST(ProjectiveConstraints, HeldDirectionsStayAndTheRestFallsFreely) {
  const std::string fem = R"(<TetrahedronFEMForceField youngModulus="100" poissonRatio="0.3"/>)";
  for (const char* solver : {"<EulerImplicitSolver/><SparseLDLSolver/>",
                             R"(<EulerImplicitSolver/><CGLinearSolver iterations="200" tolerance="1e-14" threshold="1e-30"/>)"}) {
    for (const char* held : {R"(<FixedPlaneProjectiveConstraint direction="0 0 2" dmin="-1" dmax="2"/>)",
                             R"(<PartialFixedProjectiveConstraint fixAll="true" fixedDirections="1 0 1"/>)"}) {
      const bool plane = std::string(held).find("Plane") != std::string::npos;
      auto scene = build(blockScene(solver, std::string("<UniformMass totalMass=\"1\"/>") + fem + held, "1 2 -3"));
      Simulation sim(*scene);
      const Eigen::Matrix3Xd x0 = dofs(*scene).x(sim.state());
      for (int i = 0; i < 10; ++i) ASSERT_FALSE(sim.step());
      const Eigen::Matrix3Xd d = dofs(*scene).x(sim.state()) - x0;
      const double fall = 0.01 * 0.01 * 55;  // h^2 n (n + 1) / 2 for g = 1
      for (int i = 0; i < d.cols(); ++i) {
        EXPECT_EQ(d(2, i), 0.0) << solver << held;
        EXPECT_NEAR(d(1, i), 2 * fall, 1e-9) << solver << held;
        if (plane) EXPECT_NEAR(d(0, i), fall, 1e-9) << solver << held;
        else EXPECT_EQ(d(0, i), 0.0) << solver << held;
      }
    }
  }
}

// SVDLinearSolver solves the same step as the sparse Cholesky factorisation on a regular system
// (a cantilever of tetrahedra under gravity, 10 implicit steps).
TEST(SvdLinearSolver, MatchesTheDirectSolver) {
  auto beam = [](const std::string& solver) {
    return buildScene(io::parseSceneText(R"(<Node name="root" dt="0.01" gravity="0 -9.81 0">
  <EulerImplicitSolver/>)" + solver + R"(
  <RegularGridTopology name="grid" n="4 2 2" min="0 0 0" max="3 1 1"/>
  <TetrahedronSetTopologyContainer name="tets"/><Hexa2TetraTopologicalMapping input="@grid" output="@tets"/>
  <MechanicalObject name="dofs"/><UniformMass totalMass="2"/>
  <TetrahedronFEMForceField youngModulus="2000" poissonRatio="0.3" method="large"/>
  <BoxROI name="end" box="-0.1 -0.1 -0.1 0.1 1.1 1.1"/><FixedConstraint indices="@end.indices"/>
</Node>)", "svd.xml"));
  };
  auto run = [](Scene& s) {
    Simulation sim(s);
    for (int i = 0; i < 10; ++i) EXPECT_FALSE(sim.step());
    return Eigen::Matrix3Xd(s.all<MechanicalObject>().front()->x(sim.state()));
  };
  auto a = beam("<SparseLDLSolver/>"), b = beam("<SVDLinearSolver/>");
  const Eigen::Matrix3Xd xa = run(*a), xb = run(*b);
  const Eigen::Matrix3Xd x0 = a->all<MechanicalObject>().front()->x0;
  EXPECT_GT((xa - x0).norm(), 1e-4);  // it sagged
  EXPECT_LT((xa - xb).norm(), 1e-9 * (xa - x0).norm());
}
