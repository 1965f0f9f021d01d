// The motion of a rigid body that is integrated, not driven: a Rigid3d MechanicalObject with a
// UniformMass and an ODE solver in its node or above it, and no driver. Newton-Euler in the world frame:
//   (1 + h rM) m dv = h (F - rM m v)
//   (1 + h rM) I dw = h (T - w x I w - rM I w),   I = R I_body R^T,
// the linearly implicit Euler step of SOFA's EulerImplicitSolver (symplectic Euler with rM = 0
// and no stiffness); then held components are zeroed, p += h v and the orientation turns by
// exp(h w). F and T are gravity, the forces on the body's mapped states (RigidMapping: contacts,
// springs, constant forces) and those on its frame (RigidForce) at the step start; their
// stiffness K, carried to the body's six
// motions, makes them implicit: the matrix is (1 + h rM) M - h^2 K and the right side gains h^2 K V.
// The gyroscopic term w x I w is explicit. A prescribed velocity
// (LinearVelocityProjectiveConstraint) replaces the dynamics while it applies.
// SOFA's rigid mass keeps the inertia in the world frame, unturned, and has no gyroscopic term:
// the two agree for the default inertia (the mass times the identity).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <vector>

#include "engine/Roles.h"

namespace viscera {

class Component;
class RigidMapping;
class RigidObject;
class State;

// A force on a rigid body's frame itself (SOFA's force fields on a Rigid3d state): its force and
// torque (about the body's origin) at state s, and its stiffness over the body's six motions
// (d(F, T) / d(translation, rotation vector)), which the implicit step takes in.
class RigidForce {
 public:
  virtual ~RigidForce() = default;
  virtual const RigidObject& body() const = 0;
  virtual void addWrench(const State& s, Eigen::Vector3d& force, Eigen::Vector3d& torque) const = 0;
  virtual void addStiffness(const State& s, Eigen::Matrix<double, 6, 6>& K) const {}
};

// RestShapeSpringsForceField on a Rigid3d body (RigidForces.cpp), or null outside a rigid body's node.
class BuildContext;
std::unique_ptr<Component> makeRigidRestShapeSprings(BuildContext& c);

class MechanicalObject;
class Node;

// What a solver in node n with no body of its own moves (SOFA's solver over several bodies): the
// rigid bodies in its subtree and the Vec3d bodies with a mass in their node (not mapped), each in
// a node that no solver between moves, in scene order.
void collectBodies(const Node& n, std::vector<RigidObject*>& rigid, std::vector<MechanicalObject*>& deformable);
// The node whose ODE solver integrates the deformable `body`: its own node's, or that of a solver
// above it that collects it (collectBodies); null when nothing integrates it.
const Node* integratingNode(const MechanicalObject& body);

class RigidBodyIntegrator {
 public:
  // The integrator of the rigid bodies `solver` moves: the one in its node, when that node holds a
  // rigid body and no Vec3d one; or, when its node holds neither (SOFA's solver above several
  // bodies), every rigid body in its subtree that no solver further down moves. Null when there is
  // none; a driven or massless body is held still (with a note). A body with a mass on Vec3d nodes
  // in such a subtree is refused unless `deformableToo` (its solver belongs in its node); one
  // without a mass is an obstacle.
  // `deformableToo`: the solver integrates such deformable bodies itself (EulerImplicitSolver).
  static std::unique_ptr<RigidBodyIntegrator> forSolver(Component& solver, bool deformableToo = false);

  // True when no body moves (all driven or massless).
  bool idle() const;
  // The bodies, in scene order.
  std::vector<RigidObject*> bodies() const;
  // Force and torque on `body` (about its origin) at state s: gravity, the mapped states' forces
  // and the forces on the frame.
  void wrench(State& s, const RigidObject& body, Eigen::Vector3d& force, Eigen::Vector3d& torque) const;
  // One step of size h with Rayleigh mass damping rM for every body; a non-finite result is refused.
  std::optional<Diverged> step(State& s, double t, double h, int stepIndex, double rayleighMass) const;

 private:
  struct Body {
    RigidObject* body = nullptr;
    bool idle = true;
    std::vector<const RigidMapping*> mappings;
    std::vector<const RigidForce*> forces;
  };
  static Body prepare(Component& solver, RigidObject& body);
  const Body* find(const RigidObject& b) const;
  std::optional<Diverged> step(const Body& body, State& s, double t, double h, int stepIndex, double rM) const;
  Eigen::Vector3d gravity_ = Eigen::Vector3d::Zero();
  std::vector<Body> bodies_;
};

}  // namespace viscera
