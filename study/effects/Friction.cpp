// `friction`: the instrument slides more or less on the tissue than the scene's Coulomb
// coefficient says. One parameter, mu in the CollisionResponse's responseParams ("mu=0.9"); only
// for scenes with friction contact.
#include <regex>

#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

const std::regex kMu("mu\\s*=\\s*([-+0-9.eE]+)");

class Friction : public Effect {
 public:
  std::string key() const override { return "friction"; }
  std::string what() const override { return "the Coulomb friction coefficient mu of the contact response"; }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    SceneDesc d = s.desc;
    for (ElementDesc* r : elementsOf(d.root, "CollisionResponse")) {
      const AttrDesc* p = r->find("responseParams");
      std::smatch m;
      if (p && std::regex_search(p->value, m, kMu)) return {{"mu", 0.0, 2.0, std::stod(m[1].str()), Scale::Linear, ""}};
    }
    return {};
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene&) const override {
    for (ElementDesc* r : elementsOf(desc.root, "CollisionResponse")) {
      const AttrDesc* p = r->find("responseParams");
      if (!p) continue;
      r->set("responseParams", std::regex_replace(p->value, kMu, "mu=" + numberText(v.at(0))));
      noteChange(*r, key(), "mu " + numberText(v.at(0)));
    }
  }
};

}  // namespace

std::unique_ptr<Effect> makeFriction() { return std::make_unique<Friction>(); }

}  // namespace viscera::study
