#include "engine/rigid/RigidObject.h"

#include <cmath>

#include "core/Scene.h"

namespace viscera {

bool isRigidTemplate(const std::string& t) { return t == "Rigid3d" || t == "Rigid3" || t == "Rigid3f"; }

void RigidObject::init() {
  if (attrs_.real("restScale") != 1.0) throw error("restScale", "applies to Vec3d objects; a rigid frame has no rest shape to scale");
  for (double f : attrs_.reals("externalForce"))
    if (f != 0) throw error("externalForce", "a non-zero external force is not supported");
  std::vector<double> pos = attrs_.isSet("position") ? linkedReals("position") : std::vector<double>{0, 0, 0, 0, 0, 0, 1};
  if (pos.size() != 7)
    throw error("position", "a Rigid3d object holds one frame: 7 numbers x y z qx qy qz qw (got " +
                                std::to_string(pos.size()) + ")");
  Eigen::Quaterniond rot(pos[6], pos[3], pos[4], pos[5]);
  if (!(rot.norm() > 1e-12)) throw error("position", "the orientation quaternion is zero");
  rot.normalize();
  Eigen::Vector3d at(pos[0], pos[1], pos[2]);
  // Placement, as for Vec3d objects: scale the position, then rotate, then translate.
  const auto& s = attrs_.reals("scale3d");
  const auto& r = attrs_.reals("rotation");
  const auto& t = attrs_.reals("translation");
  const Eigen::Quaterniond R = Eigen::AngleAxisd(r[2] * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(r[1] * M_PI / 180, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(r[0] * M_PI / 180, Eigen::Vector3d::UnitX());
  p0 = R * Eigen::Vector3d(s[0] * at.x(), s[1] * at.y(), s[2] * at.z()) + Eigen::Vector3d(t[0], t[1], t[2]);
  q0 = (R * rot).normalized();
  if (attrs_.isSet("velocity")) {
    auto vel = linkedReals("velocity");
    if (vel.size() != 6)
      throw error("velocity", "a Rigid3d velocity is 6 numbers: vx vy vz wx wy wz (got " + std::to_string(vel.size()) + ")");
    start.v = Eigen::Vector3d(vel[0], vel[1], vel[2]);
    start.w = Eigen::Vector3d(vel[3], vel[4], vel[5]);
  }
  start.p = p0;
  start.q = q0;
  // SOFA writes a rigid body's rest pose beside its pose; nothing here has a rest pose of a rigid
  // body, so only the same pose is accepted.
  if (attrs_.isSet("rest_position")) {
    auto rest = linkedReals("rest_position");
    bool same = rest.size() == 7;
    for (size_t k = 0; same && k < 7; ++k) same = std::abs(rest[k] - pos[k]) <= 1e-12 * (1 + std::abs(pos[k]));
    if (!same) throw error("rest_position", "differs from position; a Rigid3d body's rest pose is not used here, give the same pose or none");
  }
}

void RigidObject::Live::setMotion(const Eigen::Vector3d& pos, const Eigen::Quaterniond& rot, const Eigen::Vector3d& lin,
                                  const Eigen::Vector3d& ang) {
  p = pos;
  q = rot.normalized();
  v = lin;
  w = ang;
}

std::unique_ptr<ComponentState> RigidObject::initialState() const {
  return std::make_unique<Live>(start);
}

void RigidObject::Live::save(StateWriter& out) const {
  out.put(p);
  out.put(q.coeffs());
  out.put(v);
  out.put(w);
  out.put(force);
  out.put(torque);
  out.put(contacts);
}

void RigidObject::Live::load(StateReader& in) {
  Eigen::Vector4d qc;
  in.get(p);
  in.get(qc);
  q.coeffs() = qc;
  in.get(v);
  in.get(w);
  in.get(force);
  in.get(torque);
  in.get(contacts);
}

bool RigidObject::field(const std::string& name, FieldValue& out) const {
  if (name == "position" || name == "rest_position") out.values = {p0.x(), p0.y(), p0.z(), q0.x(), q0.y(), q0.z(), q0.w()};
  else if (name == "velocity") out.values = {start.v.x(), start.v.y(), start.v.z(), start.w.x(), start.w.y(), start.w.z()};
  else return false;
  return true;
}

RigidObject& contextRigid(Component& c, const std::string& attr) {
  RigidObject* r = nullptr;
  if (c.spec().find(attr) && c.attrs().isSet(attr)) {
    r = dynamic_cast<RigidObject*>(c.linkedComponent(attr));
    if (!r) throw c.error(attr, "does not link to a MechanicalObject with template=\"Rigid3d\"");
  } else {
    r = c.node().findInContext<RigidObject>();
    if (!r) throw c.error("no rigid body (MechanicalObject template=\"Rigid3d\") in its node or above");
  }
  c.scene().initComponent(*r);
  return *r;
}

}  // namespace viscera
