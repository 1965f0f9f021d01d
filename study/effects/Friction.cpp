// `friction`: the instrument slides more or less on the tissue than the scene's Coulomb
// coefficient says. One parameter, mu in the CollisionResponse's responseParams ("mu=0.9"); only
// for scenes with friction contact. A constraint solver that applies its own mu (SOFA's
// LCPConstraintSolver always, 0.6 unless given; GenericConstraintSolver when given) gets it too.
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
      if (!p || !std::regex_search(p->value, m, kMu)) continue;
      double mu = std::stod(m[1].str());
      for (ElementDesc* solver : elementsOf(d.root, "GenericConstraintSolver"))  // the mu that applies
        if (const AttrDesc* given = solver->find("mu")) mu = std::stod(given->value);
        else if (solver->tag == "LCPConstraintSolver" && mu > 0) mu = 0.6;
      return {{"mu", 0.0, 2.0, mu, Scale::Linear, ""}};
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
    for (ElementDesc* solver : elementsOf(desc.root, "GenericConstraintSolver"))
      if (solver->find("mu") || solver->tag == "LCPConstraintSolver") {
        solver->set("mu", numberText(v.at(0)));
        noteChange(*solver, key(), "mu " + numberText(v.at(0)));
      }
  }
};

}  // namespace

std::unique_ptr<Effect> makeFriction() { return std::make_unique<Friction>(); }

}  // namespace viscera::study
