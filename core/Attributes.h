// Validated attribute values of one component, converted to the scene's unit system.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/Error.h"
#include "core/Schema.h"

namespace viscera {

struct AttrValue {
  const AttrSpec* spec = nullptr;
  bool set = false;           // given in the scene (otherwise the default applies)
  std::string text;           // as written (or the default)
  SourceLoc loc;
  bool link = false;          // "@path" or "@path.field", resolved at init
  std::vector<double> nums;   // Real, Int, Bool, Reals, Ints (in scene units)
};

class Attributes {
 public:
  Attributes() = default;
  Attributes(std::string component, SourceLoc loc) : component_(std::move(component)), loc_(std::move(loc)) {}

  double real(const std::string& n) const;
  long integer(const std::string& n) const;
  bool boolean(const std::string& n) const;
  const std::string& str(const std::string& n) const;
  const std::vector<double>& reals(const std::string& n) const;
  std::vector<int> ints(const std::string& n) const;

  bool isSet(const std::string& n) const { return get(n).set; }
  bool isLink(const std::string& n) const { return get(n).link; }
  const AttrValue& get(const std::string& n) const;
  AttrValue& getMutable(const std::string& n);
  const std::string& component() const { return component_; }
  const SourceLoc& componentLoc() const { return loc_; }
  SourceLoc loc(const std::string& n) const;

  // An input error about attribute `n`: "file:line:col: Component.n: msg".
  Error error(const std::string& n, const std::string& msg) const;

  std::map<std::string, AttrValue>& values() { return values_; }
  const std::map<std::string, AttrValue>& values() const { return values_; }

 private:
  std::string component_;
  SourceLoc loc_;
  std::map<std::string, AttrValue> values_;
};

// Parses `text` for `spec` into `out.nums` (numbers in the scene's units). Throws
// std::invalid_argument with a message that does not repeat the attribute's name.
void parseAttrText(const AttrSpec& spec, const std::string& text, const UnitSystem& units, AttrValue& out);
// Checks the range and count of already-parsed numbers (also used for linked values at init).
void checkAttrNumbers(const AttrSpec& spec, const std::vector<double>& nums);

}  // namespace viscera
