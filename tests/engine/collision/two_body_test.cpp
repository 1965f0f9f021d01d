// Penalty contact between the surfaces of two bodies: a rigid cube resting on a fixed plate comes
// to rest where its four bottom corners carry its weight, each with SOFA's stiffness
// k1 k2 / contactDistance; a deformable cube does the same on its own nodes. Under the constraint
// response the rigid cube rests exactly at the contact distance, and Coulomb friction holds it on
// an incline or lets it slide at the closed-form rate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

// A plate (two triangles at z = 0, fixed: no solver) under a pipeline with the given response.
std::string world(const std::string& response, const std::string& body) {
  return R"(<Node name="root" dt="0.01" gravity="0 0 -10">
  <CollisionPipeline/>
  <MinProximityIntersection alarmDistance="0.05" contactDistance="0.01"/>
  <CollisionResponse response=")" + response + R"("/>
  <Node name="plate">
    <MeshTopology position="-2 -2 0  2 -2 0  2 2 0  -2 2 0" triangles="0 1 2  0 2 3"/>
    <MechanicalObject/>
    <TriangleCollisionModel simulated="0" moving="0"/>
  </Node>
)" + body + "</Node>";
}

// A unit cube's surface, outward triangles, its lowest face at z = z0.
std::string cubeSurface(double z0) {
  std::string p;
  for (int k = 0; k < 8; ++k)
    p += std::to_string(k & 1 ? 0.5 : -0.5) + " " + std::to_string(k & 2 ? 0.5 : -0.5) + " " +
         std::to_string(z0 + (k & 4 ? 1.0 : 0.0)) + "  ";
  return R"(<MeshTopology position=")" + p + R"(" triangles="0 2 1  1 2 3  4 5 6  5 7 6  0 1 4  1 5 4  2 6 3  3 6 7  0 4 2  2 4 6  1 3 5  3 7 5"/>)";
}

// A rigid unit cube of mass 1, its frame at its centre (z = 0.52), its surface in the body's frame.
std::string rigidCube() {
  return R"(
  <Node name="cube">
    <EulerImplicitSolver rayleighMass="8"/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject template="Rigid3d" position="0 0 0.52 0 0 0 1"/>
    <UniformMass totalMass="1"/>
    <Node name="surface">
      )" + cubeSurface(-0.5) + R"(
      <MechanicalObject/>
      <TriangleCollisionModel/>
      <RigidMapping/>
    </Node>
  </Node>
)";
}

}  // namespace

TEST(TwoBodyContact, ARigidCubeRestsWhereItsCornersCarryItsWeight) {
  auto scene = buildScene(io::parseSceneText(world("PenaltyContactForceField", rigidCube()), "two_body.xml"));
  Simulation sim(*scene);
  for (int i = 0; i < 1500; ++i) ASSERT_FALSE(sim.step()) << "step " << i;
  const RigidObject::Live& b = scene->all<RigidObject>().front()->live(sim.state());
  // Four corners, k = 10 x 10 / 0.01 each: the bottom sinks m g / (4 k) into the contact distance.
  const double k = 10.0 * 10.0 / 0.01, sink = 1.0 * 10.0 / (4 * k);
  EXPECT_NEAR(b.p.z() - 0.5, 0.01 - sink, 1e-6);
  EXPECT_NEAR(b.v.norm(), 0, 1e-6);
  EXPECT_NEAR(b.w.norm(), 0, 1e-6);
}

// The cube's 8 nodes as a deformable body held together by springs (a MeshSpringForceField on
// its hexahedron); its weight is shared by the 4 bottom nodes. The plate is fixed (no solver) or
// a rigid body nothing moves (no mass, no solver): an obstacle either way, so the contact is in
// the cube's implicit step. Held from the step start instead, as between two integrated bodies,
// it would not settle: k h^2 / m = 1e5 x 1e-4 / 0.25 = 40 per bottom node.
class DeformableCubeOnAnObstacle : public ::testing::TestWithParam<bool> {};

TEST_P(DeformableCubeOnAnObstacle, RestsOnItsNodes) {
  std::string text = world("PenaltyContactForceField", R"(
  <Node name="cube">
    <EulerImplicitSolver rayleighMass="8"/>
    <CGLinearSolver iterations="50" tolerance="1e-12" threshold="1e-20"/>
    <RegularGridTopology name="grid" n="2 2 2" min="-0.5 -0.5 0.02" max="0.5 0.5 1.02"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="2"/>
    <MeshSpringForceField stiffness="1e5"/>
    <TriangleCollisionModel contactStiffness="100"/>
  </Node>
)");
  if (GetParam()) {  // the plate as a massless rigid body, its surface mapped
    const std::string fixed = R"(<MeshTopology position="-2 -2 0  2 -2 0  2 2 0  -2 2 0" triangles="0 1 2  0 2 3"/>
    <MechanicalObject/>
    <TriangleCollisionModel simulated="0" moving="0"/>)";
    const std::string rigid = R"(<MechanicalObject template="Rigid3d" position="0 0 0 0 0 0 1"/>
    <Node name="plateSurface"><MeshTopology position="-2 -2 0  2 -2 0  2 2 0  -2 2 0" triangles="0 1 2  0 2 3"/>
      <MechanicalObject/><TriangleCollisionModel/><RigidMapping/></Node>)";
    ASSERT_NE(text.find(fixed), std::string::npos);
    text.replace(text.find(fixed), fixed.size(), rigid);
  }
  auto scene = buildScene(io::parseSceneText(text, "two_body.xml"));
  Simulation sim(*scene);
  for (int i = 0; i < 1500; ++i) ASSERT_FALSE(sim.step()) << "step " << i;
  MechanicalObject* cube = nullptr;
  for (MechanicalObject* m : scene->all<MechanicalObject>())
    if (m->name() == "dofs") cube = m;
  ASSERT_TRUE(cube);
  const Eigen::Matrix3Xd& x = cube->x(sim.state());
  // Each bottom node carries m g / 4 = 5 with k = 100 x 10 / 0.01 = 1e5: it sits 5e-5 inside the
  // contact distance.
  for (int i = 0; i < 8; ++i)
    if (x(2, i) < 0.5) EXPECT_NEAR(x(2, i), 0.01 - 2.0 * 10.0 / (4 * 1e5), 2e-7) << "node " << i;
}

INSTANTIATE_TEST_SUITE_P(TwoBodyContact, DeformableCubeOnAnObstacle, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "MasslessRigidPlate" : "FixedPlate"; });

// The constraint response: the same cube, with its compliance (UncoupledConstraintCorrection), comes
// to rest with its bottom exactly at the contact distance (no sink: the gap is a constraint). So it
// does under SOFA's symplectic EulerExplicitSolver, whose step moves the body by h^2 M^-1 F under a
// force F added over it, rigid or deformable. The forward (non-symplectic) step moves positions with the old velocity,
// which no correction within the step can reach; a rigid body takes the symplectic step only.
static std::string constrainedCube(const std::string& solver) {
  std::string cube = rigidCube();
  cube.replace(cube.find("<UniformMass"), 0, "<UncoupledConstraintCorrection/>");
  const std::string implicit = R"(<EulerImplicitSolver rayleighMass="8"/>)";
  if (!solver.empty()) cube.replace(cube.find(implicit), implicit.size(), solver);
  return world("FrictionContactConstraint", "<FreeMotionAnimationLoop/><GenericConstraintSolver tolerance=\"1e-12\"/>" + cube);
}

TEST(TwoBodyContact, UnderTheConstraintResponseARigidCubeRestsAtTheContactDistance) {
  for (const std::string solver : {"", R"(<EulerExplicitSolver symplectic="true"/>)"}) {
    auto scene = buildScene(io::parseSceneText(constrainedCube(solver), "two_body.xml"));
    Simulation sim(*scene);
    for (int i = 0; i < 300; ++i) ASSERT_FALSE(sim.step()) << "step " << i << " " << solver;
    const RigidObject::Live& b = scene->all<RigidObject>().front()->live(sim.state());
    EXPECT_NEAR(b.p.z() - 0.5, 0.01, 1e-9) << solver;
    EXPECT_NEAR(b.v.norm(), 0, 1e-9) << solver;
    EXPECT_NEAR(b.w.norm(), 0, 1e-9) << solver;
    EXPECT_NEAR(b.p.x(), 0, 1e-12) << solver;
  }
  // A deformable cube (8 nodes, springs) under the symplectic explicit step: its bottom nodes
  // rest exactly at the contact distance (UncoupledConstraintCorrection: the nodes' masses).
  auto springs = buildScene(io::parseSceneText(world("FrictionContactConstraint", R"(
  <FreeMotionAnimationLoop/><GenericConstraintSolver tolerance="1e-12"/>
  <Node name="cube">
    <EulerExplicitSolver/>
    <RegularGridTopology n="2 2 2" min="-0.5 -0.5 0.02" max="0.5 0.5 1.02"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="2"/>
    <MeshSpringForceField stiffness="1e3" damping="5"/>
    <TriangleCollisionModel/>
    <UncoupledConstraintCorrection/>
  </Node>
)"), "two_body.xml"));
  Simulation sim(*springs);
  for (int i = 0; i < 3000; ++i) ASSERT_FALSE(sim.step()) << "step " << i;
  for (MechanicalObject* m : springs->all<MechanicalObject>())
    if (m->name() == "dofs")
      for (int i = 0; i < 4; ++i) EXPECT_NEAR(m->x(sim.state())(2, i), 0.01, 1e-9) << "node " << i;
  try {
    auto scene = buildScene(io::parseSceneText(constrainedCube(R"(<EulerExplicitSolver symplectic="false"/>)"), "two_body.xml"));
    Simulation sim(*scene);
    sim.step();
    ADD_FAILURE() << "the forward explicit step was accepted under constraints";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("symplectic"), std::string::npos) << e.what();
  }
}

// Coulomb friction between two bodies: gravity tilted by theta from the plate's normal. Below the
// friction angle (tan theta < mu) the cube stays where it is; above, it slides with
// a = g (sin theta - mu cos theta), which the step takes exactly: x_n = h^2 a n (n + 1) / 2.
// SOFA's LCPConstraintSolver applies its own mu, 0.6 unless given, in place of the response's 0.3:
// at 30 degrees (tan = 0.577) it holds the cube the response's mu would let slide.
TEST(TwoBodyContact, FrictionHoldsBelowTheFrictionAngleAndSlidesAtTheCoulombRateAbove) {
  const double g = 10, h = 0.01;
  const int n = 100;
  struct Case {
    std::string solver;
    double mu;
    std::vector<double> degrees;  // one below the friction angle, one above (the slide stays on the plate)
  };
  for (const Case& c : {Case{"GenericConstraintSolver", 0.3, {10.0, 30.0}}, Case{"LCPConstraintSolver", 0.6, {30.0, 40.0}}})
    for (const double degrees : c.degrees) {
      const std::string& solver = c.solver;
      const double mu = c.mu;
      const double th = degrees * M_PI / 180;
      std::string cube = rigidCube();
      cube.replace(cube.find("<UniformMass"), 0, "<UncoupledConstraintCorrection/>");
      cube.replace(cube.find("rayleighMass=\"8\""), std::string("rayleighMass=\"8\"").size(), "");
      cube.replace(cube.find("0 0 0.52 0 0 0 1"), std::string("0 0 0.52 0 0 0 1").size(), "0 0 0.51 0 0 0 1");
      std::string text = world("FrictionContactConstraint", "<FreeMotionAnimationLoop/><" + solver + " tolerance=\"1e-12\"/>" + cube);
      text.replace(text.find("gravity=\"0 0 -10\""), std::string("gravity=\"0 0 -10\"").size(),
                   "gravity=\"" + std::to_string(g * std::sin(th)) + " 0 " + std::to_string(-g * std::cos(th)) + "\"");
      text.replace(text.find("response=\"FrictionContactConstraint\""), std::string("response=\"FrictionContactConstraint\"").size(),
                   "response=\"FrictionContactConstraint\" responseParams=\"mu=0.3\"");
      auto scene = buildScene(io::parseSceneText(text, "two_body.xml"));
      Simulation sim(*scene);
      for (int i = 0; i < n; ++i) ASSERT_FALSE(sim.step()) << "step " << i;
      const RigidObject::Live& b = scene->all<RigidObject>().front()->live(sim.state());
      // std::to_string rounds the gravity to 6 decimals: take the components as written.
      const double gx = std::stod(std::to_string(g * std::sin(th))), gz = -std::stod(std::to_string(g * std::cos(th)));
      const double a = std::max(0.0, gx + mu * gz);
      EXPECT_NEAR(b.p.x(), h * h * a * n * (n + 1) / 2.0, 1e-7) << solver << ", " << degrees << " degrees";
      EXPECT_NEAR(b.v.x(), n * h * a, 1e-7) << solver << ", " << degrees << " degrees";
      EXPECT_NEAR(b.p.z(), 0.51, 1e-9) << solver << ", " << degrees << " degrees";
      EXPECT_LT(b.w.norm(), 1e-7) << solver << ", " << degrees << " degrees";
    }
}

// Edge against edge: a rigid wedge, its lower ridge along y, falls onto a fixed roof whose ridge
// runs along x. The ridges cross between their vertices, so only an edge-edge contact (both
// bodies with a LineCollisionModel, as SOFA's line-line proximities) can hold the wedge: it comes
// to rest balanced on the crossing with its ridge exactly the contact distance above the roof's.
// Without the line models it falls through.
TEST(TwoBodyContact, CrossingEdgesMeetEdgeToEdge) {
  const std::string roofTris = "0 3 1  0 2 3  0 1 5  0 5 4  2 5 3  2 4 5  0 4 2  1 3 5";
  auto sceneText = [&](bool lines) {
    const std::string models = std::string("<TriangleCollisionModel/>") + (lines ? "<LineCollisionModel/>" : "");
    return R"(<Node name="root" dt="0.01" gravity="0 0 -10">
  <CollisionPipeline/>
  <MinProximityIntersection alarmDistance="0.05" contactDistance="0.01"/>
  <CollisionResponse response="FrictionContactConstraint" responseParams="mu=0"/>
  <FreeMotionAnimationLoop/><GenericConstraintSolver tolerance="1e-12"/>
  <Node name="roof">
    <MeshTopology position="-2 0 0  2 0 0  -2 -1 -1  2 -1 -1  -2 1 -1  2 1 -1" triangles=")" + roofTris + R"("/>
    <MechanicalObject/>
    )" + models + R"(
  </Node>
  <Node name="wedge">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject template="Rigid3d" position="0 0 0.03 0 0 0 1"/>
    <UniformMass totalMass="1"/>
    <UncoupledConstraintCorrection/>
    <Node name="surface">
      <MeshTopology position="0 -2 0  0 2 0  -1 -2 1  -1 2 1  1 -2 1  1 2 1" triangles=")" + roofTris + R"("/>
      <MechanicalObject/>
      )" + models + R"(
      <RigidMapping/>
    </Node>
  </Node>
</Node>)";
  };
  for (const bool lines : {true, false}) {
    auto scene = buildScene(io::parseSceneText(sceneText(lines), "edges.xml"));
    Simulation sim(*scene);
    for (int i = 0; i < 50; ++i) ASSERT_FALSE(sim.step()) << "step " << i;
    const RigidObject::Live& b = scene->all<RigidObject>().front()->live(sim.state());
    if (lines) {
      EXPECT_NEAR(b.p.z(), 0.01, 1e-9);
      EXPECT_NEAR(b.v.norm(), 0, 1e-9);
      EXPECT_LT(b.w.norm(), 1e-9);
    } else {
      EXPECT_LT(b.p.z(), -0.05);  // nothing held it
    }
  }
}

// SOFA's friction defaults: FrictionContact has mu = 0.8 unless told otherwise, the unilateral
// contact none (and refuses one).
TEST(TwoBodyContact, TheConstraintResponsesFrictionDefaultsAreSofas) {
  auto muOf = [](const std::string& response) {
    auto scene = buildScene(io::parseSceneText(
        world(response, "<FreeMotionAnimationLoop/><GenericConstraintSolver/>" + rigidCube()), "two_body.xml"));
    scene->init();
    return scene->all<CollisionPipeline>().front()->settings().mu;
  };
  EXPECT_EQ(muOf("FrictionContactConstraint"), 0.8);
  EXPECT_EQ(muOf("FrictionContactConstraint\" responseParams=\"mu=0.25"), 0.25);
  EXPECT_EQ(muOf("UnilateralContactConstraint"), 0.0);
  std::string why;
  try {
    muOf("UnilateralContactConstraint\" responseParams=\"mu=0.3");
  } catch (const Error& e) {
    why = e.what();
  }
  EXPECT_NE(why.find("CollisionResponse.responseParams: UnilateralContactConstraint has no friction"), std::string::npos) << why;
}

// SOFA's RuleBasedContactManager picks a response per pair of models; one response serves every
// contact here, so rules naming another are refused, and a rules text that is no list of
// triplets applies no rule (the default response, as in SOFA), with a note.
TEST(TwoBodyContact, ContactRulesMustNameTheOneResponse) {
  auto build = [](const std::string& rules) {
    std::string text = world("FrictionContactConstraint\" rules=\"" + rules, "<FreeMotionAnimationLoop/><GenericConstraintSolver/>" + rigidCube());
    auto scene = buildScene(io::parseSceneText(text, "two_body.xml"));
    scene->init();
    return scene;
  };
  EXPECT_EQ(build("1 * FrictionContactConstraint  * * FrictionContactConstraint")->all<CollisionPipeline>().front()->settings().mu, 0.8);
  auto fallback = build("default");
  const auto& notes = fallback->notes();
  EXPECT_TRUE(std::any_of(notes.begin(), notes.end(), [](const std::string& n) { return n.find("no rule applies") != std::string::npos; }));
  std::string why;
  try {
    build("1 2 PenalityContactForceField");
  } catch (const Error& e) {
    why = e.what();
  }
  EXPECT_NE(why.find("rules: the rule '1 2 PenalityContactForceField' asks for PenalityContactForceField"), std::string::npos) << why;
}

// An instrument with a sphere and a surface of its own (SOFA's instrument node with a collision
// child): the sphere sits inside its own surface, which is no contact.
TEST(TwoBodyContact, AnInstrumentsSphereIsNotInContactWithItsOwnSurface) {
  auto scene = buildScene(io::parseSceneText(world("PenaltyContactForceField", R"(
  <Node name="tool">
    <MechanicalObject template="Rigid3d" position="0 0 1.5 0 0 0 1"/>
    <LinearMovementConstraint keyTimes="0 1" movements="0 0 0 0 0 0  0 0 0.1 0 0 0"/>
    <SphereCollisionModel radius="0.2"/>
    <Node name="surface">)" + cubeSurface(-0.5) + R"(<MechanicalObject/><TriangleCollisionModel/><RigidMapping/></Node>
  </Node>
)"), "two_body.xml"));
  Simulation sim(*scene);
  for (int i = 0; i < 5; ++i) ASSERT_FALSE(sim.step()) << "step " << i;
}

// Two bodies' surfaces under the penalty response need a contact distance: the stiffness is
// k1 k2 / contactDistance.
TEST(TwoBodyContact, AZeroContactDistanceIsRefused) {
  std::string text = world("PenaltyContactForceField", rigidCube());
  text.replace(text.find("contactDistance=\"0.01\""), std::string("contactDistance=\"0.01\"").size(), "contactDistance=\"0\"");
  std::string why;
  try {
    buildScene(io::parseSceneText(text, "two_body.xml"))->init();
  } catch (const Error& e) {
    why = e.what();
  }
  EXPECT_NE(why.find("contactDistance above 0"), std::string::npos) << why;
}
