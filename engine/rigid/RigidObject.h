// A rigid body's state (SOFA's MechanicalObject template="Rigid3d"): one frame, position and
// orientation, with its velocity. Instruments are driven: their motion is prescribed by a driver
// (a trajectory, key frames, robot kinematics) and the contact wrench on them is recorded. A body
// with a mass, an ODE solver in its node or above it and no driver is integrated (RigidDynamics.h).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <functional>

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
  // Mass and inertia about the frame's origin in the body's frame (UniformMass); no mass: none set.
  double mass = 0;
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
  bool driven = false;  // a driver sets the motion
  // Held velocity components (world x y z translation, then rotation), by projective constraints.
  std::array<bool, 6> held{};
  // A prescribed velocity (LinearVelocityProjectiveConstraint): true with the linear and angular
  // velocity when one applies over the step that starts at t; the body then moves with it.
  std::function<bool(double t, Eigen::Vector3d& v, Eigen::Vector3d& w)> prescribedVelocity;
};

// True for the rigid state templates ("Rigid3d", "Rigid3", "Rigid3f").
bool isRigidTemplate(const std::string& t);

// The RigidObject a component acts on: its link `attr` if set, else the nearest in its context.
RigidObject& contextRigid(Component& c, const std::string& attr = "object");

}  // namespace viscera
