// A Viscera scene as the arm simulator's environment (robot/dynamics/ArmSimulator.h): the
// instrument in the scene follows the simulated arm's tool tip, the scene steps along, and the
// contact wrench on the instrument goes back to the arm as the true external force. The tissue's
// response is then the FEM's, not a spring's.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>

#include "robot/dynamics/ArmSimulator.h"

namespace viscera {

class Scene;
class Simulation;
class RigidObject;

namespace learning {

class SceneEnvironment {
 public:
  // `scene`: a scene whose instrument (a Rigid3d MechanicalObject named `instrument`, or the only
  // one) has no driver, since the arm moves it. `transform`: robot base -> scene (4 x 4, translation
  // in the scene's length unit), as PsmJointDriver takes it. Throws Error naming what does not fit.
  SceneEnvironment(const std::string& scene, const std::string& transform, const std::string& instrument = "");
  ~SceneEnvironment();

  // The tool's wrench on the tissue (robot base frame, N, N m) once the scene has stepped to time t
  // with the instrument at the tip's pose (robot base frame, m). Steps the scene at its own dt; the
  // wrench is the last step's.
  robot::Vector6d operator()(double t, const Eigen::Isometry3d& tip, const robot::Vector6d& twist);

  // The plane to palpate, in the robot's base frame: the face of the deformable bodies' bounding box
  // that faces the remote centre of motion (its centre and outward normal), palpated within 40 % of
  // its smaller half-size of the centre.
  robot::Phantom palpationSurface() const;

  int steps() const;
  double dt() const;

 private:
  std::unique_ptr<Scene> scene_;
  std::unique_ptr<Simulation> sim_;
  RigidObject* tool_ = nullptr;
  Eigen::Isometry3d robotToScene_ = Eigen::Isometry3d::Identity();
  double metresToScene_ = 1, sceneForceToNewtons_ = 1, sceneLengthToMetres_ = 1;
  robot::Vector6d last_ = robot::Vector6d::Zero();
  std::string path_;
};

}  // namespace learning
}  // namespace viscera
