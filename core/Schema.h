// Attribute declarations: every component declares each attribute once (name, type, default,
// range, unit, doc). Parsing, validation, defaults and the reference docs all read these.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/Units.h"

namespace viscera {

class Component;
class BuildContext;

enum class AttrKind {
  Real,    // one number, optionally with a unit
  Int,     // one integer
  Bool,    // true/false/1/0
  String,  // free text
  Enum,    // one of `choices`
  Reals,   // list of numbers (fixed `count` or any), optionally with one unit for all
  Ints,    // list of integers
  Link,    // "@path" to another component
  File,    // a path relative to the scene file
};

const char* kindName(AttrKind k);

struct AttrSpec {
  std::string name;
  AttrKind kind = AttrKind::Real;
  std::string defaultValue;  // text form; empty with !required means "not set"
  bool required = false;
  std::optional<double> lo, hi;  // range of every number
  bool loOpen = false, hiOpen = false;
  bool hasUnit = false;
  Dimension dim;
  int count = -1;         // Reals/Ints: exact number of values (-1: any, -2: any multiple of `multiple`)
  int multiple = 1;       // Reals/Ints: the count must be a multiple of this
  bool linkable = false;  // may be given as "@component.field"
  std::vector<std::string> choices;
  std::vector<std::string> aliases;  // other (SOFA) names of the same attribute
  std::string doc;

  // Fluent declaration: AttrSpec::real("youngModulus").def("5000").above(0).unit(pressure)...
  static AttrSpec real(std::string n) { return make(std::move(n), AttrKind::Real); }
  static AttrSpec integer(std::string n) { return make(std::move(n), AttrKind::Int); }
  static AttrSpec boolean(std::string n) { return make(std::move(n), AttrKind::Bool); }
  static AttrSpec string(std::string n) { return make(std::move(n), AttrKind::String); }
  static AttrSpec choice(std::string n, std::vector<std::string> c) {
    AttrSpec s = make(std::move(n), AttrKind::Enum);
    s.choices = std::move(c);
    return s;
  }
  static AttrSpec reals(std::string n, int count = -1) {
    AttrSpec s = make(std::move(n), AttrKind::Reals);
    s.count = count;
    return s;
  }
  static AttrSpec ints(std::string n, int count = -1) {
    AttrSpec s = make(std::move(n), AttrKind::Ints);
    s.count = count;
    return s;
  }
  static AttrSpec link(std::string n) { return make(std::move(n), AttrKind::Link); }
  static AttrSpec file(std::string n) { return make(std::move(n), AttrKind::File); }

  AttrSpec& def(std::string v) { defaultValue = std::move(v); return *this; }
  AttrSpec& req() { required = true; return *this; }
  AttrSpec& atLeast(double v) { lo = v; loOpen = false; return *this; }
  AttrSpec& above(double v) { lo = v; loOpen = true; return *this; }
  AttrSpec& atMost(double v) { hi = v; hiOpen = false; return *this; }
  AttrSpec& below(double v) { hi = v; hiOpen = true; return *this; }
  AttrSpec& unit(Dimension d) { hasUnit = true; dim = d; return *this; }
  AttrSpec& multipleOf(int m) { count = -2; multiple = m; return *this; }
  AttrSpec& linked() { linkable = true; return *this; }
  AttrSpec& alias(std::string a) { aliases.push_back(std::move(a)); return *this; }
  AttrSpec& help(std::string d) { doc = std::move(d); return *this; }

  // "[0, 0.5)" style text of the range, empty if none.
  std::string rangeText() const;

 private:
  static AttrSpec make(std::string n, AttrKind k) {
    AttrSpec s;
    s.name = std::move(n);
    s.kind = k;
    return s;
  }
};

// What a component is for; used by docs and by the scene to find roles.
using ComponentFactory = std::function<std::unique_ptr<Component>(BuildContext&)>;

struct ComponentSpec {
  std::string name;
  std::vector<std::string> aliases;  // SOFA's other names, e.g. FixedProjectiveConstraint
  std::string category;              // "mechanics", "fem", "solver", ...
  std::string doc;
  std::vector<AttrSpec> attrs;
  ComponentFactory factory;          // empty for accepted-but-ignored components

  ComponentSpec& add(AttrSpec a) { attrs.push_back(std::move(a)); return *this; }
  const AttrSpec* find(const std::string& attr) const;
};

// Attributes any component may carry that do not change the physics (drawing, logging);
// they are accepted with a note.
bool isCosmeticAttribute(const std::string& name);

}  // namespace viscera
