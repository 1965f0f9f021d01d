// `registration`: the camera -> scene transform is off (an ICP that settled a little wrong, a
// camera that moved). Six parameters, a rigid correction applied to every cloud in the scene
// frame: a rotation (degrees, about x, then y, then z, about the tissue's centre) and a
// translation, each within a few millimetres or degrees. It changes no scene component: the audit
// writes the corrected transform beside its report.
#include <Eigen/Geometry>
#include <cmath>

#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

class Registration : public Effect {
 public:
  std::string key() const override { return "registration"; }
  std::string what() const override { return "a rigid correction of the camera -> scene transform (3 rotations, 3 translations)"; }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    if (s.tissueBox.isEmpty()) return {};
    const double mm = 1e-3 / s.units.siOf(Dimension::length());
    std::vector<EffectParam> p;
    for (const char* a : {"rx", "ry", "rz"}) p.push_back({a, -3.0, 3.0, 0.0, Scale::Linear, "deg"});
    for (const char* a : {"tx", "ty", "tz"}) p.push_back({a, -5 * mm, 5 * mm, 0.0, Scale::Linear, "scene length"});
    return p;
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene&) const override {
    noteChange(desc.root, key(), "clouds corrected by rotation (" + numberText(v.at(0)) + ", " + numberText(v.at(1)) + ", " +
                                     numberText(v.at(2)) + ") deg and translation (" + numberText(v.at(3)) + ", " +
                                     numberText(v.at(4)) + ", " + numberText(v.at(5)) + ")");
  }
  bool changesSimulation() const override { return false; }
  std::optional<RigidTransform> cloudCorrection(const std::vector<double>& v, const AuditScene& s) const override {
    const Eigen::Vector3d centre = s.tissueBox.center();
    const double d = M_PI / 180;
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(v.at(2) * d, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(v.at(1) * d, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(v.at(0) * d, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    RigidTransform T = RigidTransform::Identity();
    T.linear() = R;
    // About the tissue's centre: x' = R (x - c) + c + t.
    T.translation() = centre - R * centre + Eigen::Vector3d(v.at(3), v.at(4), v.at(5));
    return T;
  }
};

}  // namespace

std::unique_ptr<Effect> makeRegistration() { return std::make_unique<Registration>(); }

}  // namespace viscera::study
