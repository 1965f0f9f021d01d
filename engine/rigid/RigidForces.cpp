// Forces on a rigid body's frame (RigidForce): RestShapeSpringsForceField on a Rigid3d state
// (a translational and an angular spring back to a rest pose, its own initial one or another
// body's) and LinearForceField on a Rigid3d state (a force and torque interpolated between key
// times). The Vec3d forms of both act on nodes (ForceField).
#include <Eigen/Geometry>
#include <algorithm>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidDynamics.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

namespace {

// The rigid body a force acts on; a force no solver would apply is refused.
RigidObject& solvedBody(Component& c) {
  RigidObject& body = contextRigid(c, "mstate");
  if (!body.node().find<OdeSolver>())
    throw c.error("no ODE solver in the node of rigid body '" + body.name() + "' integrates it: the force would be ignored");
  return body;
}

// Only frame 0: a Rigid3d MechanicalObject here is one body.
void checkFrameZero(Component& c, const char* attr) {
  if (!c.spec().find(attr) || !c.attrs().isSet(attr)) return;
  for (int i : c.linkedInts(attr))
    if (i != 0) throw c.error(attr, "a Rigid3d object has one frame (index 0), got " + std::to_string(i));
}

// Six flags (x y z, then rotation about x y z) from SOFA's activeDirections (Vec3d: three;
// Rigid3d: seven, the last unused, as in SOFA).
std::array<bool, 6> activeDirections(Component& c, bool rigid) {
  std::array<bool, 6> on{true, true, true, true, true, true};
  if (!c.attrs().isSet("activeDirections")) return on;
  const auto& d = c.attrs().ints("activeDirections");
  const size_t want = rigid ? 7 : 3;
  if (d.size() != want && !(rigid && d.size() == 6))
    throw c.error("activeDirections", std::string("takes ") + (rigid ? "7 flags on a Rigid3d state (x y z, rotation x y z, "
                                                                        "and SOFA's unused seventh)"
                                                                      : "3 flags on a Vec3d state (x y z)") +
                                          ", got " + std::to_string(d.size()));
  for (size_t k = 0; k < std::min<size_t>(d.size(), 6); ++k) on[k] = d[k] != 0;
  return on;
}

class RigidRestShapeSprings : public Component, public RigidForce {
 public:
  using Component::Component;
  const RigidObject& body() const override { return *body_; }
  void init() override {
    body_ = &solvedBody(*this);
    checkFrameZero(*this, "points");
    checkFrameZero(*this, "external_points");
    const auto& k = attrs_.reals("stiffness");
    if (k.size() != 1) throw error("stiffness", "takes one value on a Rigid3d body, got " + std::to_string(k.size()));
    k_ = k[0];
    if (!attrs_.isSet("angularStiffness")) throw error("angularStiffness", "is needed on a Rigid3d body (the torque per radian)");
    const auto& ka = attrs_.reals("angularStiffness");
    if (ka.size() != 1) throw error("angularStiffness", "takes one value, got " + std::to_string(ka.size()));
    kAngle_ = ka[0];
    active_ = activeDirections(*this, true);
    if (attrs_.isSet("external_rest_shape")) {
      rest_ = dynamic_cast<RigidObject*>(linkedComponent("external_rest_shape"));
      if (!rest_) throw error("external_rest_shape", "does not link to a Rigid3d MechanicalObject");
      scene().initComponent(*rest_);
    }
  }
  // F = -k (p - p0), T = -k_a angle axis of q q0^-1 (the shortest turn), inactive directions zeroed.
  void addWrench(const State& s, Eigen::Vector3d& force, Eigen::Vector3d& torque) const override {
    const RigidObject::Live& b = body_->live(s);
    Eigen::Vector3d p0;
    Eigen::Quaterniond q0;
    restPose(s, p0, q0);
    Eigen::Vector3d dx = b.p - p0;
    Eigen::Quaterniond dq = (b.q * q0.inverse()).normalized();
    if (dq.w() < 0) dq.coeffs() *= -1;
    const Eigen::AngleAxisd turn(dq);
    Eigen::Vector3d rot = turn.angle() > 0 ? Eigen::Vector3d(turn.axis() * turn.angle()) : Eigen::Vector3d::Zero();
    for (int a = 0; a < 3; ++a) {
      if (!active_[a]) dx[a] = 0;
      if (!active_[3 + a]) rot[a] = 0;
    }
    force -= k_ * dx;
    torque -= kAngle_ * rot;
  }
  // SOFA's stiffness: -k and -k_a on the active diagonal (the angular one exact for small turns).
  void addStiffness(const State&, Eigen::Matrix<double, 6, 6>& K) const override {
    for (int a = 0; a < 3; ++a) {
      if (active_[a]) K(a, a) -= k_;
      if (active_[3 + a]) K(3 + a, 3 + a) -= kAngle_;
    }
  }

 private:
  void restPose(const State& s, Eigen::Vector3d& p, Eigen::Quaterniond& q) const {
    if (rest_) {
      const RigidObject::Live& r = rest_->live(s);
      p = r.p;
      q = r.q;
    } else {
      p = body_->p0;
      q = body_->q0;
    }
  }

  RigidObject* body_ = nullptr;
  RigidObject* rest_ = nullptr;  // another body whose pose is the rest pose
  double k_ = 0, kAngle_ = 0;
  std::array<bool, 6> active_{};
};

// SOFA's LinearForceField: forces at key times, linearly interpolated, scaled by `force`; none
// before the first key, the last one after the last key. SOFA reads the time at the step's start.
struct KeyForces {
  std::vector<double> times;
  std::vector<Eigen::VectorXd> values;  // one per key time
  double scale = 1;
  Eigen::VectorXd at(double t) const {
    Eigen::VectorXd zero = Eigen::VectorXd::Zero(values.front().size());
    if (t < times.front()) return zero;
    if (t >= times.back()) return scale * values.back();
    const size_t k = static_cast<size_t>(std::upper_bound(times.begin(), times.end(), t) - times.begin()) - 1;
    const double a = (t - times[k]) / (times[k + 1] - times[k]);
    return scale * ((1 - a) * values[k] + a * values[k + 1]);
  }
};

KeyForces keyForces(Component& c, int width) {
  KeyForces kf;
  kf.times = c.attrs().reals("times");
  const auto& f = c.attrs().reals("forces");
  kf.scale = c.attrs().real("force");
  if (kf.times.empty()) throw c.error("times", "needs at least one key time");
  for (size_t k = 1; k < kf.times.size(); ++k)
    if (!(kf.times[k] > kf.times[k - 1]))
      throw c.error("times", "must increase (key " + std::to_string(k) + " at " + std::to_string(kf.times[k]) + ")");
  if (f.size() != static_cast<size_t>(width) * kf.times.size())
    throw c.error("forces", "needs " + std::to_string(width) + " numbers per key time (" + std::to_string(kf.times.size()) +
                                " key times), got " + std::to_string(f.size()));
  for (size_t k = 0; k < kf.times.size(); ++k)
    kf.values.push_back(Eigen::Map<const Eigen::VectorXd>(f.data() + width * k, width));
  return kf;
}

class RigidLinearForce : public Component, public RigidForce {
 public:
  using Component::Component;
  const RigidObject& body() const override { return *body_; }
  void init() override {
    body_ = &solvedBody(*this);
    checkFrameZero(*this, "points");
    keys_ = keyForces(*this, 6);
  }
  void addWrench(const State& s, Eigen::Vector3d& force, Eigen::Vector3d& torque) const override {
    const Eigen::VectorXd w = keys_.at(s.time);
    force += w.head<3>();
    torque += w.tail<3>();
  }

 private:
  RigidObject* body_ = nullptr;
  KeyForces keys_;
};

class LinearForceField : public Component, public ForceField {
 public:
  using Component::Component;
  bool assemblesUpper() const override { return true; }  // adds no stiffness
  MechanicalObject& mstate() const override { return *state_; }
  void init() override {
    state_ = &contextState(*this);
    nodes_ = linkedInts("points");
    for (int i : nodes_)
      if (i < 0 || i >= state_->size())
        throw error("points", "node " + std::to_string(i) + " is out of range (the MechanicalObject has " +
                                  std::to_string(state_->size()) + " nodes)");
    keys_ = keyForces(*this, 3);
  }
  void addForce(State& s, const Eigen::Matrix3Xd&, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    const Eigen::Vector3d force = keys_.at(s.time);
    for (int i : nodes_) f.col(i) += force;
  }

 private:
  MechanicalObject* state_ = nullptr;
  std::vector<int> nodes_;
  KeyForces keys_;
};

bool inRigidNode(const BuildContext& c) { return c.node().find<RigidObject>() && !c.node().find<MechanicalObject>(); }

}  // namespace

// The Rigid3d form of RestShapeSpringsForceField (its Vec3d form is in engine/mechanics).
std::unique_ptr<Component> makeRigidRestShapeSprings(BuildContext& c) {
  if (!inRigidNode(c)) return nullptr;
  return std::make_unique<RigidRestShapeSprings>(c);
}

void registerRigidForces(Registry& r) {
  ComponentSpec s;
  s.name = "LinearForceField";
  s.category = "forcefield";
  s.doc = "Forces given at key times, linearly interpolated and scaled by `force` (SOFA's LinearForceField): none before "
          "the first key time, the last one after the last; the time is the step's start, as SOFA reads it. On Vec3d "
          "nodes three numbers per key; on a Rigid3d body six (force, then torque about its origin).";
  s.add(AttrSpec::ints("points").def("0").atLeast(0).linked().help("the loaded nodes (a Rigid3d body: 0)"));
  s.add(AttrSpec::reals("times").req().unit(Dimension::time()).help("the key times, increasing"));
  s.add(AttrSpec::reals("forces").req().help("per key time: fx fy fz (Vec3d) or fx fy fz tx ty tz (Rigid3d)"));
  s.add(AttrSpec::real("force").def("1").help("a factor on every force"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
  s.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
    if (inRigidNode(c)) return std::make_unique<RigidLinearForce>(c);
    return std::make_unique<LinearForceField>(c);
  };
  r.add(std::move(s));
}

}  // namespace viscera
