// `instrumentRadius`: the instrument's tip is larger or smaller than modelled (a worn or coated
// tip, a wrong CAD size). One parameter, the radius of every SphereCollisionModel.
#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

class InstrumentRadius : public Effect {
 public:
  std::string key() const override { return "instrumentRadius"; }
  std::string what() const override { return "the radius of the instrument's sphere"; }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    if (!(s.instrumentRadius > 0)) return {};
    const double r = s.instrumentRadius;
    return {{"radius", 0.5 * r, 1.5 * r, r, Scale::Linear, "scene length"}};
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene&) const override {
    for (ElementDesc* sphere : elementsOf(desc.root, "SphereCollisionModel")) {
      sphere->set("radius", numberText(v.at(0)));
      noteChange(*sphere, key(), "radius " + numberText(v.at(0)));
    }
  }
};

}  // namespace

std::unique_ptr<Effect> makeInstrumentRadius() { return std::make_unique<InstrumentRadius>(); }

}  // namespace viscera::study
