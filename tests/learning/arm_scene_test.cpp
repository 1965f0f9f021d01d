// A Viscera scene as the simulated arm's environment: the gel phantom pushes back on the tool when
// the tip is pressed into it, along the face the arm palpates, harder the deeper it goes.
#include <gtest/gtest.h>

#include "core/Error.h"
#include "learning/ArmScene.h"
#include "robot/kinematics/PsmKinematics.h"

using namespace viscera;

namespace {

const std::string kScene = std::string(VISCERA_SOURCE_DIR) + "/scenes/psm_phantom_arm.xml";
const std::string kTransform = std::string(VISCERA_SOURCE_DIR) + "/scenes/psm_to_phantom.txt";

// The tool's force on the gel after holding the tip `depth` below the palpated face's centre for
// 0.5 s (its centre approached along the face's normal).
Eigen::Vector3d pushAt(double depth) {
  learning::SceneEnvironment env(kScene, kTransform);
  const robot::Phantom face = env.palpationSurface();
  Eigen::Isometry3d tip = Eigen::Isometry3d::Identity();
  tip.translation() = face.point - depth * face.normal;
  robot::Vector6d w = robot::Vector6d::Zero();
  for (double t = 0; t <= 0.5; t += 0.01) w = env(t, tip, robot::Vector6d::Zero());
  return w.head<3>();
}

TEST(SceneEnvironment, TheGelPushesBackAlongItsFace) {
  learning::SceneEnvironment env(kScene, kTransform);
  const robot::Phantom face = env.palpationSurface();
  // The face towards the remote centre is the top face (scene +z), whose normal in the robot frame
  // is the transform's rotation of +z transposed.
  EXPECT_NEAR(face.normal.norm(), 1, 1e-12);
  EXPECT_GT(face.radius, 0);
  const Eigen::Vector3d far = pushAt(-0.02);  // 2 cm above: no contact
  EXPECT_EQ(far.norm(), 0);
  const Eigen::Vector3d shallow = pushAt(-0.002), deep = pushAt(0.004);  // sphere radius 5 mm
  // The tool pushes into the gel: against the outward normal, and more the deeper it is.
  EXPECT_LT(shallow.dot(face.normal), 0);
  EXPECT_LT(deep.dot(face.normal), 1.5 * shallow.dot(face.normal));
  EXPECT_GT(std::abs(deep.dot(face.normal)), 0.8 * deep.norm());
}

TEST(SceneEnvironment, RefusesAnInstrumentWithADriver) {
  EXPECT_THROW(learning::SceneEnvironment(std::string(VISCERA_SOURCE_DIR) + "/scenes/psm_palpation.xml", kTransform), Error);
}

}  // namespace
