// `youngModulus`: the tissue is stiffer or softer than the scene says. One parameter, a factor on
// every TetrahedronFEMForceField's Young's modulus (per-element lists scaled alike).
#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

class YoungModulus : public Effect {
 public:
  std::string key() const override { return "youngModulus"; }
  std::string what() const override { return "a factor on the Young's modulus of every FEM force field"; }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    SceneDesc d = s.desc;
    const auto fems = elementsOf(d.root, "TetrahedronFEMForceField");
    if (fems.empty()) return {};
    for (ElementDesc* f : fems)
      if (isLink(*f, "youngModulus")) return {};  // set by engines: not ours to rewrite
    return {{"scale", 0.1, 10.0, 1.0, Scale::Log, ""}};
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene& s) const override {
    for (ElementDesc* fem : elementsOf(desc.root, "TetrahedronFEMForceField")) {
      std::string text;
      for (double e : realsOf(*fem, "youngModulus", s.units)) text += (text.empty() ? "" : " ") + numberText(e * v.at(0));
      fem->set("youngModulus", text);
      noteChange(*fem, key(), "Young's modulus x " + numberText(v.at(0)));
    }
  }
};

}  // namespace

std::unique_ptr<Effect> makeYoungModulus() { return std::make_unique<YoungModulus>(); }

}  // namespace viscera::study
