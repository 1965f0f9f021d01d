// SOFA's LocalMinDistance between two surfaces, checked against contacts worked out by hand: a
// fixed cube and a rigid probe above it. A vertex over a face touches it at its foot (triangle-
// point); near an edge it also touches the edge where it lies inside the edge's cone (line-point);
// an edge crossing an edge touches it between their closest points (line-line); a vertex whose
// faces lean away, or one behind a face, touches nothing while the filter is on, and with
// `filterIntersection="0"` SOFA keeps what the cones would drop. Every contact's mirror is on the
// other body. Two triangle models alone do not meet (SOFA has no triangle-triangle test), and the
// scene says so.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "contact_helpers.h"

using namespace viscera;
using Eigen::Vector3d;

namespace {

// A thin tetrahedron pointing down: its apex, the body's origin, under a base 0.5 above.
const char* kApexDown = R"(position="0 0 0  0.2 0 0.5  -0.1 0.17 0.5  -0.1 -0.17 0.5" triangles="1 2 3  0 2 1  0 3 2  0 1 3")";
// A wedge whose lowest edge, 0.6 long along x through the origin, is the body's bottom.
const char* kEdgeDown = R"(position="-0.3 0 0  0.3 0 0  0 0.1 0.5  0 -0.1 0.5" triangles="0 2 1  1 3 0  0 3 2  1 2 3")";

// A fixed cube [-0.5, 0.5]^2 x [0, 1] (outward triangles) and a rigid probe of the given shape
// (kApexDown) whose origin is at `apex`; `models`: the collision models on both.
std::string scene(const Vector3d& apex, const std::string& filter, const char* shape = kApexDown,
                  const std::string& models = "Triangle Line Point") {
  auto collision = [&](const std::string& extra) {
    std::string out;
    for (const char* m : {"Triangle", "Line", "Point"})
      if (models.find(m) != std::string::npos) out += std::string("<") + m + "CollisionModel " + extra + "/>";
    return out;
  };
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
    )" + collision(R"(simulated="0" moving="0")") + R"(
  </Node>
  <Node name="probe">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject template="Rigid3d" position=")" + std::to_string(apex.x()) + " " + std::to_string(apex.y()) + " " +
         std::to_string(apex.z()) + R"( 0 0 0 1"/>
    <UniformMass totalMass="1"/>
    <UncoupledConstraintCorrection/>
    <Node name="surface">
      <MeshTopology )" + shape + R"(/>
      <MechanicalObject/>
      )" + collision("") + R"(
      <RigidMapping/>
    </Node>
  </Node>
</Node>)";
}

// The contacts of the first step on the cube and on the probe, with the probe's origin at `apex`.
struct Found {
  std::vector<Contact> cube, probe;
  std::vector<std::string> notes;
};
Found detect(const Vector3d& apex, const std::string& filter = "", const char* shape = kApexDown,
             const std::string& models = "Triangle Line Point") {
  auto run = contact_test::buildRun(scene(apex, filter, shape, models), "local_min_distance.xml");
  State& st = run.sim->state();
  EXPECT_FALSE(run.sim->step().has_value());
  Found f;
  f.notes = run.scene->notes();
  for (const SurfaceCollisionModel* s : run.sim->pipeline()->surfaces())
    if (s->active()) (s->node().name() == "cube" ? f.cube : f.probe) = s->contacts(st);
  // Each contact's mirror is on the other body: the same gap, the opposite normal, pointing back.
  EXPECT_EQ(f.cube.size(), f.probe.size());
  for (size_t i = 0; i < f.cube.size(); ++i) {
    const Contact& c = f.cube[i];
    if (c.mirror < 0 || c.mirror >= static_cast<int>(f.probe.size())) {
      ADD_FAILURE() << "contact " << i << " has no mirror";
      continue;
    }
    const Contact& m = f.probe[c.mirror];
    EXPECT_EQ(m.mirror, static_cast<int>(i));
    EXPECT_EQ(m.gap0, c.gap0);
    EXPECT_EQ(m.n, Vector3d(-c.n));
  }
  return f;
}
std::vector<Contact> cubeContacts(const Vector3d& apex, const std::string& filter = "") { return detect(apex, filter).cube; }

}  // namespace

TEST(LocalMinDistance, AVertexOverAFaceTouchesItAtItsFoot) {
  const Found f = detect(Vector3d(0.1, 0.2, 1.05));
  ASSERT_EQ(f.cube.size(), 1u);
  const Contact& c = f.cube[0];
  EXPECT_EQ(c.feature, Feature::Face);
  EXPECT_LE((c.n - Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_NEAR(c.gap0, 0.05 - 0.01, 1e-12);
  EXPECT_LE((c.p0 - Vector3d(0.1, 0.2, 1)).norm(), 1e-12);
  ASSERT_EQ(f.probe.size(), 1u);
  EXPECT_EQ(f.probe[0].feature, Feature::Vertex);
  // A vertex lying on the face touches it along the face's normal (no direction between them).
  const Found on = detect(Vector3d(0.1, 0.2, 1.0));
  ASSERT_EQ(on.cube.size(), 1u);
  EXPECT_LE((on.cube[0].n - Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_NEAR(on.cube[0].gap0, -0.01, 1e-12);
}

TEST(LocalMinDistance, AnEdgeCrossingAnEdgeTouchesItBetweenTheirClosestPoints) {
  // The wedge's bottom edge, 0.05 above the cube's top edge x = 0.5 and square to it, meets it at
  // (0.5, 0, 1). Its end at x = 0.2 lies 0.05 over the top face but does not touch it: the mean of
  // its three faces' normals, (-0.99, 0, 0.14), leans away from the face below (SOFA's vertex test).
  const Found f = detect(Vector3d(0.5, 0, 1.05), "", kEdgeDown);
  ASSERT_EQ(f.cube.size(), 1u);
  const Contact& edge = f.cube[0];
  EXPECT_EQ(edge.feature, Feature::Edge);
  EXPECT_EQ(f.probe[edge.mirror].feature, Feature::Edge);
  EXPECT_LE((edge.n - Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_NEAR(edge.gap0, 0.04, 1e-12);
  EXPECT_LE((edge.p0 - Vector3d(0.5, 0, 1)).norm(), 1e-12);
  // Unfiltered, that end touches the face too.
  const Found all = detect(Vector3d(0.5, 0, 1.05), R"(filterIntersection="0")", kEdgeDown);
  int faces = 0;
  for (const Contact& c : all.cube) faces += c.feature == Feature::Face && (c.p0 - Vector3d(0.2, 0, 1)).norm() < 1e-12;
  EXPECT_EQ(faces, 1);
}

TEST(LocalMinDistance, SurfacesWithoutPointOrLineModelsDoNotMeetAndSaySo) {
  // SOFA's LocalMinDistance has no triangle-triangle test: two triangle models pass through.
  const Found f = detect(Vector3d(0.1, 0.2, 1.05), "", kApexDown, "Triangle");
  EXPECT_TRUE(f.cube.empty());
  bool said = false;
  for (const std::string& n : f.notes) said = said || n.find("LocalMinDistance tests nothing between") != std::string::npos;
  EXPECT_TRUE(said);
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
