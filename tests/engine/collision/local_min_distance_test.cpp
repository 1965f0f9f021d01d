// SOFA's LocalMinDistance between two surfaces, checked against contacts worked out by hand: a
// thin rigid probe's apex above a fixed cube's top face near its edge. The apex touches the face
// at its foot (triangle-point) and, where it sees the edge from inside the edge's cone, the edge
// at its nearest point too (line-point); a vertex behind a face touches nothing while the filter
// is on; with `filterIntersection="0"` SOFA keeps what the cones would drop.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "contact_helpers.h"

using namespace viscera;
using Eigen::Vector3d;

namespace {

// A fixed cube [-0.5, 0.5]^2 x [0, 1] (outward triangles) and a rigid probe: a thin tetrahedron
// whose apex, the body's origin, points down at `apex`, its base 0.5 above.
std::string scene(const Vector3d& apex, const std::string& filter) {
  std::string cube;
  for (int k = 0; k < 8; ++k)
    cube += std::string(k & 1 ? "0.5 " : "-0.5 ") + (k & 2 ? "0.5 " : "-0.5 ") + (k & 4 ? "1  " : "0  ");
  return R"(<Node name="root" dt="0.01" gravity="0 0 0">
  <FreeMotionAnimationLoop/>
  <GenericConstraintSolver/>
  <CollisionPipeline/>
  <LocalMinDistance alarmDistance="0.1" contactDistance="0.01" )" + filter + R"(/>
  <CollisionResponse response="FrictionContactConstraint"/>
  <Node name="cube">
    <MeshTopology position=")" + cube + R"(" triangles="0 2 1  1 2 3  4 5 6  5 7 6  0 1 4  1 5 4  2 6 3  3 6 7  0 4 2  2 4 6  1 3 5  3 7 5"/>
    <MechanicalObject/>
    <TriangleCollisionModel simulated="0" moving="0"/>
    <LineCollisionModel simulated="0" moving="0"/>
    <PointCollisionModel simulated="0" moving="0"/>
  </Node>
  <Node name="probe">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject template="Rigid3d" position=")" + std::to_string(apex.x()) + " " + std::to_string(apex.y()) + " " +
         std::to_string(apex.z()) + R"( 0 0 0 1"/>
    <UniformMass totalMass="1"/>
    <UncoupledConstraintCorrection/>
    <Node name="surface">
      <MeshTopology position="0 0 0  0.2 0 0.5  -0.1 0.17 0.5  -0.1 -0.17 0.5" triangles="1 2 3  0 2 1  0 3 2  0 1 3"/>
      <MechanicalObject/>
      <TriangleCollisionModel/>
      <LineCollisionModel/>
      <PointCollisionModel/>
      <RigidMapping/>
    </Node>
  </Node>
</Node>)";
}

// The cube's contacts of the first step, with the probe's apex at `apex`.
std::vector<Contact> cubeContacts(const Vector3d& apex, const std::string& filter = "") {
  auto run = contact_test::buildRun(scene(apex, filter), "local_min_distance.xml");
  State& st = run.sim->state();
  EXPECT_FALSE(run.sim->step().has_value());
  for (const SurfaceCollisionModel* s : run.sim->pipeline()->surfaces())
    if (s->active() && s->node().name() == "cube") return s->contacts(st);
  ADD_FAILURE() << "no active surface on the cube";
  return {};
}

}  // namespace

TEST(LocalMinDistance, AVertexOverAFaceTouchesItAtItsFoot) {
  const auto cs = cubeContacts(Vector3d(0.1, 0.2, 1.05));
  ASSERT_EQ(cs.size(), 1u);
  EXPECT_EQ(cs[0].feature, Feature::Face);
  EXPECT_LE((cs[0].n - Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_NEAR(cs[0].gap0, 0.05 - 0.01, 1e-12);
  EXPECT_LE((cs[0].p0 - Vector3d(0.1, 0.2, 1)).norm(), 1e-12);
}

TEST(LocalMinDistance, AVertexNearAnEdgeAlsoTouchesTheEdgeInsideItsCone) {
  // The edge x = 0.5, z = 1 between the top face (+z) and a side (+x): its cone reaches over the
  // top face by coneFactor (n1 + n2)/|n1 + n2| . t = 0.5 / sqrt(2): the direction from the edge to
  // the apex may lean over the face while t . d >= -0.354 |d|.
  const Vector3d near(0.49, 0, 1.05);  // d = (-0.01, 0, 0.05): -0.01 >= -0.018, inside
  auto cs = cubeContacts(near);
  ASSERT_EQ(cs.size(), 2u);
  const Contact* edge = cs[0].feature == Feature::Edge ? &cs[0] : &cs[1];
  const Contact* face = cs[0].feature == Feature::Face ? &cs[0] : &cs[1];
  ASSERT_EQ(edge->feature, Feature::Edge);
  ASSERT_EQ(face->feature, Feature::Face);
  const Vector3d d(-0.01, 0, 0.05);
  EXPECT_LE((edge->n - d.normalized()).norm(), 1e-12);
  EXPECT_NEAR(edge->gap0, d.norm() - 0.01, 1e-12);
  EXPECT_LE((face->n - Vector3d::UnitZ()).norm(), 1e-12);
  // Further over the face the edge sees the apex outside its cone: the face alone.
  cs = cubeContacts(Vector3d(0.47, 0, 1.05));  // d = (-0.03, 0, 0.05): -0.03 < -0.021
  ASSERT_EQ(cs.size(), 1u);
  EXPECT_EQ(cs[0].feature, Feature::Face);
  // Without the filter the edge contact stays.
  EXPECT_EQ(cubeContacts(Vector3d(0.47, 0, 1.05), R"(filterIntersection="0")").size(), 2u);
  // As it does with SOFA's filters handed to another component.
  EXPECT_EQ(cubeContacts(Vector3d(0.47, 0, 1.05), R"(useLMDFilters="1")").size(), 2u);
}

TEST(LocalMinDistance, AVertexBehindAFaceTouchesNothingWhileFiltered) {
  EXPECT_TRUE(cubeContacts(Vector3d(0.1, 0.2, 0.97)).empty());
  // Unfiltered, SOFA's test keeps it, its normal from the face to the vertex (into the cube).
  const auto cs = cubeContacts(Vector3d(0.1, 0.2, 0.97), R"(filterIntersection="0")");
  ASSERT_EQ(cs.size(), 1u);
  EXPECT_EQ(cs[0].feature, Feature::Face);
  EXPECT_LE((cs[0].n + Vector3d::UnitZ()).norm(), 1e-12);
}
