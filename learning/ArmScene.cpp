#include "learning/ArmScene.h"

#include <cmath>
#include <limits>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "io/scene/Transform.h"
#include "study/Replay.h"

namespace viscera::learning {

SceneEnvironment::SceneEnvironment(const std::string& scene, const std::string& transform, const std::string& instrument)
    : path_(scene) {
  SceneDesc desc = io::readScene(scene);
  study::removeOutputs(desc.root, true);
  scene_ = buildScene(desc);
  scene_->init();
  std::vector<RigidObject*> tools;
  for (RigidObject* r : scene_->all<RigidObject>())
    if (instrument.empty() || r->name() == instrument) tools.push_back(r);
  if (tools.size() != 1)
    throw Error(scene + ": " + (tools.empty() ? "no instrument (MechanicalObject template=\"Rigid3d\")" : "several instruments") +
                (instrument.empty() ? "; name one with --instrument" : " named " + quoted(instrument)));
  tool_ = tools.front();
  if (tool_->driven)
    throw Error(scene + ": the instrument '" + tool_->name() + "' has a driver; the arm moves it here, so remove the driver");
  robotToScene_ = readTransform(transform);
  sceneLengthToMetres_ = scene_->units().siOf(Dimension::length());
  metresToScene_ = 1 / sceneLengthToMetres_;
  sceneForceToNewtons_ = scene_->units().siOf(Dimension::force());
  sim_ = std::make_unique<Simulation>(*scene_);
  sim_->begin();
}

SceneEnvironment::~SceneEnvironment() {
  if (sim_) sim_->end();
}

robot::Vector6d SceneEnvironment::operator()(double t, const Eigen::Isometry3d& tip, const robot::Vector6d& twist) {
  const Eigen::Matrix3d R = robotToScene_.linear();
  const Eigen::Vector3d p = robotToScene_ * (tip.translation() * metresToScene_);
  const Eigen::Quaterniond q(R * tip.linear());
  const Eigen::Vector3d v = R * twist.head<3>() * metresToScene_, w = R * twist.tail<3>();
  while (sim_->time() + 0.5 * scene_->dt() <= t) {
    tool_->live(sim_->state()).setMotion(p, q, v, w);
    if (const auto d = sim_->step())
      throw Error(path_ + ": the scene diverged at t = " + std::to_string(d->time) + " s (" + d->reason + ")");
    const RigidObject::Live& l = tool_->live(sim_->state());
    // The tissue's wrench on the instrument, turned into the tool's on the tissue, robot frame, SI.
    last_.head<3>() = -R.transpose() * l.force * sceneForceToNewtons_;
    last_.tail<3>() = -R.transpose() * l.torque * sceneForceToNewtons_ * sceneLengthToMetres_;
  }
  return last_;
}

robot::Phantom SceneEnvironment::palpationSurface() const {
  Eigen::AlignedBox3d box;
  for (const MechanicalObject* m : scene_->all<MechanicalObject>())
    for (int i = 0; i < m->size(); ++i) box.extend(m->x0.col(i));
  if (box.isEmpty()) throw Error(path_ + ": no deformable body to palpate");
  const Eigen::Vector3d rcm = robotToScene_.translation();
  double best = -std::numeric_limits<double>::infinity();
  robot::Phantom ph;
  ph.enabled = true;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      Eigen::Vector3d n = Eigen::Vector3d::Zero();
      n[axis] = side ? 1 : -1;
      Eigen::Vector3d c = box.center();
      c[axis] = side ? box.max()[axis] : box.min()[axis];
      const double distance = (rcm - c).dot(n);
      if (distance > best) {
        best = distance;
        // Palpations stay within the face, away from its edges: 40 % of its smaller half-size.
        const int a = (axis + 1) % 3, b = (axis + 2) % 3;
        ph.radius = 0.4 * 0.5 * std::min(box.sizes()[a], box.sizes()[b]) * sceneLengthToMetres_;
        ph.point = robotToScene_.inverse() * c * sceneLengthToMetres_;
        ph.normal = robotToScene_.linear().transpose() * n;
      }
    }
  return ph;
}

int SceneEnvironment::steps() const { return sim_->steps(); }
double SceneEnvironment::dt() const { return scene_->dt(); }

}  // namespace viscera::learning
