#include "engine/rigid/RigidMapping.h"

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mapping/VisualModel.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"

namespace viscera {

void RigidMapping::init() {
  const auto& t = attrs_.str("template");
  if (!t.empty() && t.rfind("Rigid", 0) != 0)
    throw error("template", "maps a rigid body (Rigid3d,Vec3d), got '" + t + "'");
  if (attrs_.isSet("input")) {
    const LinkTarget t = linkTarget(*this, "input");
    body_ = t.node ? t.node->find<RigidObject>() : dynamic_cast<RigidObject*>(t.component);
    if (!body_) throw error("input", "'" + attrs_.get("input").text + "' is not a MechanicalObject with template=\"Rigid3d\" (or its node)");
  } else {
    // SOFA's default input is the state of the parent node.
    for (const Node* n = node().parent(); n && !body_; n = n->parent()) body_ = n->find<RigidObject>();
    if (!body_) throw error("input", "is not set and no node above holds a MechanicalObject with template=\"Rigid3d\"");
  }
  scene().initComponent(*body_);
  for (int i : attrs_.ints("index"))
    if (i != 0) throw error("index", "a Rigid3d object has one frame (index 0), got " + std::to_string(i));

  Component* out = nullptr;
  if (attrs_.isSet("output")) {
    const LinkTarget t = linkTarget(*this, "output");
    out = t.component;
    if (t.node && !(out = t.node->find<MechanicalObject>())) out = t.node->find<VisualModel>();
  } else {
    out = node().find<MechanicalObject>();
    if (!out) out = node().find<VisualModel>();
  }
  if (!out) throw error("output", "there is no OglModel/VisualModel or Vec3d MechanicalObject to move");
  scene().initComponent(*out);
  const Eigen::Matrix3Xd* start = nullptr;
  if ((visual_ = dynamic_cast<VisualModel*>(out))) {
    visual_->setDriver(*this);
    start = &visual_->x0;
  } else if ((state_ = dynamic_cast<MechanicalObject*>(out))) {
    if (auto* solver = state_->node().find<OdeSolver>(); solver && &state_->node() != &body_->node())
      throw error("output", "MechanicalObject '" + state_->name() + "' is integrated by the " +
                                dynamic_cast<Component&>(*solver).typeName() + " in its node; a mapped state must be in a "
                                "node without an ODE solver");
    state_->setMappedBy(*this, true);
    start = &state_->xInit;
    for (const auto& c : state_->node().components())
      if (auto* f = dynamic_cast<ForceField*>(c.get())) {
        // A collision surface initialises this mapping first (it reads the mapped state): it is
        // taken as it is, and its contact forces are added where they act on this state.
        if (f->actsThroughMapping()) {
          surfaces_.push_back(f);
          continue;
        }
        scene().initComponent(*c);
        if (&f->mstate() == state_) forces_.push_back(f);
      }
  } else {
    throw error("output", "'" + out->name() + "' (" + out->typeName() +
                              ") is neither a visual model (OglModel/VisualModel) nor a MechanicalObject (Vec3d)");
  }
  // The points are given in the body's frame (SOFA's default), or with globalToLocalCoords in the
  // world, where they start.
  if (attrs_.boolean("globalToLocalCoords"))
    local_ = body_->start.q.conjugate().toRotationMatrix() * (start->colwise() - body_->start.p);
  else
    local_ = *start;
}

void RigidMapping::apply(State& s) const {
  const RigidObject::Live& b = body_->live(s);
  const Eigen::Matrix3d R = b.q.toRotationMatrix();
  const Eigen::Matrix3Xd arm = R * local_;
  if (visual_) {
    visual_->x(s) = arm.colwise() + b.p;
    return;
  }
  state_->x(s) = arm.colwise() + b.p;
  Eigen::Matrix3Xd& v = state_->v(s);
  for (Eigen::Index i = 0; i < arm.cols(); ++i) v.col(i) = b.v + b.w.cross(arm.col(i));
}

void RigidMapping::addWrench(State& s, Eigen::Vector3d& force, Eigen::Vector3d& torque) const {
  if (forces_.empty() && surfaces_.empty()) return;
  MechanicalObject::Live& m = state_->live(s);
  m.f.setZero(3, m.x.cols());
  for (ForceField* f : forces_) f->addForce(s, m.x, m.v, m.f);
  for (ForceField* f : surfaces_)
    if (&f->mstate() == state_) f->addForce(s, m.x, m.v, m.f);
  const Eigen::Vector3d p = body_->live(s).p;
  for (Eigen::Index i = 0; i < m.f.cols(); ++i) {
    force += m.f.col(i);
    torque += (m.x.col(i) - p).cross(m.f.col(i));
  }
}

void RigidMapping::addStiffness(const State& s, Eigen::Matrix<double, 6, 6>& K) const {
  if (forces_.empty() && surfaces_.empty()) return;
  const Eigen::Matrix3Xd& x = state_->x(s);
  const Eigen::Vector3d p = body_->live(s).p;
  const Eigen::Index n = x.cols();
  Eigen::Matrix3Xd dx(3, n), df(3, n);
  for (int k = 0; k < 6; ++k) {
    // The points' motion under a unit translation or rotation of the body: dp + dtheta x r.
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(k % 3);
    for (Eigen::Index i = 0; i < n; ++i) dx.col(i) = k < 3 ? e : Eigen::Vector3d(e.cross(x.col(i) - p));
    df.setZero();
    for (ForceField* f : forces_) f->addDForce(s, dx, df, 1.0);
    for (ForceField* f : surfaces_)
      if (&f->mstate() == state_) f->addDForce(s, dx, df, 1.0);
    for (Eigen::Index i = 0; i < n; ++i) {
      K.block<3, 1>(0, k) += df.col(i);
      K.block<3, 1>(3, k) += (x.col(i) - p).cross(df.col(i));
    }
  }
}

void registerRigidMapping(Registry& r) {
  ComponentSpec s;
  s.name = "RigidMapping";
  s.category = "mapping";
  s.doc = "Moves points fixed in a rigid body's frame with the body (SOFA's RigidMapping): a visual model, or a Vec3d "
          "MechanicalObject in a child node (positions and velocities: x = p + R l, v = v_body + w x R l), e.g. the "
          "body's collision surface. The points' positions are their coordinates l in the body's frame (SOFA's "
          "default), or with globalToLocalCoords their world positions at the start, turned into l. Forces on the mapped state (a ConstantForceField, springs) "
          "act on an integrated body as the wrench sum f, sum r x f.";
  s.add(AttrSpec::string("template").def("Rigid3d,Vec3d").help("input,output types (Rigid3d,Vec3d and their f variants)"));
  s.add(AttrSpec::link("input").alias("object1").help(
      "the Rigid3d MechanicalObject, or its node (default: the nearest node above with one)"));
  s.add(AttrSpec::link("output").alias("object2").help(
      "the OglModel/VisualModel or Vec3d MechanicalObject moved, or its node (default: this node's MechanicalObject, "
      "else its visual model)"));
  s.add(AttrSpec::ints("index").def("0").help("the frame of the input (a Rigid3d object has one: 0)"));
  s.add(AttrSpec::boolean("globalToLocalCoords").def("false").help(
      "take the points' coordinates in the body's frame from where they start in the world (default, as SOFA: their "
      "positions are those coordinates)"));
  for (const char* a : {"mapForces", "mapConstraints", "mapMasses"})
    s.add(AttrSpec::boolean(a).def("true").help("accepted for SOFA scenes: forces on the mapped state always reach the body"));
  s.add(AttrSpec::boolean("applyRestPosition").def("false").help("accepted for SOFA scenes; the points' frame coordinates are fixed at init"));
  s.factory = [](BuildContext& c) { return std::make_unique<RigidMapping>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
