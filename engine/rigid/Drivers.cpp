// Kinematic drivers of rigid bodies: TrajectoryDriver (a timed pose CSV, interpolated) and SOFA's
// LinearMovementConstraint (key times with displacements from the initial pose).
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "engine/Roles.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/Placement.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/InputCache.h"
#include "motion/Trajectory.h"

namespace viscera {

namespace {

class TrajectoryDriver : public Component, public Driver {
 public:
  using Component::Component;
  void init() override {
    body_ = &contextRigid(*this);
    if (body_->driven) throw error("object", "'" + body_->name() + "' already has a driver");
    body_->driven = true;
    const std::string path = scene().resolvePath(attrs_.str("filename"));
    try {
      traj_ = io::cachedRead<motion::Trajectory>(path, motion::readTrajectoryCsv);
    } catch (const Error& e) {
      throw fileErrorFor(e, *this, "filename");
    }
    offset_ = attrs_.real("timeOffset");
    place_ = readPlacement(*this);
    body_->start = motionAt(scene().startTime(), scene().dt());
    body_->p0 = body_->start.p;
    body_->q0 = body_->start.q;
  }
  // The pose at t and, as velocity, the mean over the step that ends at t (drive is called with
  // each step's end time): velocity x dt is the step's displacement, which the friction
  // constraints compare the tissue's motion with. Within a sample interval this is the
  // interpolation's velocity; at a sample time it is that of the interval ending there.
  void drive(State& s, double t, double h) const override {
    RigidObject::Live& b = body_->live(s);
    const RigidObject::Live m = motionAt(t, h);
    b.setMotion(m.p, m.q, m.v, m.w);
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "duration") out.values = {traj_->end() - offset_};
    else return false;
    return true;
  }

 private:
  RigidObject::Live motionAt(double t, double h) const {
    const double tt = t + offset_;
    const motion::Pose pose = traj_->sample(tt), before = traj_->sample(tt - h);
    RigidObject::Live m;
    m.setMotion(place_.point(pose.p), place_.rotation(pose.q), place_.vector((pose.p - before.p) / h),
                place_.vector(rotationVector(before.q, pose.q) / h));
    return m;
  }

  RigidObject* body_ = nullptr;
  std::shared_ptr<const motion::Trajectory> traj_;  // shared by every scene that replays the file
  double offset_ = 0;
  Placement place_;
};

class LinearMovementConstraint : public Component, public Driver {
 public:
  using Component::Component;
  void init() override {
    body_ = &contextRigid(*this, "mstate");
    if (body_->driven) throw error("'" + body_->name() + "' already has a driver");
    body_->driven = true;
    for (int i : attrs_.ints("indices"))
      if (i != 0) throw error("indices", "a Rigid3d object has one frame (index 0), got " + std::to_string(i));
    times_ = attrs_.reals("keyTimes");
    const auto& m = attrs_.reals("movements");
    if (times_.empty()) throw error("keyTimes", "needs at least one key time");
    for (size_t k = 1; k < times_.size(); ++k)
      if (!(times_[k] > times_[k - 1]))
        throw error("keyTimes", "must increase (key " + std::to_string(k) + " at " + std::to_string(times_[k]) +
                                    " follows " + std::to_string(times_[k - 1]) + ")");
    if (m.size() != 6 * times_.size())
      throw error("movements", "needs 6 numbers (dx dy dz rx ry rz) per key time: " + std::to_string(times_.size()) +
                                   " key times, " + std::to_string(m.size()) + " numbers");
    for (size_t k = 0; k < times_.size(); ++k) {
      d_.emplace_back(m[6 * k], m[6 * k + 1], m[6 * k + 2]);
      r_.emplace_back(m[6 * k + 3], m[6 * k + 4], m[6 * k + 5]);
    }
    relative_ = attrs_.boolean("relativeMovements");
    motionAt(scene().startTime(), scene().dt(), body_->start);
  }
  // Piecewise-linear displacement and rotation vector between keys, held outside them. The
  // velocity is the mean over the step that ends at t (drive is called with each step's end
  // time): velocity x dt is the step's displacement, which the friction constraints compare the
  // tissue's motion with. Within a key interval this is the interval's rate; at a key time it is
  // that of the interval ending there, not of the next one.
  void drive(State& s, double t, double h) const override { motionAt(t, h, body_->live(s)); }

 private:
  void motionAt(double t, double h, RigidObject::Live& b) const {
    Eigen::Vector3d d, r, dBefore, rBefore;
    at(t, d, r);
    at(t - h, dBefore, rBefore);
    const Eigen::Vector3d vd = (d - dBefore) / h, vr = (r - rBefore) / h;
    const Eigen::Quaterniond rot = r.norm() > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(r.norm(), r.normalized()))
                                                : Eigen::Quaterniond::Identity();
    if (relative_) b.setMotion(body_->p0 + d, rot * body_->q0, vd, vr);
    else b.setMotion(d, rot, vd, vr);
  }
  // Displacement and rotation vector at time t.
  void at(double t, Eigen::Vector3d& d, Eigen::Vector3d& r) const {
    if (t <= times_.front()) {
      d = d_.front();
      r = r_.front();
    } else if (t >= times_.back()) {
      d = d_.back();
      r = r_.back();
    } else {
      const size_t k = std::upper_bound(times_.begin(), times_.end(), t) - times_.begin() - 1;
      const double a = (t - times_[k]) / (times_[k + 1] - times_[k]);
      d = (1 - a) * d_[k] + a * d_[k + 1];
      r = (1 - a) * r_[k] + a * r_[k + 1];
    }
  }

  RigidObject* body_ = nullptr;
  std::vector<double> times_;
  std::vector<Eigen::Vector3d> d_, r_;
  bool relative_ = true;
};

// SOFA's LinearVelocityProjectiveConstraint on a Rigid3d body: between key times the body's
// velocity is interpolated linearly from the keys' velocities (held at the last one after the
// end with continueAfterEnd); the body moves with it, and outside the keys it is free.
class LinearVelocityConstraint : public Component {
 public:
  using Component::Component;
  void init() override {
    if (node().find<MechanicalObject>() && !node().find<RigidObject>())
      throw error("acts on a Rigid3d body here (a MechanicalObject template=\"Rigid3d\" in its node)");
    body_ = &contextRigid(*this, "mstate");
    for (int i : attrs_.ints("indices"))
      if (i != 0) throw error("indices", "a Rigid3d object has one frame (index 0), got " + std::to_string(i));
    if (attrs_.isSet("coordinates")) throw error("coordinates", "only the whole velocity (all six components) is prescribed here");
    times_ = attrs_.reals("keyTimes");
    for (size_t k = 1; k < times_.size(); ++k)
      if (!(times_[k] > times_[k - 1])) throw error("keyTimes", "must increase");
    const auto& v = attrs_.reals("velocities");
    if (v.size() != 6 * times_.size())
      throw error("velocities", "needs 6 numbers (vx vy vz wx wy wz) per key time: " + std::to_string(times_.size()) +
                                    " key times, " + std::to_string(v.size()) + " numbers");
    for (size_t k = 0; k < times_.size(); ++k) {
      v_.emplace_back(v[6 * k], v[6 * k + 1], v[6 * k + 2]);
      w_.emplace_back(v[6 * k + 3], v[6 * k + 4], v[6 * k + 5]);
    }
    const bool keep = attrs_.boolean("continueAfterEnd");
    if (body_->prescribedVelocity) throw error("rigid body '" + body_->name() + "' already has a prescribed velocity");
    body_->prescribedVelocity = [this, keep](double t, Eigen::Vector3d& v, Eigen::Vector3d& w) {
      if (t < times_.front() || (t >= times_.back() && !keep)) return false;
      if (t >= times_.back()) {
        v = v_.back();
        w = w_.back();
        return true;
      }
      const size_t k = std::upper_bound(times_.begin(), times_.end(), t) - times_.begin() - 1;
      const double a = (t - times_[k]) / (times_[k + 1] - times_[k]);
      v = (1 - a) * v_[k] + a * v_[k + 1];
      w = (1 - a) * w_[k] + a * w_[k + 1];
      return true;
    };
  }

 private:
  RigidObject* body_ = nullptr;
  std::vector<double> times_;
  std::vector<Eigen::Vector3d> v_, w_;
};

}  // namespace

void registerDrivers(Registry& r) {
  {
    ComponentSpec s;
    s.name = "LinearVelocityProjectiveConstraint";
    s.aliases = {"LinearVelocityConstraint"};
    s.category = "constraint";
    s.doc = "Prescribes an integrated rigid body's velocity (SOFA's LinearVelocityProjectiveConstraint): at each key time "
            "a velocity vx vy vz wx wy wz, linear in between; over a step that starts at t the body moves with the "
            "velocity at t. Before the first key, and after the last unless continueAfterEnd, the body is free.";
    s.add(AttrSpec::reals("keyTimes").req().unit(Dimension::time()).help("key times, increasing"));
    s.add(AttrSpec::reals("velocities").req().help("6 numbers per key time: vx vy vz wx wy wz"));
    s.add(AttrSpec::ints("indices").def("0").help("the frame (a Rigid3d object has one: 0)"));
    s.add(AttrSpec::boolean("continueAfterEnd").def("false").help("keep the last velocity after the last key time"));
    s.add(AttrSpec::ints("coordinates").help("SOFA's subset of components; only all six are supported"));
    s.add(AttrSpec::link("mstate").help("the Rigid3d MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<LinearVelocityConstraint>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "TrajectoryDriver";
    s.category = "driver";
    s.doc = "Moves a rigid body (the instrument) along a recorded trajectory: a CSV of t,x,y,z,qx,qy,qz,qw rows in "
            "the scene's units (header optional). Positions are interpolated linearly and orientations by slerp "
            "between samples. Before the first sample and after the last the pose is held. The body's velocity is the "
            "mean over each time step (the step's displacement / dt), which is the interpolation's velocity within a "
            "sample interval. The trajectory may be placed in the scene by a `transform` file (robot -> scene, e.g. "
            "from `viscera register points`), then `rotation`, then `translation`: x_scene = R_rot (R_file x + t_file) + "
            "t; orientations are turned by R_rot R_file.";
    s.add(AttrSpec::file("filename").req().help("trajectory CSV (t,x,y,z,qx,qy,qz,qw)"));
    s.add(AttrSpec::link("object").help("the Rigid3d MechanicalObject (default: the one in the node)"));
    s.add(AttrSpec::real("timeOffset").def("0").unit(Dimension::time()).help("trajectory time = scene time + timeOffset"));
    addPlacementAttributes(s, "the trajectory");
    s.factory = [](BuildContext& c) { return std::make_unique<TrajectoryDriver>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "LinearMovementConstraint";
    s.aliases = {"LinearMovementProjectiveConstraint"};
    s.category = "driver";
    s.doc = "Moves a rigid body through key frames (SOFA's LinearMovementConstraint): at each key time a "
            "displacement dx dy dz and a rotation vector rx ry rz (radians) from the initial pose; linear in "
            "between, held outside. The velocity is the mean over each time step (the step's displacement / dt); the "
            "angular velocity is the rate of the rotation vector (exact for a fixed axis).";
    s.add(AttrSpec::reals("keyTimes").req().unit(Dimension::time()).help("key times, increasing"));
    s.add(AttrSpec::reals("movements").req().help("6 numbers per key time: dx dy dz rx ry rz"));
    s.add(AttrSpec::ints("indices").def("0").help("the frame moved (a Rigid3d object has one: 0)"));
    s.add(AttrSpec::boolean("relativeMovements").def("true").help("movements are from the initial pose (false: absolute poses)"));
    s.add(AttrSpec::link("mstate").help("the Rigid3d MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<LinearMovementConstraint>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
