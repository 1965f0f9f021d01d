// A rigid body's state (SOFA's MechanicalObject template="Rigid3d"): one frame, position and
// orientation, with its velocity. In Viscera rigid bodies are instruments: their motion is
// prescribed by a driver (a trajectory, key frames, robot kinematics) and the contact wrench on
// them is recorded, not integrated.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/State.h"
#include "core/Component.h"

namespace viscera {

class RigidObject : public Component, public Stateful {
 public:
  explicit RigidObject(BuildContext& ctx) : Component(ctx) {}
  void init() override;
  bool field(const std::string& name, FieldValue& out) const override;
  // Pose, velocity and the last contact wrench, in a simulation's state.
  struct Live : ComponentStateOf<Live> {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();  // position
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    Eigen::Vector3d v = Eigen::Vector3d::Zero(), w = Eigen::Vector3d::Zero();  // linear, angular velocity
    // Contact wrench on the body over the last step (world frame, torque about p).
    Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
    int contacts = 0;
    // Sets the pose and velocity (world frame; angular velocity as a vector).
    void setMotion(const Eigen::Vector3d& pos, const Eigen::Quaterniond& rot, const Eigen::Vector3d& lin,
                   const Eigen::Vector3d& ang);
    // Velocity of the body point at world position `at`.
    Eigen::Vector3d pointVelocity(const Eigen::Vector3d& at) const { return v + w.cross(at - p); }
    void save(StateWriter& out) const override;
    void load(StateReader& in) override;
  };
  std::unique_ptr<ComponentState> initialState() const override;
  Live& live(State& s) const { return stateIn<Live>(s); }
  const Live& live(const State& s) const { return stateIn<Live>(s); }

  // The reference pose: `position` as placed, or where a trajectory starts.
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q0 = Eigen::Quaterniond::Identity();
  // The pose and velocity at the start of a simulation (a driver sets them at init).
  Live start;
  double mass = 0;  // informative: the body is driven
  bool driven = false;  // a driver sets the motion
};

// True for the rigid state templates ("Rigid3d", "Rigid3", "Rigid3f").
bool isRigidTemplate(const std::string& t);

// The RigidObject a component acts on: its link `attr` if set, else the nearest in its context.
RigidObject& contextRigid(Component& c, const std::string& attr = "object");

}  // namespace viscera
