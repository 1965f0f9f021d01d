// SOFA's RigidMapping: points fixed in a rigid body's frame (a collision surface, a visual model,
// a mapped Vec3d state) follow the body: x = p + R l, v = v_body + w x (R l), with l the point in
// the body's frame: the point's given position, or (globalToLocalCoords) its world position at init
// taken into the frame.
// Forces on a mapped state reach an integrated body as the wrench sum f, sum (x - p) x f.
#pragma once

#include <Eigen/Core>

#include "core/Component.h"
#include "engine/Roles.h"

namespace viscera {

class MechanicalObject;
class Registry;
class RigidObject;
class VisualModel;

class RigidMapping : public Component, public Mapping {
 public:
  using Component::Component;
  void init() override;
  void apply(State& s) const override;

  RigidObject& body() const { return *body_; }
  // The mapped state (null when the output is a visual model) and the force fields acting on it.
  MechanicalObject* outputState() const { return state_; }
  const std::vector<ForceField*>& outputForces() const { return forces_; }
  // The wrench of the output's force fields and contacts at state s (world frame, torque about
  // the body's origin), taken explicitly over the step.
  void addWrench(State& s, Eigen::Vector3d& force, Eigen::Vector3d& torque) const;
  // K += J^T K_points J: the stiffness of those forces (as linearised by the last addWrench) in the
  // body's translation and rotation, J taking (dp, dtheta) to the points' dp + dtheta x r.
  void addStiffness(const State& s, Eigen::Matrix<double, 6, 6>& K) const;

 private:
  RigidObject* body_ = nullptr;
  MechanicalObject* state_ = nullptr;
  VisualModel* visual_ = nullptr;
  Eigen::Matrix3Xd local_;  // the points in the body's frame
  std::vector<ForceField*> forces_;
  std::vector<ForceField*> surfaces_;  // collision surfaces on the mapped state (contact forces)
};

void registerRigidMapping(Registry& r);

}  // namespace viscera
