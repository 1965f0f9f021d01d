// `gravity`: the tissue's weight, which the nominal scene may leave out (dissertation §4.3.4). One
// parameter, the magnitude g along the scene's gravity direction (-z when the scene has none).
#include <cmath>

#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

class Gravity : public Effect {
 public:
  std::string key() const override { return "gravity"; }
  std::string what() const override { return "the tissue's weight: the root's gravity, magnitude g"; }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    const double g = current(s).norm();
    const double si = s.units.siOf(Dimension::acceleration());
    // Up to twice Earth's, in the scene's units.
    return {{"g", 0.0, std::max(2 * 9.81 / si, 2 * g), g, Scale::Linear, "scene acceleration"}};
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene& s) const override {
    Eigen::Vector3d dir = current(s);
    dir = dir.norm() > 0 ? dir.normalized() : Eigen::Vector3d(0, 0, -1);
    const Eigen::Vector3d g = v.at(0) * dir;
    desc.root.set("gravity", numberText(g.x()) + " " + numberText(g.y()) + " " + numberText(g.z()));
    noteChange(desc.root, key(), "gravity magnitude " + numberText(v.at(0)));
  }

 private:
  static Eigen::Vector3d current(const AuditScene& s) {
    const auto g = realsOf(s.desc.root, "gravity", s.units);
    return g.size() == 3 ? Eigen::Vector3d(g[0], g[1], g[2]) : Eigen::Vector3d::Zero();
  }
};

}  // namespace

std::unique_ptr<Effect> makeGravity() { return std::make_unique<Gravity>(); }

}  // namespace viscera::study
