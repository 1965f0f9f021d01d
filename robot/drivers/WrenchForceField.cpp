// WrenchForceField: a force measured or estimated at the instrument's tip (a wrench log, e.g. from
// `viscera force estimate`) applied to the tissue where the instrument is, instead of (or beside)
// the kinematic contact of its collision sphere.
#include <Eigen/Geometry>
#include <algorithm>
#include <vector>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/Roles.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/Placement.h"
#include "engine/rigid/RigidObject.h"
#include "robot/force/ArmLogs.h"

namespace viscera {

namespace {

class WrenchForceField : public Component, public ForceField {
 public:
  using Component::Component;
  bool assemblesUpper() const override { return true; }  // adds no stiffness
  MechanicalObject& mstate() const override { return *state_; }

  void init() override {
    state_ = &contextState(*this);
    instrument_ = &contextRigid(*this, "instrument");
    const std::string path = scene().resolvePath(attrs_.str("filename"));
    try {
      wrench_ = robot::readWrenchCsv(path);
    } catch (const Error& e) {
      throw fileErrorFor(e, *this, "filename");
    }
    place_ = readPlacement(*this);
    newtonsToScene_ = 1.0 / scene().units().siOf(Dimension::force()) * attrs_.real("scale");
    radius_ = attrs_.real("radius");
    if (!(radius_ > 0)) throw error("radius", "must be positive");
    offset_ = attrs_.real("timeOffset");
  }

  // The force at the time the instrument was driven to (the end of the step), spread over the nodes
  // within `radius` of the instrument with weights falling linearly to zero at the radius (the
  // nearest node alone when none is that close). Explicit: no stiffness.
  void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    const double t = std::clamp(s.time + scene().dt() + offset_, wrench_.t.front(), wrench_.t.back());
    const Eigen::Vector3d force = place_.vector(robot::interpolate(wrench_, {t}).values.row(0).head<3>().transpose()) * newtonsToScene_;
    if (force.squaredNorm() == 0) return;
    const Eigen::Vector3d tip = instrument_->live(s).p;
    std::vector<std::pair<int, double>> weights;
    double sum = 0;
    int nearest = 0;
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < static_cast<int>(x.cols()); ++i) {
      const double d = (x.col(i) - tip).norm();
      if (d < best) best = d, nearest = i;
      if (d < radius_) {
        weights.emplace_back(i, 1 - d / radius_);
        sum += 1 - d / radius_;
      }
    }
    if (weights.empty()) {
      f.col(nearest) += force;
      return;
    }
    for (const auto& [i, w] : weights) f.col(i) += force * (w / sum);
  }

 private:
  MechanicalObject* state_ = nullptr;
  RigidObject* instrument_ = nullptr;
  robot::Series wrench_;
  Placement place_;
  double newtonsToScene_ = 1, radius_ = 1, offset_ = 0;
};

}  // namespace

void registerForceDrivers(Registry& r) {
  ComponentSpec s;
  s.name = "WrenchForceField";
  s.category = "forcefield";
  s.doc = "Applies the force of a wrench log (t,Fx,Fy,Fz,Tx,Ty,Tz; s, N; the tool's force on the tissue, robot base "
          "frame, as `viscera force estimate` writes it or a force sensor measures it) to the body where the "
          "instrument is: spread over the nodes within `radius` of the instrument's position, weighted linearly to "
          "zero at the radius (the nearest node when none is that close). The force is interpolated linearly in time "
          "(held outside the log), turned into the scene frame by `transform` / `rotation` (the robot -> scene "
          "registration; translation does not apply to a force) and converted from N to the scene's force unit. With "
          "the instrument's collision model off, the estimated force replaces the kinematic contact; with it on, both "
          "act. Torques are not applied.";
  s.add(AttrSpec::file("filename").req().help("wrench log CSV (t,Fx,Fy,Fz,Tx,Ty,Tz; N, N m)"));
  s.add(AttrSpec::link("instrument").help("the instrument's Rigid3d MechanicalObject (default: the nearest in context)"));
  s.add(AttrSpec::real("radius").def("1").unit(Dimension::length()).help("nodes within this distance of the instrument share the force"));
  s.add(AttrSpec::real("scale").def("1").help("factor on the force"));
  s.add(AttrSpec::real("timeOffset").def("0").unit(Dimension::time()).help("log time = scene time + timeOffset"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
  addPlacementAttributes(s, "the forces (robot base frame)");
  s.factory = [](BuildContext& c) { return std::make_unique<WrenchForceField>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
