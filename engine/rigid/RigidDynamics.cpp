#include "engine/rigid/RigidDynamics.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidMapping.h"
#include "engine/rigid/RigidObject.h"

namespace viscera {

void collectBodies(const Node& n, std::vector<RigidObject*>& rigid, std::vector<MechanicalObject*>& deformable) {
  for (const auto& child : n.children()) {
    const Node& c = *child;
    if (!c.active() || c.find<OdeSolver>()) continue;  // inactive, or moved by its own solver
    if (RigidObject* b = c.find<RigidObject>(); b && !c.find<MechanicalObject>()) {
      rigid.push_back(b);
      continue;  // below a rigid body: its mapped points and visuals
    }
    if (MechanicalObject* m = c.find<MechanicalObject>(); m && c.find<Mass>()) deformable.push_back(m);
    collectBodies(c, rigid, deformable);
  }
}

const Node* integratingNode(const MechanicalObject& body) {
  const Node* own = &body.node();
  if (own->find<OdeSolver>()) return own;
  for (const Node* n = own->parent(); n; n = n->parent()) {
    if (!n->find<OdeSolver>()) continue;
    if (n->find<MechanicalObject>()) return nullptr;  // that solver integrates its own node's body
    std::vector<RigidObject*> rigid;
    std::vector<MechanicalObject*> deformable;
    collectBodies(*n, rigid, deformable);
    return std::find(deformable.begin(), deformable.end(), &body) != deformable.end() ? n : nullptr;
  }
  return nullptr;
}

std::unique_ptr<RigidBodyIntegrator> RigidBodyIntegrator::forSolver(Component& solver, bool deformableToo) {
  Node& node = solver.node();
  if (node.find<MechanicalObject>()) return nullptr;
  std::vector<RigidObject*> found;
  if (RigidObject* body = node.find<RigidObject>()) {
    found.push_back(body);
  } else {
    std::vector<MechanicalObject*> deformable;
    collectBodies(node, found, deformable);
    if (found.empty()) return nullptr;
    if (!deformable.empty() && !deformableToo)
      throw solver.error("moves the rigid bodies below its node, but MechanicalObject '" + deformable.front()->name() +
                         "' (" + deformable.front()->node().path() + ") has a mass and no solver of its own: a "
                         "deformable body needs the solver in its node");
  }
  auto r = std::unique_ptr<RigidBodyIntegrator>(new RigidBodyIntegrator);
  r->gravity_ = solver.scene().gravity();
  for (RigidObject* body : found) r->bodies_.push_back(prepare(solver, *body));
  return r;
}

RigidBodyIntegrator::Body RigidBodyIntegrator::prepare(Component& solver, RigidObject& body) {
  Node& node = body.node();
  Scene& scene = solver.scene();
  scene.initComponent(body);
  // Drivers and masses mark the body when they initialise: settle them before deciding.
  for (Driver* d : scene.all<Driver>()) scene.initComponent(dynamic_cast<Component&>(*d));
  for (const auto& c : node.components())
    if (c.get() != &solver) scene.initComponent(*c);
  Body r;
  r.body = &body;
  for (RigidMapping* m : scene.all<RigidMapping>()) {
    scene.initComponent(*m);
    if (&m->body() == &body) r.mappings.push_back(m);
  }
  for (RigidForce* f : scene.all<RigidForce>()) {
    scene.initComponent(dynamic_cast<Component&>(*f));
    if (&f->body() == &body) r.forces.push_back(f);
  }
  const std::string who = solver.loc().str() + ": note: " + solver.typeName() + " '" + solver.name() + "' moves rigid body '" + body.name() + "'";
  if (body.driven) {
    scene.addNote(who + ", which is driven, not integrated: the solver stays idle for it");
  } else if (!(body.mass > 0)) {
    scene.addNote(who + ", which has no mass (UniformMass): the body is held where it starts");
  } else {
    r.idle = false;
    return r;
  }
  if (body.prescribedVelocity)
    throw solver.error("rigid body '" + body.name() + "' has a prescribed velocity (LinearVelocityProjectiveConstraint) "
                       "but is " + (body.driven ? "driven" : "not integrated (no mass)") + ": the velocity would be ignored");
  // A held or driven body does not move under forces: refuse forces that would be ignored.
  if (!r.forces.empty())
    throw dynamic_cast<const Component&>(*r.forces.front())
        .error("acts on rigid body '" + body.name() + "', which is " + (body.driven ? "driven" : "held (no mass)") +
               ": the force would be ignored");
  for (const RigidMapping* m : r.mappings)
    if (!m->outputForces().empty())
      throw dynamic_cast<const Component&>(*m->outputForces().front())
          .error("acts on a state mapped from rigid body '" + body.name() + "', which is " +
                 (body.driven ? "driven" : "held (no mass)") + ": the force would be ignored");
  return r;
}

bool RigidBodyIntegrator::idle() const {
  for (const Body& b : bodies_)
    if (!b.idle) return false;
  return true;
}

std::vector<RigidObject*> RigidBodyIntegrator::bodies() const {
  std::vector<RigidObject*> r;
  for (const Body& b : bodies_) r.push_back(b.body);
  return r;
}

const RigidBodyIntegrator::Body* RigidBodyIntegrator::find(const RigidObject& body) const {
  for (const Body& b : bodies_)
    if (b.body == &body) return &b;
  return nullptr;
}

void RigidBodyIntegrator::wrench(State& s, const RigidObject& body, Eigen::Vector3d& force, Eigen::Vector3d& torque) const {
  force = body.mass * gravity_;
  torque.setZero();
  if (const Body* b = find(body)) {
    for (const RigidMapping* m : b->mappings) m->addWrench(s, force, torque);
    for (const RigidForce* f : b->forces) f->addWrench(s, force, torque);
  }
}

std::optional<Diverged> RigidBodyIntegrator::step(State& s, double t, double h, int stepIndex, double rM) const {
  for (const Body& b : bodies_)
    if (auto bad = step(b, s, t, h, stepIndex, rM)) return bad;
  return std::nullopt;
}

std::optional<Diverged> RigidBodyIntegrator::step(const Body& body, State& s, double t, double h, int stepIndex,
                                                  double rM) const {
  if (body.idle) return std::nullopt;
  const RigidObject* rb = body.body;
  Eigen::Vector3d F, T;
  wrench(s, *rb, F, T);
  RigidObject::Live& b = rb->live(s);
  const RigidObject::Live before = b;
  const Eigen::Matrix3d R = b.q.toRotationMatrix();
  const Eigen::Matrix3d I = R * rb->inertia * R.transpose();
  const double m = rb->mass, damp = 1.0 + h * rM;
  const Eigen::Vector3d Iw = I * b.w;
  Eigen::Vector3d v, w;
  if (rb->prescribedVelocity && rb->prescribedVelocity(t, v, w)) {
    b.v = v;
    b.w = w;
  } else {
    // [(1 + h rM) M - h^2 K] dV = h (F - rM M V + h K V), V = (v, w): the forces on the mapped
    // points (contacts above all) are implicit in the body's own motion.
    Eigen::Matrix<double, 6, 6> K = Eigen::Matrix<double, 6, 6>::Zero();
    for (const RigidMapping* map : body.mappings) map->addStiffness(s, K);
    for (const RigidForce* f : body.forces) f->addStiffness(s, K);
    Eigen::Matrix<double, 6, 6> M = Eigen::Matrix<double, 6, 6>::Zero();
    M.topLeftCorner<3, 3>() = m * Eigen::Matrix3d::Identity();
    M.bottomRightCorner<3, 3>() = I;
    Eigen::Matrix<double, 6, 1> V, rhs;
    V << b.v, b.w;
    rhs << F, T - b.w.cross(Iw);
    rhs = h * (rhs - rM * M * V + h * K * V);
    Eigen::Matrix<double, 6, 6> A = damp * M - h * h * K;
    for (int k = 0; k < 6; ++k)
      if (rb->held[k]) {
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
    if (rb->held[k]) b.v[k] = 0;
    if (rb->held[3 + k]) b.w[k] = 0;
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
    d.object = rb->name();
    return d;
  }
  // The points on the body where it now is (the constraint response's free motion reads them).
  for (const RigidMapping* map : body.mappings) map->apply(s);
  return std::nullopt;
}

}  // namespace viscera
