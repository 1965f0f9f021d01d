#include "engine/rigid/RigidDynamics.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>

#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidMapping.h"
#include "engine/rigid/RigidObject.h"

namespace viscera {

std::unique_ptr<RigidBodyIntegrator> RigidBodyIntegrator::forSolver(Component& solver) {
  Node& node = solver.node();
  RigidObject* body = node.find<RigidObject>();
  if (!body || node.find<MechanicalObject>()) return nullptr;
  Scene& scene = solver.scene();
  scene.initComponent(*body);
  // Drivers and masses mark the body when they initialise: settle them before deciding.
  for (Driver* d : scene.all<Driver>()) scene.initComponent(dynamic_cast<Component&>(*d));
  for (const auto& c : node.components())
    if (c.get() != &solver) scene.initComponent(*c);
  auto r = std::unique_ptr<RigidBodyIntegrator>(new RigidBodyIntegrator);
  r->body_ = body;
  r->gravity_ = scene.gravity();
  for (RigidMapping* m : scene.all<RigidMapping>()) {
    scene.initComponent(*m);
    if (&m->body() == body) r->mappings_.push_back(m);
  }
  for (RigidForce* f : scene.all<RigidForce>()) {
    scene.initComponent(dynamic_cast<Component&>(*f));
    if (&f->body() == body) r->forces_.push_back(f);
  }
  const std::string who = solver.loc().str() + ": note: " + solver.typeName() + " '" + solver.name() + "' is in the node of rigid body '" + body->name() + "'";
  if (body->driven) {
    scene.addNote(who + ", which is driven, not integrated: the solver stays idle");
  } else if (!(body->mass > 0)) {
    scene.addNote(who + ", which has no mass (UniformMass): the body is held where it starts");
  } else {
    r->idle_ = false;
    return r;
  }
  if (body->prescribedVelocity)
    throw solver.error("rigid body '" + body->name() + "' has a prescribed velocity (LinearVelocityProjectiveConstraint) "
                       "but is " + (body->driven ? "driven" : "not integrated (no mass)") + ": the velocity would be ignored");
  // A held or driven body does not move under forces: refuse forces that would be ignored.
  if (!r->forces_.empty())
    throw dynamic_cast<const Component&>(*r->forces_.front())
        .error("acts on rigid body '" + body->name() + "', which is " + (body->driven ? "driven" : "held (no mass)") +
               ": the force would be ignored");
  for (const RigidMapping* m : r->mappings_)
    if (!m->outputForces().empty())
      throw dynamic_cast<const Component&>(*m->outputForces().front())
          .error("acts on a state mapped from rigid body '" + body->name() + "', which is " +
                 (body->driven ? "driven" : "held (no mass)") + ": the force would be ignored");
  return r;
}

void RigidBodyIntegrator::wrench(State& s, Eigen::Vector3d& force, Eigen::Vector3d& torque) const {
  force = body_->mass * gravity_;
  torque.setZero();
  for (const RigidMapping* m : mappings_) m->addWrench(s, force, torque);
  for (const RigidForce* f : forces_) f->addWrench(s, force, torque);
}

std::optional<Diverged> RigidBodyIntegrator::step(State& s, double t, double h, int stepIndex, double rM) const {
  if (idle_) return std::nullopt;
  Eigen::Vector3d F, T;
  wrench(s, F, T);
  RigidObject::Live& b = body_->live(s);
  const RigidObject::Live before = b;
  const Eigen::Matrix3d R = b.q.toRotationMatrix();
  const Eigen::Matrix3d I = R * body_->inertia * R.transpose();
  const double m = body_->mass, damp = 1.0 + h * rM;
  const Eigen::Vector3d Iw = I * b.w;
  Eigen::Vector3d v, w;
  if (body_->prescribedVelocity && body_->prescribedVelocity(t, v, w)) {
    b.v = v;
    b.w = w;
  } else {
    // [(1 + h rM) M - h^2 K] dV = h (F - rM M V + h K V), V = (v, w): the forces on the mapped
    // points (contacts above all) are implicit in the body's own motion.
    Eigen::Matrix<double, 6, 6> K = Eigen::Matrix<double, 6, 6>::Zero();
    for (const RigidMapping* map : mappings_) map->addStiffness(s, K);
    for (const RigidForce* f : forces_) f->addStiffness(s, K);
    Eigen::Matrix<double, 6, 6> M = Eigen::Matrix<double, 6, 6>::Zero();
    M.topLeftCorner<3, 3>() = m * Eigen::Matrix3d::Identity();
    M.bottomRightCorner<3, 3>() = I;
    Eigen::Matrix<double, 6, 1> V, rhs;
    V << b.v, b.w;
    rhs << F, T - b.w.cross(Iw);
    rhs = h * (rhs - rM * M * V + h * K * V);
    Eigen::Matrix<double, 6, 6> A = damp * M - h * h * K;
    for (int k = 0; k < 6; ++k)
      if (body_->held[k]) {
        A.row(k).setZero();
        A.col(k).setZero();
        A(k, k) = 1;
        rhs[k] = 0;
      }
    const Eigen::Matrix<double, 6, 1> dV = A.partialPivLu().solve(rhs);
    b.v += dV.head<3>();
    b.w += dV.tail<3>();
  }
  for (int k = 0; k < 3; ++k) {
    if (body_->held[k]) b.v[k] = 0;
    if (body_->held[3 + k]) b.w[k] = 0;
  }
  b.p += h * b.v;
  const double angle = h * b.w.norm();
  if (angle > 0) b.q = (Eigen::Quaterniond(Eigen::AngleAxisd(angle, b.w.normalized())) * b.q).normalized();
  if (!b.p.allFinite() || !b.v.allFinite() || !b.w.allFinite() || !b.q.coeffs().allFinite()) {
    b = before;
    Diverged d;
    d.step = stepIndex;
    d.time = t + h;
    d.reason = "the rigid body's motion is not finite";
    d.object = body_->name();
    return d;
  }
  // The points on the body where it now is: a body whose contacts follow this one's (solved
  // later in the step) reads this body's surface at the end of its step.
  for (const RigidMapping* map : mappings_) map->apply(s);
  return std::nullopt;
}

}  // namespace viscera
