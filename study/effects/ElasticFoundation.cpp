// `elasticFoundation`: the tissue rests on a compliant support rather than a rigid one. The
// FixedConstraints holding the tissue become RestShapeSpringsForceFields (SOFA's name) on the same
// nodes; one parameter, the stiffness of each spring, searched over decades around the stiffness
// the tissue itself gives a node (E times a tenth of the tissue's size).
#include <algorithm>

#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

class ElasticFoundation : public Effect {
 public:
  std::string key() const override { return "elasticFoundation"; }
  std::string what() const override {
    return "a compliant support: the fixed nodes held by RestShapeSpringsForceField springs of stiffness k";
  }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    SceneDesc d = s.desc;
    const auto fixed = supports(d.root);
    const auto fems = elementsOf(d.root, "TetrahedronFEMForceField");
    if (fixed.empty() || fems.empty() || s.tissueBox.isEmpty() || isLink(*fems.front(), "youngModulus")) return {};
    const double E = realsOf(*fems.front(), "youngModulus", s.units).at(0);
    const double k = E * s.tissueBox.sizes().maxCoeff() / 10;
    return {{"stiffness", 1e-2 * k, 1e3 * k, 1e3 * k, Scale::Log, "scene stiffness"}};
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene&) const override {
    for (ElementDesc* f : supports(desc.root)) {
      f->tag = "RestShapeSpringsForceField";
      for (auto& a : f->attrs)
        if (a.name == "indices") a.name = "points";
      f->set("stiffness", numberText(v.at(0)));
      noteChange(*f, key(), "FixedConstraint replaced by springs of stiffness " + numberText(v.at(0)));
    }
  }

 private:
  // FixedConstraints that hold chosen nodes (fixAll holds a body still: not a support).
  static std::vector<ElementDesc*> supports(ElementDesc& root) {
    std::vector<ElementDesc*> out;
    for (ElementDesc* f : elementsOf(root, "FixedConstraint")) {
      const AttrDesc* all = f->find("fixAll");
      if (all && (all->value == "true" || all->value == "1")) continue;
      if (f->find("indices")) out.push_back(f);
    }
    return out;
  }
};

}  // namespace

std::unique_ptr<Effect> makeElasticFoundation() { return std::make_unique<ElasticFoundation>(); }

}  // namespace viscera::study
