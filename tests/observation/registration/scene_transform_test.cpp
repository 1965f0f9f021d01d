// Scenes reference registration transforms: TrajectoryDriver.transform maps each recorded robot
// pose into the scene (x_scene = R_rot (R_file x + t_file) + t) before `rotation` and
// `translation`; errors in the file name it, the scene line and the attribute.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "observation/Registration.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "io/scene/Transform.h"
#include "tests/observation/registration/phantom.h"
#include "tests/support/TempDir.h"

using namespace registration_test;
using viscera::RigidObject;
using viscera::RigidTransform;
using viscera::test_support::TempDir;

namespace {

// A robot trajectory touching the given points one after the other (a sample each 0.1 s, tool
// orientation `q` throughout).
std::string touchTrajectory(const Eigen::Matrix3Xd& p, const Eigen::Quaterniond& q) {
  std::string csv = "t,x,y,z,qx,qy,qz,qw\n";
  char buf[512];
  for (Eigen::Index i = 0; i < p.cols(); ++i) {
    std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", 0.1 * static_cast<double>(i), p(0, i),
                  p(1, i), p(2, i), q.x(), q.y(), q.z(), q.w());
    csv += buf;
  }
  return csv;
}

std::string scene(const std::string& driverAttrs) {
  return R"(<Node name="root" gravity="0 0 0" dt="0.1" units="mm g s">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d"/>
    <TrajectoryDriver filename="touch.csv" )" +
         driverAttrs + R"(/>
  </Node>
</Node>
)";
}

void write(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

RigidObject& tool(viscera::Scene& s) { return *s.all<RigidObject>().front(); }

// The robot touched the four top corners; registering them to the scene's corners and replaying
// the recording through the transform puts the instrument on the scene's corners.
TEST(SceneTransform, RegisteredTrajectoryTouchesTheSceneCorners) {
  TempDir dir("viscera_registration");
  const Eigen::Matrix3Xd corners = phantomCorners().leftCols(4);
  RigidTransform robotToScene = RigidTransform::Identity();
  robotToScene.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  robotToScene.translation() = Eigen::Vector3d(-120, 340, -55);
  const Eigen::Matrix3Xd robot = robotToScene.inverse() * corners;
  const Eigen::Quaterniond toolQ(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0, 1, 1).normalized()));
  write(dir / "touch.csv", touchTrajectory(robot, toolQ));
  const auto reg = viscera::obs::registerPoints(robot, corners);
  viscera::writeTransform(dir / "robot_to_scene.txt", reg.transform, "robot -> scene");
  write(dir / "scene.xml", scene(R"(transform="robot_to_scene.txt")"));  // relative to the scene's folder

  auto s = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
  viscera::Simulation sim(*s);
  const RigidObject::Live& b = tool(*s).live(sim.state());
  const Eigen::Quaterniond expectedQ = Eigen::Quaterniond(robotToScene.linear()) * toolQ;
  for (int k = 0; k < 4; ++k) {
    if (k > 0) {
      ASSERT_FALSE(sim.step().has_value());
    }
    // The transform went through Kabsch and a %.17g text file: agreement to rounding (~1e-12 mm
    // for coordinates of a few hundred mm).
    EXPECT_LT((b.p - corners.col(k)).norm(), 1e-10) << "sample " << k;
    EXPECT_LT(std::min((b.q.coeffs() - expectedQ.coeffs()).norm(), (b.q.coeffs() + expectedQ.coeffs()).norm()), 1e-12);
  }
}

// transform, then rotation, then translation: x_scene = R_rot (R_file x + t_file) + t.
TEST(SceneTransform, AppliedBeforeRotationAndTranslation) {
  TempDir dir("viscera_registration");
  Eigen::Matrix3Xd p(3, 2);
  p << 1, 4,
       2, -1,
       3, 0.5;
  const Eigen::Quaterniond toolQ(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  write(dir / "touch.csv", touchTrajectory(p, toolQ));
  // The file: a quarter turn about z (x -> y, y -> -x) and a shift (10, 0, 0).
  write(dir / "t.txt", "# quarter turn\n0 -1 0 10\n1 0 0 0\n0 0 1 0\n0 0 0 1\n");
  // rotation="90 0 0": a quarter turn about x (y -> z, z -> -y); then translation (0, 0, 100).
  write(dir / "scene.xml", scene(R"(transform="t.txt" rotation="90 0 0" translation="0 0 100")"));
  auto s = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
  viscera::Simulation sim(*s);
  const RigidObject::Live& b = tool(*s).live(sim.state());
  // By hand for (1, 2, 3): file -> (-2 + 10, 1, 3) = (8, 1, 3); about x -> (8, -3, 1); + t -> (8, -3, 101).
  EXPECT_LT((b.p - Eigen::Vector3d(8, -3, 101)).norm(), 1e-12);
  ASSERT_FALSE(sim.step().has_value());
  // (4, -1, 0.5): file -> (1 + 10, 4, 0.5) = (11, 4, 0.5); about x -> (11, -0.5, 4); + t -> (11, -0.5, 104).
  EXPECT_LT((b.p - Eigen::Vector3d(11, -0.5, 104)).norm(), 1e-12);
  const Eigen::Quaterniond expectedQ = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX())) *
                                       Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())) * toolQ;
  EXPECT_LT(std::min((b.q.coeffs() - expectedQ.coeffs()).norm(), (b.q.coeffs() + expectedQ.coeffs()).norm()), 1e-12);
}

std::string initError(const TempDir& dir) {
  try {
    auto s = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
    s->init();
  } catch (const viscera::Error& e) {
    return e.what();
  }
  return "";
}

TEST(SceneTransform, ErrorsNameTheFileTheSceneLineAndTheAttribute) {
  TempDir dir("viscera_registration");
  write(dir / "touch.csv", touchTrajectory(phantomCorners().leftCols(2), Eigen::Quaterniond::Identity()));
  write(dir / "scene.xml", scene(R"(transform="missing.txt")"));
  std::string e = initError(dir);
  EXPECT_NE(e.find("missing.txt: cannot open transform file"), std::string::npos) << e;
  EXPECT_NE(e.find("scene.xml:4:"), std::string::npos) << e;
  EXPECT_NE(e.find("TrajectoryDriver.transform"), std::string::npos) << e;

  // Not a rotation (a scale of 2): the transform file's line comes first.
  write(dir / "scaled.txt", "# scaled\n2 0 0 0\n0 2 0 0\n0 0 2 0\n0 0 0 1\n");
  write(dir / "scene.xml", scene(R"(transform="scaled.txt")"));
  e = initError(dir);
  EXPECT_EQ(e.find(dir / "scaled.txt:2:"), 0u) << e;
  EXPECT_NE(e.find("not a rotation"), std::string::npos) << e;
  EXPECT_NE(e.find("TrajectoryDriver.transform"), std::string::npos) << e;
}

}  // namespace
