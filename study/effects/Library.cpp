// The effect library and the helpers effects share.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "builtin/Builtins.h"
#include "core/Attributes.h"
#include "core/Error.h"
#include "core/Registry.h"
#include "study/effects/Effect.h"

namespace viscera::study {

std::unique_ptr<Effect> makeGravity();
std::unique_ptr<Effect> makeYoungModulus();
std::unique_ptr<Effect> makePoissonRatio();
std::unique_ptr<Effect> makeInclusion();
std::unique_ptr<Effect> makeDamping();
std::unique_ptr<Effect> makeFriction();
std::unique_ptr<Effect> makeInstrumentRadius();
std::unique_ptr<Effect> makeElasticFoundation();
std::unique_ptr<Effect> makeRegistration();

std::vector<std::unique_ptr<Effect>> effectLibrary() {
  std::vector<std::unique_ptr<Effect>> v;
  v.push_back(makeGravity());
  v.push_back(makeYoungModulus());
  v.push_back(makePoissonRatio());
  v.push_back(makeInclusion());
  v.push_back(makeDamping());
  v.push_back(makeFriction());
  v.push_back(makeInstrumentRadius());
  v.push_back(makeElasticFoundation());
  v.push_back(makeRegistration());
  return v;
}

namespace {
void collect(ElementDesc& el, const std::string& tag, std::vector<ElementDesc*>& out) {
  const ComponentSpec* s = builtinRegistry().find(el.tag);
  if (el.tag == tag || (s && s->name == tag)) out.push_back(&el);
  for (auto& c : el.children) collect(c, tag, out);
}
}  // namespace

std::vector<ElementDesc*> elementsOf(ElementDesc& root, const std::string& tag) {
  std::vector<ElementDesc*> out;
  collect(root, tag, out);
  return out;
}

std::vector<double> realsOf(const ElementDesc& el, const std::string& attribute, const UnitSystem& units) {
  const ComponentSpec* spec = el.tag == "Node" ? &Registry::nodeSpec() : builtinRegistry().find(el.tag);
  const AttrSpec* a = spec ? spec->find(attribute) : nullptr;
  if (!a) throw Error(el.loc, el.tag + " has no attribute '" + attribute + "'");
  const AttrDesc* given = el.find(attribute);
  AttrValue v;
  try {
    parseAttrText(*a, given ? given->value : a->defaultValue, units, v);
  } catch (const std::invalid_argument& e) {
    throw Error(given ? given->loc : el.loc, el.tag + "." + attribute + ": " + e.what());
  }
  return v.nums;
}

std::vector<double> Effect::plant(const AuditScene& scene, double strength, unsigned) const {
  std::vector<double> v;
  for (const EffectParam& p : params(scene)) {
    const bool log = p.scale == Scale::Log;
    auto u = [&](double x) { return log ? std::log10(x) : x; };
    const double n = u(std::clamp(p.nominal, p.lo, p.hi)), lo = u(p.lo), hi = u(p.hi);
    const double far = hi - n >= n - lo ? hi : lo;
    const double x = n + 0.5 * strength * (far - n);
    v.push_back(log ? std::pow(10.0, x) : x);
  }
  return v;
}

bool isLink(const ElementDesc& el, const std::string& attribute) {
  const AttrDesc* a = el.find(attribute);
  return a && !a->value.empty() && a->value[0] == '@';
}

std::string numberText(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

void noteChange(ElementDesc& el, const std::string& effect, const std::string& what) {
  el.comment += (el.comment.empty() ? "" : "; ") + std::string("audit effect '") + effect + "': " + what;
}

}  // namespace viscera::study
