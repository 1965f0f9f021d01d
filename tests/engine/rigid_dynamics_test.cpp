// Integrated rigid bodies (a Rigid3d MechanicalObject with a UniformMass and an ODE solver, no
// driver) and RigidMapping, checked against closed forms: free fall (with the solver in the body's
// node or above several bodies), Rayleigh mass damping, a pendulum's period, the mapped points'
// positions and velocities; held components, .rigid files and the refusals.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <memory>
#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using Eigen::Vector3d;

namespace {

std::unique_ptr<Scene> build(const std::string& text, const std::string& file = "rigid_dynamics.xml") {
  auto s = buildScene(io::parseSceneText(text, file));
  s->init();
  return s;
}

std::string errorOf(const std::string& text, const std::string& file = "rigid_dynamics.xml") {
  try {
    build(text, file);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

RigidObject& body(Scene& s) { return *s.all<RigidObject>().front(); }

MechanicalObject& state(Scene& s, const std::string& name) {
  for (MechanicalObject* m : s.all<MechanicalObject>())
    if (m->name() == name) return *m;
  throw std::out_of_range(name);
}

// A free body at (1, 2, 3) turned 90 degrees about z, with a point mapped at (0.5, 0, 0) in its frame.
std::string fallingBody(const std::string& solver, const std::string& extra = "") {
  return R"(<Node name="root" dt="0.01" gravity="0 0 -9.81">
  <Node name="body">
    )" + solver + R"(
    <CGLinearSolver iterations="10"/>
    <MechanicalObject name="frame" template="Rigid3d" position="1 2 3 0 0 0.7071067811865476 0.7071067811865476"/>
    <UniformMass totalMass="2"/>
    )" + extra + R"(
    <Node name="tip">
      <MechanicalObject name="tipState" position="0.5 0 0"/>
      <RigidMapping/>
    </Node>
  </Node>
</Node>)";
}

}  // namespace

TEST(RigidDynamics, FreeFallIsSymplecticEulerExactly) {
  for (const std::string solver : {"<EulerImplicitSolver/>", "<EulerExplicitSolver/>"}) {
    auto scene = build(fallingBody(solver));
    Simulation sim(*scene);
    const int n = 50;
    const double h = 0.01, g = -9.81;
    for (int i = 0; i < n; ++i) ASSERT_FALSE(sim.step());
    const RigidObject::Live& b = body(*scene).live(sim.state());
    // v_n = n h g; p_n = p_0 + h^2 g n (n + 1) / 2 (velocity first, then position).
    EXPECT_NEAR(b.v.z(), n * h * g, 1e-12) << solver;
    EXPECT_NEAR(b.p.z(), 3 + h * h * g * n * (n + 1) / 2.0, 1e-12) << solver;
    EXPECT_NEAR(b.p.x(), 1, 1e-15);
    EXPECT_NEAR(b.w.norm(), 0, 1e-15);
    // The mapped point: the body's frame turned 90 degrees about z takes (0.5, 0, 0) to (0, 0.5, 0).
    const MechanicalObject& tip = state(*scene, "tipState");
    EXPECT_LT((tip.x(sim.state()).col(0) - (b.p + Vector3d(0, 0.5, 0))).norm(), 1e-12);
    EXPECT_LT((tip.v(sim.state()).col(0) - b.v).norm(), 1e-12);
  }
}

// SOFA's solver above several bodies: one EulerImplicitSolver in a parent node moves each rigid body
// below it as its own solver would; a massless Vec3d node beside them stays where it is (an
// obstacle), and a deformable body with a mass there falls with them (an explicit solver, which
// moves rigid bodies only, refuses it, named).
TEST(RigidDynamics, ASolverAboveMovesEveryRigidBodyBelowIt) {
  auto scene = build(R"(<Node name="root" dt="0.01" gravity="0 0 -9.81">
  <Node name="bodies">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10"/>
    <Node name="a"><MechanicalObject name="A" template="Rigid3d" position="0 0 3 0 0 0 1"/><UniformMass totalMass="1"/></Node>
    <Node name="group">
      <Node name="b"><MechanicalObject name="B" template="Rigid3d" position="5 0 1 0 0 0 1"/><UniformMass totalMass="7"/></Node>
    </Node>
    <Node name="floor"><MechanicalObject name="floorState" position="0 0 0  1 0 0  0 1 0"/></Node>
  </Node>
</Node>)");
  Simulation sim(*scene);
  const int n = 40;
  const double h = 0.01, g = -9.81;
  for (int i = 0; i < n; ++i) ASSERT_FALSE(sim.step());
  const auto bodies = scene->all<RigidObject>();
  ASSERT_EQ(bodies.size(), 2u);
  const double z0[2] = {3, 1};
  for (int k = 0; k < 2; ++k) {
    const RigidObject::Live& b = bodies[k]->live(sim.state());
    EXPECT_NEAR(b.v.z(), n * h * g, 1e-12) << bodies[k]->name();
    EXPECT_NEAR(b.p.z(), z0[k] + h * h * g * n * (n + 1) / 2.0, 1e-12) << bodies[k]->name();
  }
  EXPECT_EQ(state(*scene, "floorState").x(sim.state()).col(1), Vector3d(1, 0, 0));

  // A deformable body with a mass beside them: EulerImplicitSolver integrates it too (one system
  // of the deformable bodies below it); an explicit solver moves rigid bodies only and says so.
  const std::string mixed = R"(<Node name="root" dt="0.01" gravity="0 0 -9.81">
  <Node name="bodies">
    SOLVER
    <Node name="a"><MechanicalObject template="Rigid3d" position="0 0 3 0 0 0 1"/><UniformMass totalMass="1"/></Node>
    <Node name="soft"><MechanicalObject name="softState" position="0 0 0  1 0 0"/><UniformMass totalMass="1"/></Node>
  </Node>
</Node>)";
  auto with = [&](const std::string& solver) {
    std::string text = mixed;
    return text.replace(text.find("SOLVER"), 6, solver);
  };
  auto both = build(with("<EulerImplicitSolver/><CGLinearSolver iterations=\"10\"/>"));
  Simulation sim2(*both);
  for (int i = 0; i < n; ++i) ASSERT_FALSE(sim2.step());
  EXPECT_NEAR(both->all<RigidObject>().front()->live(sim2.state()).p.z(), 3 + h * h * g * n * (n + 1) / 2.0, 1e-12);
  for (int i = 0; i < 2; ++i)
    EXPECT_NEAR(state(*both, "softState").x(sim2.state())(2, i), h * h * g * n * (n + 1) / 2.0, 1e-9) << "node " << i;
  const std::string why = errorOf(with("<EulerExplicitSolver/>"));
  EXPECT_NE(why.find("'softState' (/root/bodies/soft) has a mass and no solver of its own"), std::string::npos) << why;
}

TEST(RigidDynamics, RayleighMassDampingFollowsTheLinearlyImplicitStep) {
  auto scene = build(fallingBody(R"(<EulerImplicitSolver rayleighMass="0.5"/>)"));
  Simulation sim(*scene);
  const double h = 0.01, g = -9.81, rM = 0.5;
  double v = 0, z = 3;
  for (int i = 0; i < 30; ++i) {
    ASSERT_FALSE(sim.step());
    // (1 + h rM) m dv = h (m g - rM m v)
    v += h * (g - rM * v) / (1 + h * rM);
    z += h * v;
  }
  const RigidObject::Live& b = body(*scene).live(sim.state());
  EXPECT_NEAR(b.v.z(), v, 1e-12);
  EXPECT_NEAR(b.p.z(), z, 1e-12);
}

// A body held at the origin, free to turn about z, with a constant force F (-y) on a mapped point
// at L along -y: a pendulum with I theta'' = -L F sin(theta), I = m (the default inertia, m times
// the identity). At small amplitude the period is 2 pi sqrt(I / (L F)).
TEST(RigidDynamics, PendulumPeriodFromAMappedForce) {
  const double m = 2, L = 0.5, F = 8, h = 1e-3;
  auto scene = build(R"(<Node name="root" dt="0.001" gravity="0 0 0">
  <Node name="pendulum">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject template="Rigid3d" position="0 0 0 0 0 0.04997916927067833 0.9987502603949663"/>
    <UniformMass totalMass="2"/>
    <PartialFixedProjectiveConstraint fixedDirections="1 1 1 1 1 0"/>
    <Node name="bob">
      <MechanicalObject name="bobState" position="0 -0.5 0"/>
      <ConstantForceField forces="0 -8 0"/>
      <RigidMapping/>
    </Node>
  </Node>
</Node>)");
  Simulation sim(*scene);
  const double expected = 2 * M_PI * std::sqrt(m / (L * F));  // 4.443 s
  // The initial angle is 0.1 rad; find the upward crossings of theta = 0 (w changes sign from -
  // to + at the far end: use theta's zero crossings with w < 0, one per period).
  std::vector<double> crossings;
  double prev = 0.1;
  for (int i = 0; i < 15000; ++i) {
    ASSERT_FALSE(sim.step());
    const RigidObject::Live& b = body(*scene).live(sim.state());
    const double theta = 2 * std::atan2(b.q.z(), b.q.w());
    if (prev > 0 && theta <= 0) crossings.push_back((i + 1) * h - h * theta / (theta - prev));
    prev = theta;
    ASSERT_NEAR(b.p.norm(), 0, 1e-15);
    ASSERT_NEAR(b.w.x(), 0, 1e-15);
  }
  ASSERT_GE(crossings.size(), 3u);
  const double period = (crossings.back() - crossings.front()) / (crossings.size() - 1);
  // Finite amplitude lengthens the period by theta0^2 / 16 (0.06 %); the step adds O(h^2).
  EXPECT_NEAR(period, expected * (1 + 0.01 / 16), 2e-3 * expected);
}

TEST(RigidDynamics, FixedConstraintHoldsTheBody) {
  auto scene = build(fallingBody("<EulerImplicitSolver/>", "<FixedConstraint/>"));
  Simulation sim(*scene);
  for (int i = 0; i < 10; ++i) ASSERT_FALSE(sim.step());
  EXPECT_EQ(body(*scene).live(sim.state()).p, Vector3d(1, 2, 3));
}

TEST(RigidDynamics, RigidFileGivesMassAndInertia) {
  test_support::TempDir dir;
  {
    std::ofstream f(dir / "shape.rigid");
    f << "Xsp 3.0\nmass 5\nvolm 8.7\ninrt 2 0 0 0 3 0 0 0 4\ncenter 0.01 0 0\n";
  }
  const std::string scene = R"(<Node name="root" dt="0.01" gravity="0 0 0">
  <Node name="body"><EulerImplicitSolver/><CGLinearSolver/>
    <MechanicalObject template="Rigid3d"/><UniformMass filename="shape.rigid"/></Node></Node>)";
  {
    std::ofstream f(dir / "scene.xml");
    f << scene;
  }
  auto s = buildScene(io::readScene(dir / "scene.xml"));
  s->init();
  EXPECT_DOUBLE_EQ(body(*s).mass, 5);
  EXPECT_DOUBLE_EQ(body(*s).inertia(2, 2), 20);  // mass x the per-unit-mass inertia
  {
    std::ofstream f(dir / "shape.rigid");
    f << "Xsp 3.0\nmass 5\nspin 1\n";
  }
  std::string why;
  try {
    buildScene(io::readScene(dir / "scene.xml"))->init();
  } catch (const Error& e) {
    why = e.what();
  }
  EXPECT_NE(why.find("shape.rigid:3"), std::string::npos) << why;
  EXPECT_NE(why.find("spin"), std::string::npos) << why;
}

TEST(RigidDynamics, RefusesWhatWouldBeIgnored) {
  // A force on a state mapped from a body that does not move under forces.
  EXPECT_NE(errorOf(R"(<Node name="root"><Node name="body"><EulerImplicitSolver/><CGLinearSolver/>
    <MechanicalObject template="Rigid3d"/>
    <Node name="p"><MechanicalObject position="1 0 0"/><ConstantForceField forces="0 1 0"/><RigidMapping/></Node>
  </Node></Node>)")
                .find("held (no mass)"),
            std::string::npos);
  EXPECT_NE(errorOf(fallingBody("<RungeKutta4Solver/>")).find("does not integrate rigid bodies"), std::string::npos);
  EXPECT_NE(errorOf(fallingBody("<EulerImplicitSolver/>", R"(<PartialFixedConstraint fixedDirections="1 0 1"/>)"))
                .find("six flags"),
            std::string::npos);
  EXPECT_NE(errorOf(R"(<Node name="root"><Node name="n"><MechanicalObject position="0 0 0"/>
    <Node name="c"><MechanicalObject position="1 0 0"/><RigidMapping/></Node></Node></Node>)")
                .find("Rigid3d"),
            std::string::npos);
}

// A body on rest-shape springs settles where they carry its loads: gravity sags it by m g / k,
// and a constant torque T about z (LinearForceField) turns it by T / k_a, exactly (the angular
// spring pulls along the rotation vector). Mass damping makes the settling quick.
TEST(RigidForces, RestShapeSpringsCarryGravityAndATorque) {
  auto s = build(R"(<Node name="root" dt="0.01" gravity="0 -9.81 0">
  <Node name="body">
    <EulerImplicitSolver rayleighMass="5"/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject template="Rigid3d" position="1 2 3 0 0 0 1"/>
    <UniformMass totalMass="2"/>
    <RestShapeSpringsForceField stiffness="100" angularStiffness="10"/>
    <LinearForceField times="0" forces="0 0 0 0 0 3"/>
  </Node>
</Node>)");
  Simulation sim(*s);
  for (int k = 0; k < 2000; ++k) ASSERT_FALSE(sim.step());
  const RigidObject::Live& b = body(*s).live(sim.state());
  EXPECT_LT((b.p - Eigen::Vector3d(1, 2 - 2 * 9.81 / 100, 3)).norm(), 1e-9);
  const Eigen::AngleAxisd turn(b.q);
  EXPECT_NEAR(turn.angle(), 0.3, 1e-9);
  EXPECT_LT((turn.axis() - Eigen::Vector3d::UnitZ()).norm(), 1e-9);
}

// The rest pose may be another body's; inactive directions are free: with y inactive the body
// falls freely along y while x and z are pulled to the other body's.
TEST(RigidForces, ExternalRestPoseAndActiveDirections) {
  auto s = build(R"(<Node name="root" dt="0.01" gravity="0 -1 0">
  <Node name="anchor"><MechanicalObject name="anchor" template="Rigid3d" position="0.5 0 -0.5 0 0 0 1"/></Node>
  <Node name="body">
    <EulerImplicitSolver rayleighMass="5"/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject name="frame" template="Rigid3d" position="0 0 0 0 0 0 1"/>
    <UniformMass totalMass="1"/>
    <RestShapeSpringsForceField stiffness="50" angularStiffness="5" external_rest_shape="@../anchor/anchor" activeDirections="1 0 1 1 1 1 1"/>
  </Node>
</Node>)");
  Simulation sim(*s);
  for (int k = 0; k < 1000; ++k) ASSERT_FALSE(sim.step());
  const RigidObject* frame = nullptr;
  for (RigidObject* r : s->all<RigidObject>())
    if (r->name() == "frame") frame = r;
  ASSERT_TRUE(frame);
  const RigidObject::Live& b = frame->live(sim.state());
  EXPECT_NEAR(b.p.x(), 0.5, 1e-9);
  EXPECT_NEAR(b.p.z(), -0.5, 1e-9);
  // Along y, mass damping gives the terminal velocity g / rM.
  EXPECT_NEAR(b.v.y(), -1.0 / 5, 1e-6);
  EXPECT_NE(errorOf(R"(<Node name="root"><Node name="b"><MechanicalObject template="Rigid3d" position="0 0 0 0 0 0 1"/>
    <UniformMass totalMass="1"/><RestShapeSpringsForceField stiffness="1" angularStiffness="1"/></Node></Node>)")
                .find("no ODE solver in the node of rigid body"),
            std::string::npos);
}

// LinearForceField interpolates its keys, scaled by `force`: none before the first key, the last
// after the last; the time is the step's start.
TEST(RigidForces, LinearForceFieldFollowsItsKeys) {
  auto s = build(R"(<Node name="root" dt="0.5" gravity="0 0 0">
    <MechanicalObject position="0 0 0  1 0 0"/>
    <LinearForceField points="1" times="1 2 4" forces="2 0 0  4 0 0  0 0 6" force="0.5"/>
  </Node>)");
  ForceField& ff = *s->all<ForceField>().front();
  const MechanicalObject& mo = state(*s, "MechanicalObject");
  State st;
  for (const auto& [t, expected] : std::vector<std::pair<double, Eigen::Vector3d>>{
           {0.5, Eigen::Vector3d::Zero()}, {1.0, Eigen::Vector3d(1, 0, 0)}, {1.5, Eigen::Vector3d(1.5, 0, 0)},
           {3.0, Eigen::Vector3d(1, 0, 1.5)}, {9.0, Eigen::Vector3d(0, 0, 3)}}) {
    st.time = t;
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, 2);
    ff.addForce(st, mo.x0, mo.x0, f);
    EXPECT_LT((f.col(1) - expected).norm(), 1e-12) << "t = " << t;
    EXPECT_EQ(f.col(0), Eigen::Vector3d::Zero());
  }
}
