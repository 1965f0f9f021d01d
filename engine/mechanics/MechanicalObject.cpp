#include "engine/mechanics/MechanicalObject.h"

#include <Eigen/Geometry>
#include <cmath>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/Roles.h"
#include "engine/rigid/RigidObject.h"

namespace viscera {

namespace {

Eigen::Matrix3Xd toPoints(const Component& c, const std::string& attr, const std::vector<double>& v) {
  if (v.size() % 3 != 0)
    throw c.error(attr, "expects x y z triples, got " + std::to_string(v.size()) + " numbers");
  Eigen::Matrix3Xd p(3, v.size() / 3);
  for (size_t i = 0; i < v.size(); ++i) p(i % 3, i / 3) = v[i];
  return p;
}

}  // namespace

void MechanicalObject::init() {
  if (attrs_.isSet("position")) {
    xInit = toPoints(*this, "position", linkedReals("position"));
  } else if (attrs_.isSet("src")) {
    Component* src = linkedComponent("src");
    FieldValue points;
    if (auto* t = dynamic_cast<Topology*>(src)) {
      xInit = t->points();
    } else if (src->field("position", points)) {  // e.g. a SphereLoader: centres without a topology
      xInit = toPoints(*this, "src", points.values);
    } else {
      throw error("src", "does not link to a loader or topology");
    }
    if (xInit.cols() == 0) throw error("src", "links to a component with no points");
  } else {
    // As SOFA: positions come from the first topology in the context that carries points.
    for (const Node* n = &node(); n && xInit.cols() == 0; n = n->parent())
      for (const auto& c : n->components()) {
        auto* t = dynamic_cast<Topology*>(c.get());
        if (!t || c.get() == this) continue;
        scene().initComponent(*c);
        if (t->points().cols() > 0) {
          xInit = t->points();
          break;
        }
      }
  }
  if (xInit.cols() == 0 && attrs_.isSet("position")) throw error("position", "is empty: there are no points");
  if (xInit.cols() == 0) {
    // SOFA's default: one point at the origin (moved by the transform attributes), e.g. the
    // anchor of an attachment in a node without a mesh.
    xInit = Eigen::Matrix3Xd::Zero(3, 1);
    scene().addNote(loc().str() + ": note: MechanicalObject '" + name() +
                    "' has no positions (no `position`, loader or topology): one point at the origin, as in SOFA");
  }
  applyPlacement(attrs_, xInit);
  x0 = xInit;
  if (attrs_.isSet("rest_position")) {
    x0 = toPoints(*this, "rest_position", linkedReals("rest_position"));
    if (x0.cols() != xInit.cols())
      throw error("rest_position", "has " + std::to_string(x0.cols()) + " points, position has " + std::to_string(xInit.cols()));
  }
  for (double f : attrs_.reals("externalForce"))
    if (f != 0) throw error("externalForce", "a non-zero external force is not supported; use a ConstantForceField");
  // SOFA's restScale: rest positions scaled about the origin, a body pre-stretched (< 1: shrunk rest).
  x0 *= attrs_.real("restScale");
  vInit = Eigen::Matrix3Xd::Zero(3, xInit.cols());
  if (attrs_.isSet("velocity")) {
    auto vv = linkedReals("velocity");
    if (vv.size() == 3) {
      for (int i = 0; i < vInit.cols(); ++i) vInit.col(i) = Eigen::Vector3d(vv[0], vv[1], vv[2]);
    } else if (static_cast<int>(vv.size()) == 3 * xInit.cols()) {
      vInit = toPoints(*this, "velocity", vv);
    } else {
      throw error("velocity", "expected one velocity or one per node (" + std::to_string(xInit.cols()) + "), got " +
                                  std::to_string(vv.size() / 3));
    }
  }
}

void MechanicalObject::setMappedBy(const Component& mapping, bool carriesForces) {
  if (mappedBy_ && mappedBy_ != &mapping)
    throw mapping.error("output", "MechanicalObject '" + name() + "' is already the output of " + mappedBy_->typeName() +
                                      " '" + mappedBy_->name() + "'; give each mapped state one mapping");
  // Forces on a mapped state reach its input only through a mapping that carries them: refuse what
  // would be ignored.
  for (const auto& c : node().components())
    if (const auto* f = dynamic_cast<const ForceField*>(c.get()); (f && !f->actsThroughMapping() && !carriesForces) ||
        dynamic_cast<const Mass*>(c.get()) || dynamic_cast<const ProjectiveConstraint*>(c.get()))
      throw mapping.error("output", "MechanicalObject '" + name() + "' is mapped, but the " + c->typeName() + " '" +
                                        c->name() + "' in its node acts on it; forces and constraints on a mapped state "
                                        "are not carried back to the input (put them on the input's node)");
  mappedBy_ = &mapping;
}

std::unique_ptr<ComponentState> MechanicalObject::initialState() const {
  auto l = std::make_unique<Live>();
  l->x = xInit;
  l->v = vInit;
  l->f = Eigen::Matrix3Xd::Zero(3, xInit.cols());
  return l;
}

void MechanicalObject::Live::load(StateReader& in) {
  Eigen::Matrix3Xd nx, nv, nf;
  in.get(nx);
  in.get(nv);
  in.get(nf);
  if (nx.cols() != x.cols() || nv.cols() != x.cols() || nf.cols() != x.cols())
    in.mismatch(std::to_string(nx.cols()) + " nodes where this object has " + std::to_string(x.cols()));
  x = std::move(nx);
  v = std::move(nv);
  f = std::move(nf);
}

bool MechanicalObject::field(const std::string& name, FieldValue& out) const {
  const Eigen::Matrix3Xd* m = nullptr;
  if (name == "position") m = &xInit;
  else if (name == "rest_position") m = &x0;
  else if (name == "velocity") m = &vInit;
  if (!m) return false;
  out.values.assign(m->data(), m->data() + m->size());
  return true;
}

void applyPlacement(const Attributes& attrs, Eigen::Matrix3Xd& points) {
  const auto& s = attrs.reals("scale3d");
  const auto& r = attrs.reals("rotation");
  const auto& t = attrs.reals("translation");
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(r[2] * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(r[1] * M_PI / 180, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(r[0] * M_PI / 180, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d S(s[0], s[1], s[2]), T(t[0], t[1], t[2]);
  for (int i = 0; i < points.cols(); ++i) points.col(i) = R * (S.asDiagonal() * points.col(i)) + T;
}

void addPointPlacementAttributes(ComponentSpec& s, const std::string& what) {
  s.add(AttrSpec::reals("translation", 3).def("0 0 0").unit(Dimension::length()).help("translation of " + what + " (SOFA's dx dy dz)"));
  s.add(AttrSpec::reals("rotation", 3).def("0 0 0").help("rotation of " + what + " in degrees about x, then y, then z (SOFA's rx ry rz)"));
  s.add(AttrSpec::reals("scale3d", 3).def("1 1 1").help("scale factors of " + what + ", applied first (SOFA's scale: one factor or three)"));
}

MechanicalObject& contextState(Component& c, const std::string& linkAttr) {
  MechanicalObject* m = nullptr;
  if (c.spec().find(linkAttr) && c.attrs().isSet(linkAttr)) {
    m = dynamic_cast<MechanicalObject*>(c.linkedComponent(linkAttr));
    if (!m) throw c.error(linkAttr, "does not link to a MechanicalObject");
  } else {
    m = c.node().findInContext<MechanicalObject>();
    if (!m) throw c.error("no MechanicalObject in its node or above");
  }
  c.scene().initComponent(*m);
  return *m;
}

Topology& contextTopology(Component& c, const std::string& attr, bool allowHexa) {
  if (c.spec().find(attr) && c.attrs().isSet(attr)) {
    auto* t = dynamic_cast<Topology*>(c.linkedComponent(attr));
    if (!t) throw c.error(attr, "does not link to a topology (loader, grid or container)");
    return *t;
  }
  Topology* hexa = nullptr;
  for (const Node* n = &c.node(); n; n = n->parent()) {
    const auto& comps = n->components();
    for (auto it = comps.rbegin(); it != comps.rend(); ++it) {
      auto* t = dynamic_cast<Topology*>(it->get());
      if (!t) continue;
      c.scene().initComponent(**it);
      if (t->tetrahedra().cols() > 0) return *t;
      if (!hexa && !t->hexahedra().empty()) hexa = t;
    }
    if (hexa && allowHexa) return *hexa;
  }
  throw c.error("no topology with tetrahedra in its node or above");
}

Topology& contextHexahedra(Component& c, const std::string& attr) {
  if (c.spec().find(attr) && c.attrs().isSet(attr)) {
    auto* t = dynamic_cast<Topology*>(c.linkedComponent(attr));
    if (!t) throw c.error(attr, "does not link to a topology");
    c.scene().initComponent(dynamic_cast<Component&>(*t));
    if (t->hexahedra().empty()) throw c.error(attr, "links to a topology without hexahedra");
    return *t;
  }
  for (const Node* n = &c.node(); n; n = n->parent())
    for (auto it = n->components().rbegin(); it != n->components().rend(); ++it)
      if (auto* t = dynamic_cast<Topology*>(it->get())) {
        c.scene().initComponent(**it);
        if (!t->hexahedra().empty()) return *t;
      }
  throw c.error("no topology with hexahedra in its node or above (a RegularGridTopology, or a loader with hexahedra)");
}

void registerMechanicalObject(Registry& r) {
  ComponentSpec s;
  s.name = "MechanicalObject";
  s.category = "state";
  s.doc = "Degrees of freedom of a body. Vec3d: the nodes of a deformable body (positions, velocities, rest "
          "positions; positions default to those of the topology in the same node). Rigid3d: one rigid frame "
          "(x y z qx qy qz qw), the instrument, moved by a driver (TrajectoryDriver, LinearMovementConstraint).";
  s.add(AttrSpec::choice("template", {"Vec3d", "Vec3", "Vec3f", "Rigid3d", "Rigid3", "Rigid3f"}).def("Vec3d").help("state type; the f variants are computed in double precision"));
  s.add(AttrSpec::link("src").help("a loader or topology whose points are the initial positions (Vec3d)"));
  s.add(AttrSpec::reals("position").unit(Dimension::length()).linked().help("initial positions x y z ... (Rigid3d: x y z qx qy qz qw), or a link"));
  s.add(AttrSpec::reals("rest_position").unit(Dimension::length()).linked().help("rest positions (default: initial positions; Vec3d only)"));
  s.add(AttrSpec::reals("velocity").unit(Dimension::velocity()).linked().help("initial velocity: one for all nodes or one per node (Rigid3d: vx vy vz wx wy wz)"));
  addPointPlacementAttributes(s, "the initial positions");
  s.add(AttrSpec::real("restScale").def("1").above(0).help(
      "scale of the rest positions about the origin (Vec3d; below 1 the body starts stretched: SOFA's pre-tension)"));
  // SOFA writes these work vectors into saved scenes; they are recomputed every step there too.
  for (const char* work : {"force", "derivX", "free_position", "free_velocity"})
    s.add(AttrSpec::reals(work).help("accepted for SOFA scenes: recomputed every step, so a value given has no effect (as in SOFA)"));
  s.add(AttrSpec::reals("externalForce").help("SOFA's external force vector: only zeros are accepted (a non-zero value is not supported)"));
  s.factory = [](BuildContext& ctx) -> std::unique_ptr<Component> {
    if (isRigidTemplate(ctx.attrs().str("template"))) return std::make_unique<RigidObject>(ctx);
    return std::make_unique<MechanicalObject>(ctx);
  };
  r.add(std::move(s));
}

}  // namespace viscera
