// The example scene scenes/psm_palpation.xml: a joint log replayed through PsmJointDriver moves the
// instrument along the kinematic path (every step, the pose is recomputed here from the log, the
// kinematics and the transform file) and the tool tip indents the phantom.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "io/scene/Transform.h"
#include "robot/kinematics/JointTrajectory.h"
#include "robot/kinematics/PsmKinematics.h"
#include "tests/support/TempDir.h"

namespace {

std::string source(const std::string& rel) { return std::string(VISCERA_SOURCE_DIR) + "/" + rel; }

TEST(PsmPalpationScene, InstrumentFollowsTheJointLogAndIndentsThePhantom) {
  viscera::test_support::TempDir out("viscera_psm_scene");
  auto scene = viscera::buildScene(viscera::io::readScene(source("scenes/psm_palpation.xml")));
  scene->setOutputDirectory(out.str());  // the scene's VTKExporter writes here, not beside the scene
  viscera::Simulation sim(*scene);
  const viscera::RigidObject::Live& tool = scene->all<viscera::RigidObject>().front()->live(sim.state());
  const viscera::MechanicalObject& tissue = *scene->all<viscera::MechanicalObject>().front();
  const auto log = viscera::robot::readJointCsv(source("scenes/psm_palpation_joints.csv"), 6);
  const auto psm = viscera::robot::psmLargeNeedleDriver();
  const viscera::RigidTransform T = viscera::readTransform(source("scenes/psm_to_phantom.txt"));

  // The first 6.5 s hold the first poke (press, dwell, retract).
  double worstPosition = 0, worstAngle = 0, deepest = 0;
  int contactSteps = 0;
  sim.begin();
  for (int k = 0; k < 975; ++k) {
    ASSERT_FALSE(sim.step().has_value());
    const Eigen::Isometry3d tip = psm.tipPose(log.sample(sim.time()));
    const Eigen::Vector3d expected = T * (1000.0 * tip.translation());  // m -> mm, then robot -> scene
    worstPosition = std::max(worstPosition, (tool.p - expected).norm());
    worstAngle = std::max(worstAngle, Eigen::AngleAxisd(tool.q.toRotationMatrix() * (T.linear() * tip.linear()).transpose()).angle());
    contactSteps += tool.contacts > 0;
    deepest = std::max(deepest, (tissue.x(sim.state()) - tissue.x0).colwise().norm().maxCoeff());
  }
  sim.end();
  // Round-off of ~200 mm coordinates through the chain and the transform.
  EXPECT_LT(worstPosition, 1e-10);
  EXPECT_LT(worstAngle, 1e-12);
  // The poke is 3 mm (+- 25 %) past the undeformed top, less the 0.5 mm contact distance: the
  // surface moves by millimetres, and only while the tool presses.
  EXPECT_GT(contactSteps, 100);
  EXPECT_GT(deepest, 1.0);
  EXPECT_LT(deepest, 4.0);
}

}  // namespace
