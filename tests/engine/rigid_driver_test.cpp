// Rigid bodies (MechanicalObject template="Rigid3d") and their kinematic drivers:
// LinearMovementConstraint (key frames) and TrajectoryDriver (a timed pose CSV), checked step by
// step against poses and velocities computed here independently.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using viscera::test_support::TempDir;

namespace {

std::unique_ptr<Scene> build(const std::string& text, const std::string& file = "rigid_test.xml") {
  return buildScene(io::parseSceneText(text, file));
}

// The error message of building and initialising `text`, or "" if it succeeds.
std::string errorOf(const std::string& text) {
  try {
    auto s = build(text);
    s->init();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

RigidObject& body(Scene& s, const std::string& name = "tool") {
  for (RigidObject* r : s.all<RigidObject>())
    if (r->name() == name) return *r;
  throw std::out_of_range("no rigid body " + name);
}

Component& named(Scene& s, const std::string& name) {
  for (Component* c : s.all<Component>())
    if (c->name() == name) return *c;
  throw std::out_of_range("no component " + name);
}

std::vector<double> fieldOf(const Component& c, const std::string& f) {
  FieldValue v;
  EXPECT_TRUE(c.field(f, v)) << c.name() << "." << f;
  return v.values;
}

// Distance between two rotations as unit quaternions (q and -q are the same rotation).
double quatDistance(const Quaterniond& a, const Quaterniond& b) {
  return std::min((a.coeffs() - b.coeffs()).norm(), (a.coeffs() + b.coeffs()).norm());
}

Quaterniond axisAngle(double angle, const Vector3d& axis) { return Quaterniond(Eigen::AngleAxisd(angle, axis.normalized())); }

// The rotation vector v with to = exp(v) from (world frame), by the angle-axis of the relative
// rotation, shortest arc.
Vector3d rotationVectorBetween(const Quaterniond& from, const Quaterniond& to) {
  Eigen::AngleAxisd aa(to * from.conjugate());
  double angle = aa.angle();
  Vector3d axis = aa.axis();
  if (angle > M_PI) {
    angle = 2 * M_PI - angle;
    axis = -axis;
  }
  return angle * axis;
}

bool contains(const std::vector<std::string>& notes, const std::string& a, const std::string& b = "") {
  for (const auto& n : notes)
    if (n.find(a) != std::string::npos && n.find(b) != std::string::npos) return true;
  return false;
}

// ---------------------------------------------------------------------------------------------
// MechanicalObject template="Rigid3d"

std::string rigidScene(const std::string& moAttrs, const std::string& extra = "") {
  return R"(<Node name="root" gravity="0 0 -9.81" dt="0.01">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d" )" +
         moAttrs + R"(/>
)" + extra + R"(
  </Node>
</Node>
)";
}

TEST(RigidBody, PositionIsOneFrameWithNormalisedQuaternion) {
  auto s = build(rigidScene(R"(position="1 2 3  0 0 2 2")"));
  s->init();
  RigidObject& b = body(*s);
  EXPECT_EQ(b.start.p, Vector3d(1, 2, 3));
  const double h = std::sqrt(0.5);
  EXPECT_NEAR(b.start.q.x(), 0, 1e-15);
  EXPECT_NEAR(b.start.q.y(), 0, 1e-15);
  EXPECT_NEAR(b.start.q.z(), h, 1e-15);
  EXPECT_NEAR(b.start.q.w(), h, 1e-15);
  EXPECT_NEAR(b.start.q.norm(), 1, 1e-15);
  EXPECT_EQ(b.p0, b.start.p);
  EXPECT_EQ(b.q0.coeffs(), b.start.q.coeffs());
  EXPECT_EQ(b.start.v, Vector3d::Zero());
  EXPECT_EQ(b.start.w, Vector3d::Zero());
  // The "@tool.position" field: one frame, 7 numbers x y z qx qy qz qw.
  const auto pos = fieldOf(b, "position");
  ASSERT_EQ(pos.size(), 7u);
  const std::vector<double> expected = {1, 2, 3, 0, 0, h, h};
  for (int i = 0; i < 7; ++i) EXPECT_NEAR(pos[i], expected[i], 1e-15) << i;
  EXPECT_EQ(fieldOf(b, "rest_position").size(), 7u);
  EXPECT_EQ(fieldOf(b, "velocity").size(), 6u);
  // Default: the identity frame at the origin.
  auto d = build(rigidScene(""));
  d->init();
  EXPECT_EQ(body(*d).start.p, Vector3d::Zero());
  EXPECT_EQ(body(*d).start.q.coeffs(), Quaterniond::Identity().coeffs());
}

TEST(RigidBody, PositionLinkCarriesSevenValues) {
  // A second rigid body placed by a link to the first one's position field.
  const std::string text = R"(<Node name="root" dt="0.01">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d" position="4 5 6  1 0 0 1" velocity="1 2 3 4 5 6"/>
  </Node>
  <Node name="copy">
    <MechanicalObject name="twin" template="Rigid3d" position="@/root/instrument/tool.position"/>
  </Node>
</Node>
)";
  auto s = build(text);
  s->init();
  RigidObject& tool = body(*s, "tool");
  RigidObject& twin = body(*s, "twin");
  EXPECT_EQ(twin.start.p, tool.start.p);
  EXPECT_LE(quatDistance(twin.start.q, tool.start.q), 1e-15);
  EXPECT_LE(quatDistance(tool.start.q, axisAngle(M_PI / 2, Vector3d::UnitX())), 1e-15);
  EXPECT_EQ(tool.start.v, Vector3d(1, 2, 3));
  EXPECT_EQ(tool.start.w, Vector3d(4, 5, 6));
  EXPECT_EQ(fieldOf(tool, "position").size(), 7u);
}

TEST(RigidBody, PlacementRotatesThenTranslates) {
  auto s = build(rigidScene(R"(position="1 0 0  0 0 0 1" rotation="0 0 90" translation="10 0 0")"));
  s->init();
  RigidObject& b = body(*s);
  EXPECT_LE((b.start.p - Vector3d(10, 1, 0)).norm(), 1e-15);
  EXPECT_LE(quatDistance(b.start.q, axisAngle(M_PI / 2, Vector3d::UnitZ())), 1e-15);
}

TEST(RigidBody, WrongPositionCountIsAnErrorNamingTheAttribute) {
  for (const char* pos : {"1 2 3", "1 2 3 0 0 0", "1 2 3 0 0 0 1 0", "1 2 3 0 0 0 1  4 5 6 0 0 0 1"}) {
    SCOPED_TRACE(pos);
    const std::string e = errorOf(rigidScene(std::string("position=\"") + pos + "\""));
    EXPECT_NE(e.find("MechanicalObject.position"), std::string::npos) << e;
    EXPECT_NE(e.find("7 numbers"), std::string::npos) << e;
    EXPECT_NE(e.find("rigid_test.xml:3:"), std::string::npos) << e;  // where the attribute is
  }
  const std::string zero = errorOf(rigidScene(R"(position="1 2 3 0 0 0 0")"));
  EXPECT_NE(zero.find("MechanicalObject.position"), std::string::npos) << zero;
  EXPECT_NE(zero.find("zero"), std::string::npos) << zero;
  const std::string vel = errorOf(rigidScene(R"(velocity="1 2 3")"));
  EXPECT_NE(vel.find("MechanicalObject.velocity"), std::string::npos) << vel;
}

// A driven body's own mass and solver (a SOFA instrument node): the driver moves it, the solver idles.
TEST(RigidBody, MassAndSolverBesideADriverAreAcceptedAndIdle) {
  auto s = build(rigidScene(R"(position="1 2 3 0 0 0 1" velocity="0.5 0 0 0 0 0")",
                            R"(    <LinearMovementConstraint keyTimes="0 10" movements="0 0 0 0 0 0  0 0 0 0 0 0"/>
    <UniformMass name="mass" totalMass="0.25"/>
    <EulerImplicitSolver name="ode"/>
    <CGLinearSolver name="cg" iterations="10" tolerance="1e-9" threshold="1e-12"/>)"));
  Simulation sim(*s);
  RigidObject& b = body(*s);
  EXPECT_EQ(b.mass, 0.25);
  EXPECT_TRUE(contains(s->notes(), "EulerImplicitSolver 'ode'", "stays idle")) << [&] {
    std::string all;
    for (const auto& n : s->notes()) all += n + "\n";
    return all;
  }();
  EXPECT_TRUE(contains(s->notes(), "'tool'", "driven, not integrated"));
  // The body is not integrated: no gravity, and the driver holds it.
  for (int k = 0; k < 5; ++k) ASSERT_FALSE(sim.step().has_value());
  EXPECT_EQ(b.live(sim.state()).p, Vector3d(1, 2, 3));
  EXPECT_EQ(b.live(sim.state()).q.coeffs(), Quaterniond::Identity().coeffs());
  EXPECT_EQ(sim.lastLinearIterations(), 0);
}

// ---------------------------------------------------------------------------------------------
// LinearMovementConstraint

// Piecewise-linear key frames, held outside [t0, tn].
struct Keys {
  std::vector<double> t;
  std::vector<Vector3d> d, r;
  void at(double time, Vector3d& dd, Vector3d& rr) const {
    if (time <= t.front()) {
      dd = d.front();
      rr = r.front();
      return;
    }
    for (size_t k = 0; k + 1 < t.size(); ++k)
      if (time < t[k + 1]) {
        const double a = (time - t[k]) / (t[k + 1] - t[k]);
        dd = d[k] + a * (d[k + 1] - d[k]);
        rr = r[k] + a * (r[k + 1] - r[k]);
        return;
      }
    dd = d.back();
    rr = r.back();
  }
};

Quaterniond fromRotationVector(const Vector3d& r) {
  return r.norm() > 0 ? axisAngle(r.norm(), r) : Quaterniond::Identity();
}

std::string lmcScene(const std::string& lmcAttrs, double dt = 0.25) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", dt);
  return std::string(R"(<Node name="root" gravity="0 0 0" dt=")") + buf + R"(">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d" position="1 2 3  0.5 0 0 0.8660254037844386"/>
    <LinearMovementConstraint name="keys" )" +
         lmcAttrs + R"(/>
  </Node>
</Node>
)";
}

TEST(RigidLinearMovement, PosesAtAndBetweenKeysHeldOutside) {
  const Keys K{{0.5, 1.5, 2.5},
               {Vector3d(0, 0, 0), Vector3d(2, 0, -1), Vector3d(2, 4, -1)},
               {Vector3d(0, 0, 0), Vector3d(0, 0, 1.2), Vector3d(0.6, 0, 1.2)}};
  auto s = build(lmcScene(R"(keyTimes="0.5 1.5 2.5" movements="0 0 0 0 0 0   2 0 -1 0 0 1.2   2 4 -1 0.6 0 1.2")"));
  Simulation sim(*s);
  RigidObject& b = body(*s);
  const RigidObject::Live& live = b.live(sim.state());
  const Vector3d p0(1, 2, 3);
  const Quaterniond q0 = axisAngle(M_PI / 3, Vector3d::UnitX());  // (sin 30, 0, 0, cos 30)
  EXPECT_LE((live.p - p0).norm(), 0.0);
  EXPECT_LE(quatDistance(live.q, q0), 1e-15);
  EXPECT_EQ(b.p0, p0);
  const double dt = s->dt();
  for (int k = 1; k <= 14; ++k) {  // t = 0.25 .. 3.5: before, at and between keys, after
    ASSERT_FALSE(sim.step().has_value());
    const double t = k * dt;
    SCOPED_TRACE("t = " + std::to_string(t));
    Vector3d d, r, dPrev, rPrev;
    K.at(t, d, r);
    K.at(t - dt, dPrev, rPrev);
    EXPECT_LE((live.p - (p0 + d)).norm(), 1e-14);
    // The rotation vector turns the initial orientation (world frame: exp(r) q0).
    EXPECT_LE(quatDistance(live.q, fromRotationVector(r) * q0), 1e-14);
    EXPECT_LE((live.v - (d - dPrev) / dt).norm(), 1e-13);
    EXPECT_LE((live.w - (r - rPrev) / dt).norm(), 1e-13);
  }
  // Spot checks against hand values: at the key t = 1.5 and half way to the next one, and held.
  auto s2 = build(lmcScene(R"(keyTimes="0.5 1.5 2.5" movements="0 0 0 0 0 0   2 0 -1 0 0 1.2   2 4 -1 0.6 0 1.2")", 0.5));
  Simulation sim2(*s2);
  const RigidObject::Live& b2 = body(*s2).live(sim2.state());
  const std::vector<Vector3d> pos = {p0, p0 + Vector3d(1, 0, -0.5), p0 + Vector3d(2, 0, -1), p0 + Vector3d(2, 2, -1),
                                     p0 + Vector3d(2, 4, -1), p0 + Vector3d(2, 4, -1)};
  const std::vector<Vector3d> rot = {Vector3d::Zero(), Vector3d(0, 0, 0.6), Vector3d(0, 0, 1.2), Vector3d(0.3, 0, 1.2),
                                     Vector3d(0.6, 0, 1.2), Vector3d(0.6, 0, 1.2)};
  for (int k = 0; k < 6; ++k) {  // t = 0.5, 1.0, ..., 3.0
    ASSERT_FALSE(sim2.step().has_value());
    SCOPED_TRACE("t = " + std::to_string(sim2.time()));
    EXPECT_LE((b2.p - pos[k]).norm(), 1e-14);
    EXPECT_LE(quatDistance(b2.q, axisAngle(rot[k].norm(), rot[k].norm() > 0 ? rot[k] : Vector3d::UnitX()) * q0), 1e-14);
  }
  // Held after the last key: no velocity.
  EXPECT_EQ(b2.v, Vector3d::Zero());
  EXPECT_EQ(b2.w, Vector3d::Zero());
}

TEST(RigidLinearMovement, AbsoluteMovements) {
  auto s = build(lmcScene(R"(keyTimes="0 1" movements="5 0 0 0 0 0  5 2 0 0 1 0" relativeMovements="false")"));
  Simulation sim(*s);
  RigidObject& b = body(*s);
  const RigidObject::Live& live = b.live(sim.state());
  EXPECT_LE((live.p - Vector3d(5, 0, 0)).norm(), 1e-15);  // absolute: the initial pose is replaced
  EXPECT_LE(quatDistance(live.q, Quaterniond::Identity()), 1e-15);
  sim.step();
  sim.step();  // t = 0.5
  EXPECT_LE((live.p - Vector3d(5, 1, 0)).norm(), 1e-14);
  EXPECT_LE(quatDistance(live.q, axisAngle(0.5, Vector3d::UnitY())), 1e-14);
  EXPECT_LE((live.v - Vector3d(0, 2, 0)).norm(), 1e-13);
  EXPECT_LE((live.w - Vector3d(0, 1, 0)).norm(), 1e-13);
}

TEST(RigidLinearMovement, BadKeysAreErrorsNamingTheAttribute) {
  for (const char* times : {"0 1 1", "0 2 1", "1 0"}) {
    SCOPED_TRACE(times);
    std::string movements;
    for (char c : std::string(times))
      if (c != ' ') movements += "0 0 0 0 0 0 ";
    const std::string e = errorOf(lmcScene(std::string("keyTimes=\"") + times + "\" movements=\"" + movements + "\""));
    EXPECT_NE(e.find("LinearMovementConstraint.keyTimes"), std::string::npos) << e;
    EXPECT_NE(e.find("increase"), std::string::npos) << e;
  }
  for (const char* movements : {"0 0 0 0 0 0", "0 0 0 0 0 0  1 1 1 0 0 0  0", "0 0 0 0 0 0  1 1 1 0 0 0  2 2 2 0 0 0"}) {
    SCOPED_TRACE(movements);
    const std::string e = errorOf(lmcScene(std::string("keyTimes=\"0 1\" movements=\"") + movements + "\""));
    EXPECT_NE(e.find("LinearMovementConstraint.movements"), std::string::npos) << e;
    EXPECT_NE(e.find("6 numbers"), std::string::npos) << e;
  }
  const std::string idx = errorOf(lmcScene(R"(keyTimes="0 1" movements="0 0 0 0 0 0  1 1 1 0 0 0" indices="1")"));
  EXPECT_NE(idx.find("LinearMovementConstraint.indices"), std::string::npos) << idx;
  // Two drivers on one body.
  const std::string twice = errorOf(lmcScene(R"(keyTimes="0 1" movements="0 0 0 0 0 0  1 1 1 0 0 0"/>
    <LinearMovementConstraint name="again" keyTimes="0 1" movements="0 0 0 0 0 0  1 1 1 0 0 0")"));
  EXPECT_NE(twice.find("already has a driver"), std::string::npos) << twice;
}

// ---------------------------------------------------------------------------------------------
// TrajectoryDriver

struct Sample {
  double t;
  Vector3d p;
  Quaterniond q;
};

// Samples: a translation, a turn about z, a turn about a tilted axis while moving, and a last
// orientation written with the opposite sign (the same rotation: interpolation must take the
// shortest arc).
std::vector<Sample> samples() {
  const Quaterniond q1 = axisAngle(M_PI / 3, Vector3d::UnitZ());
  const Quaterniond q2 = axisAngle(M_PI / 2, Vector3d(1, 1, 0)) * q1;
  Quaterniond q3 = axisAngle(0.4, Vector3d(0, 1, 2)) * q2;
  q3.coeffs() *= -1;
  return {{0.0, Vector3d(0, 0, 0), Quaterniond::Identity()},
          {0.1, Vector3d(1, 0, 0), q1},
          {0.3, Vector3d(1, 2, 0), q2},
          {0.5, Vector3d(1, 2, -3), q3}};
}

std::string formatCsv(const std::vector<Sample>& S) {
  std::string out = "t,x,y,z,qx,qy,qz,qw\n";
  char buf[512];
  for (const auto& s : S) {
    std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", s.t, s.p.x(), s.p.y(), s.p.z(),
                  s.q.x(), s.q.y(), s.q.z(), s.q.w());
    out += buf;
  }
  return out;
}

// The interpolated pose at time t: linear position; orientation a * exp(s log(a^-1 b)) on the
// shortest arc (angle-axis of the relative rotation, independent of the engine's slerp formula).
void poseAt(const std::vector<Sample>& S, double t, Vector3d& p, Quaterniond& q) {
  if (t <= S.front().t) {
    p = S.front().p;
    q = S.front().q;
    return;
  }
  if (t >= S.back().t) {
    p = S.back().p;
    q = S.back().q;
    return;
  }
  size_t i = 0;
  while (t >= S[i + 1].t) ++i;
  const double s = (t - S[i].t) / (S[i + 1].t - S[i].t);
  p = S[i].p + s * (S[i + 1].p - S[i].p);
  Eigen::AngleAxisd rel(S[i].q.conjugate() * S[i + 1].q);
  double angle = rel.angle();
  Vector3d axis = rel.axis();
  if (angle > M_PI) {  // shortest arc
    angle = 2 * M_PI - angle;
    axis = -axis;
  }
  q = S[i].q * axisAngle(s * angle, axis);
}

struct DriverRun {
  TempDir dir{"viscera_rigid"};
  std::unique_ptr<Scene> scene;
  std::unique_ptr<Simulation> sim;
  RigidObject* b = nullptr;

  explicit DriverRun(const std::string& driverAttrs, double dt = 0.04, const std::string& time = "0") {
    {
      std::ofstream f(dir / "traj.csv");
      f << formatCsv(samples());
    }
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", dt);
    const std::string text = std::string(R"(<Node name="root" gravity="0 0 0" time=")") + time + R"(" dt=")" + buf + R"(">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d"/>
    <UniformMass totalMass="1"/>
    <TrajectoryDriver name="replay" filename="traj.csv" )" +
                             driverAttrs + R"(/>
    <SphereCollisionModel radius="0.5"/>
  </Node>
</Node>
)";
    scene = build(text, dir / "scene.xml");  // the CSV is found beside the scene
    sim = std::make_unique<Simulation>(*scene);
    b = &body(*scene);
  }
  const RigidObject::Live& live() const { return b->live(sim->state()); }
};

// Steps `steps` times and checks pose and mean velocity after each against the interpolation,
// mapped by x -> R x + T and read at scene time + offset.
void checkReplay(DriverRun& run, int steps, const Eigen::Matrix3d& R, const Vector3d& T, double offset) {
  const auto S = samples();
  const double dt = run.scene->dt(), t0 = run.scene->startTime();
  const Quaterniond Rq(R);
  {
    Vector3d p;
    Quaterniond q;
    poseAt(S, t0 + offset, p, q);
    EXPECT_LE((run.live().p - (R * p + T)).norm(), 1e-12);
    EXPECT_LE(quatDistance(run.live().q, Rq * q), 1e-12);
    EXPECT_EQ(run.b->p0, run.live().p);  // the initial pose is the trajectory's
  }
  for (int k = 1; k <= steps; ++k) {
    ASSERT_FALSE(run.sim->step().has_value());
    const double t = t0 + k * dt, tPrev = t0 + (k - 1) * dt;
    SCOPED_TRACE("step " + std::to_string(k) + ", t = " + std::to_string(t));
    Vector3d p, pPrev;
    Quaterniond q, qPrev;
    poseAt(S, t + offset, p, q);
    poseAt(S, tPrev + offset, pPrev, qPrev);
    EXPECT_LE((run.live().p - (R * p + T)).norm(), 1e-12);
    EXPECT_LE(quatDistance(run.live().q, Rq * q), 1e-12);
    EXPECT_NEAR(run.live().q.norm(), 1.0, 1e-15);
    // Mean velocity over the step: the step's displacement / dt (t_{k-1} is t_k - dt to rounding,
    // which moves the result by ~1e-16 / dt).
    EXPECT_LE((run.live().v - R * (p - pPrev) / dt).norm(), 1e-10);
    EXPECT_LE((run.live().w - R * rotationVectorBetween(qPrev, q) / dt).norm(), 1e-10);
  }
}

TEST(RigidTrajectoryDriver, ReplaysTheInterpolatedTrajectory) {
  DriverRun run("");
  // 16 steps of 0.04 s: inside every interval, across sample times, then held after t = 0.5.
  checkReplay(run, 16, Eigen::Matrix3d::Identity(), Vector3d::Zero(), 0.0);
  const auto S = samples();
  EXPECT_EQ(run.live().p, S.back().p);
  EXPECT_LE(quatDistance(run.live().q, S.back().q), 1e-15);
  EXPECT_EQ(run.live().v, Vector3d::Zero());
  EXPECT_LE(run.live().w.norm(), 1e-14);  // the rotation between two equal quaternions, to rounding
  EXPECT_EQ(fieldOf(named(*run.scene, "replay"), "duration"), std::vector<double>{0.5});
}

TEST(RigidTrajectoryDriver, StepsLandingOnSampleTimes) {
  DriverRun run("", 0.05);  // t = 0.1, 0.3 (to rounding), 0.5 are step ends
  checkReplay(run, 12, Eigen::Matrix3d::Identity(), Vector3d::Zero(), 0.0);
}

TEST(RigidTrajectoryDriver, RotationThenTranslationPlaceTheTrajectory) {
  DriverRun run(R"(rotation="90 0 90" translation="10 -5 2")");
  // About x by 90 degrees, then about z by 90: x -> y, y -> z, z -> x.
  Eigen::Matrix3d R;
  R << 0, 0, 1,
       1, 0, 0,
       0, 1, 0;
  checkReplay(run, 16, R, Vector3d(10, -5, 2), 0.0);
  EXPECT_LE((run.live().p - (R * Vector3d(1, 2, -3) + Vector3d(10, -5, 2))).norm(), 1e-12);
  EXPECT_LE((run.live().p - Vector3d(7, -4, 4)).norm(), 1e-12);
}

TEST(RigidTrajectoryDriver, TimeOffsetShiftsTheTrajectory) {
  {
    DriverRun run(R"(timeOffset="0.12")");
    checkReplay(run, 12, Eigen::Matrix3d::Identity(), Vector3d::Zero(), 0.12);
  }
  {
    // Negative offset: the first pose is held until scene time 0.1, then the replay starts.
    DriverRun run(R"(timeOffset="-0.1")");
    checkReplay(run, 18, Eigen::Matrix3d::Identity(), Vector3d::Zero(), -0.1);
  }
  {
    // A scene starting at t = 0.2 with offset 0.05: trajectory time 0.25 at the start.
    DriverRun run(R"(timeOffset="0.05")", 0.04, "0.2");
    checkReplay(run, 10, Eigen::Matrix3d::Identity(), Vector3d::Zero(), 0.05);
  }
}

TEST(RigidTrajectoryDriver, DurationAndMissingFile) {
  DriverRun run(R"(timeOffset="0.12")");
  const auto d = fieldOf(named(*run.scene, "replay"), "duration");
  ASSERT_EQ(d.size(), 1u);
  EXPECT_NEAR(d[0], 0.5 - 0.12, 1e-15);
  const std::string e = errorOf(R"(<Node name="root" dt="0.01">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d"/>
    <TrajectoryDriver filename="no_such_trajectory.csv"/>
  </Node>
</Node>
)");
  EXPECT_NE(e.find("TrajectoryDriver.filename"), std::string::npos) << e;
}

}  // namespace
