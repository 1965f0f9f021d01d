// `poissonRatio`: the tissue is more or less compressible than the scene says. One parameter,
// Poisson's ratio of every TetrahedronFEMForceField.
#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

class PoissonRatio : public Effect {
 public:
  std::string key() const override { return "poissonRatio"; }
  std::string what() const override { return "Poisson's ratio of every FEM force field"; }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    SceneDesc d = s.desc;
    const auto fems = elementsOf(d.root, "TetrahedronFEMForceField");
    if (fems.empty()) return {};
    return {{"nu", 0.3, 0.49, realsOf(*fems.front(), "poissonRatio", s.units).at(0), Scale::Linear, ""}};
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene&) const override {
    for (ElementDesc* fem : elementsOf(desc.root, "TetrahedronFEMForceField")) {
      fem->set("poissonRatio", numberText(v.at(0)));
      noteChange(*fem, key(), "Poisson's ratio " + numberText(v.at(0)));
    }
  }
};

}  // namespace

std::unique_ptr<Effect> makePoissonRatio() { return std::make_unique<PoissonRatio>(); }

}  // namespace viscera::study
