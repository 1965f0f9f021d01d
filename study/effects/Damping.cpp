// `damping`: the tissue's viscosity differs from the scene's Rayleigh damping. Two parameters, the
// stiffness and mass coefficients of every EulerImplicitSolver.
#include <algorithm>

#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

class Damping : public Effect {
 public:
  std::string key() const override { return "damping"; }
  std::string what() const override { return "Rayleigh damping: rayleighStiffness and rayleighMass of the implicit solvers"; }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    SceneDesc d = s.desc;
    const auto odes = elementsOf(d.root, "EulerImplicitSolver");
    if (odes.empty()) return {};
    const double rs = realsOf(*odes.front(), "rayleighStiffness", s.units).at(0);
    const double rm = realsOf(*odes.front(), "rayleighMass", s.units).at(0);
    return {{"rayleighStiffness", 1e-3, 1.0, std::clamp(rs, 1e-3, 1.0), Scale::Log, "s"},
            {"rayleighMass", 1e-3, 10.0, std::clamp(rm, 1e-3, 10.0), Scale::Log, "1/s"}};
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene&) const override {
    for (ElementDesc* ode : elementsOf(desc.root, "EulerImplicitSolver")) {
      ode->set("rayleighStiffness", numberText(v.at(0)));
      ode->set("rayleighMass", numberText(v.at(1)));
      noteChange(*ode, key(), "rayleighStiffness " + numberText(v.at(0)) + ", rayleighMass " + numberText(v.at(1)));
    }
  }
};

}  // namespace

std::unique_ptr<Effect> makeDamping() { return std::make_unique<Damping>(); }

}  // namespace viscera::study
