#include "core/Attributes.h"
#include "core/Text.h"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace viscera {

const AttrValue& Attributes::get(const std::string& n) const {
  auto it = values_.find(n);
  if (it == values_.end()) throw std::logic_error(component_ + " has no declared attribute '" + n + "'");
  return it->second;
}

AttrValue& Attributes::getMutable(const std::string& n) {
  auto it = values_.find(n);
  if (it == values_.end()) throw std::logic_error(component_ + " has no declared attribute '" + n + "'");
  return it->second;
}

SourceLoc Attributes::loc(const std::string& n) const {
  auto it = values_.find(n);
  return it != values_.end() && it->second.set ? it->second.loc : loc_;
}

Error Attributes::error(const std::string& n, const std::string& msg) const {
  return Error(loc(n), component_ + "." + n + ": " + msg);
}

double Attributes::real(const std::string& n) const {
  const auto& v = get(n);
  if (v.nums.empty()) throw error(n, "no value");
  return v.nums[0];
}

long Attributes::integer(const std::string& n) const { return std::lround(real(n)); }
bool Attributes::boolean(const std::string& n) const { return real(n) != 0.0; }
const std::string& Attributes::str(const std::string& n) const { return get(n).text; }
const std::vector<double>& Attributes::reals(const std::string& n) const { return get(n).nums; }

std::vector<int> Attributes::ints(const std::string& n) const {
  std::vector<int> r;
  for (double d : get(n).nums) r.push_back(static_cast<int>(std::lround(d)));
  return r;
}

namespace {

// Splits "5 kPa" / "1e3" / "-9.81 m/s^2" lists into numbers and one optional trailing unit.
void splitNumbersAndUnit(const std::string& text, std::vector<double>& nums, std::string& unit) {
  std::istringstream in(text);
  std::string tok;
  std::vector<std::string> toks;
  while (in >> tok) toks.push_back(tok);
  size_t i = 0;
  for (; i < toks.size(); ++i) {
    const std::string& t = toks[i];
    double d = 0;
    const size_t used = parseNumberPrefix(t, d);
    if (used == 0) break;  // not a number: the unit starts here
    if (used < t.size()) {
      const char* end = t.c_str() + used;
      const std::string lead = t.substr(0, used);
      if ((*end == 'x' || *end == 'X') && (lead == "0" || lead == "-0" || lead == "+0"))
        throw std::invalid_argument("'" + t + "' is not a number (hexadecimal is not accepted)");
      // "5kPa": a number glued to its unit
      if (i + 1 == toks.size() && std::isalpha(static_cast<unsigned char>(*end))) {
        nums.push_back(d);
        unit = end;
        return;
      }
      throw std::invalid_argument("'" + t + "' is not a number");
    }
    nums.push_back(d);
  }
  for (; i < toks.size(); ++i) unit += (unit.empty() ? "" : " ") + toks[i];
}

// SOFA's index ranges in integer lists: "0-8" is 0 1 2 ... 8. A list may expand to at most
// kMaxRangeValues values (a typo such as "0-99999999999" is refused, not allocated).
constexpr long long kMaxRangeValues = 10'000'000;

std::string expandIndexRanges(const std::string& text) {
  std::istringstream in(text);
  std::string out, t;
  long long total = 0;
  while (in >> t) {
    const size_t dash = t.find('-', 1);
    long long a = 0, b = 0;
    if (dash != std::string::npos && std::isdigit(static_cast<unsigned char>(t[0])) &&
        parseInteger(std::string_view(t).substr(0, dash), a) && parseInteger(std::string_view(t).substr(dash + 1), b) &&
        std::isdigit(static_cast<unsigned char>(t[dash + 1]))) {
      if (b < a) throw std::invalid_argument("range '" + t + "' ends before it starts");
      // a >= 0, so b - a cannot overflow; compared before adding, so total cannot either.
      if (b - a >= kMaxRangeValues - total)
        throw std::invalid_argument("ranges give more than " + std::to_string(kMaxRangeValues) + " values");
      total += b - a + 1;
      for (long long i = a; i <= b; ++i) out += std::to_string(i) + " ";
      continue;
    }
    if (++total > kMaxRangeValues)
      throw std::invalid_argument("more than " + std::to_string(kMaxRangeValues) + " values");
    out += t + " ";
  }
  return out;
}

}  // namespace

void checkAttrNumbers(const AttrSpec& spec, const std::vector<double>& nums) {
  for (double d : nums) {
    if (!std::isfinite(d)) throw std::invalid_argument("value is not finite");
    std::ostringstream v;
    v << d;
    if (spec.lo && (d < *spec.lo || (spec.loOpen && d == *spec.lo)))
      throw std::invalid_argument("value " + v.str() + " is out of range " + spec.rangeText());
    if (spec.hi && (d > *spec.hi || (spec.hiOpen && d == *spec.hi)))
      throw std::invalid_argument("value " + v.str() + " is out of range " + spec.rangeText());
  }
  if (spec.count >= 0 && static_cast<int>(nums.size()) != spec.count)
    throw std::invalid_argument("expected " + std::to_string(spec.count) + " values, got " + std::to_string(nums.size()));
  if (spec.count == -2 && nums.size() % spec.multiple != 0)
    throw std::invalid_argument("expected a multiple of " + std::to_string(spec.multiple) + " values, got " +
                                std::to_string(nums.size()));
}

void parseAttrText(const AttrSpec& spec, const std::string& text, const UnitSystem& units, AttrValue& out) {
  out.nums.clear();
  switch (spec.kind) {
    case AttrKind::String:
    case AttrKind::File:
    case AttrKind::Link:
      return;
    case AttrKind::Enum: {
      for (const auto& c : spec.choices)
        if (c == text) return;
      std::string all;
      for (const auto& c : spec.choices) all += (all.empty() ? "" : ", ") + c;
      throw std::invalid_argument("'" + text + "' is not one of: " + all);
    }
    case AttrKind::Bool: {
      if (text == "true" || text == "1" || text == "True" || text == "yes") out.nums = {1.0};
      else if (text == "false" || text == "0" || text == "False" || text == "no") out.nums = {0.0};
      else throw std::invalid_argument("'" + text + "' is not a boolean (true/false/1/0)");
      return;
    }
    default: break;
  }
  std::string unit;
  if (spec.kind == AttrKind::Ints && text.find('-', 1) != std::string::npos)
    splitNumbersAndUnit(expandIndexRanges(text), out.nums, unit);
  else
    splitNumbersAndUnit(text, out.nums, unit);
  if (!unit.empty()) {
    if (!spec.hasUnit) throw std::invalid_argument("takes no unit, got '" + unit + "'");
    const Unit u = parseUnit(unit);
    if (!(u.dim == spec.dim))
      throw std::invalid_argument("unit '" + unit + "' is incompatible (dimension " + u.dim.str() + ", expected " +
                                  spec.dim.str() + ")");
    for (double& d : out.nums) d = units.convert(d, u, spec.dim);
  }
  if ((spec.kind == AttrKind::Real || spec.kind == AttrKind::Int) && out.nums.size() != 1)
    throw std::invalid_argument(out.nums.empty() ? "'" + text + "' is not a number" : "expected one value, got " + std::to_string(out.nums.size()));
  if (spec.kind == AttrKind::Int || spec.kind == AttrKind::Ints)
    for (double d : out.nums)
      if (d != std::floor(d)) throw std::invalid_argument("'" + text + "' is not an integer");
  checkAttrNumbers(spec, out.nums);
}

}  // namespace viscera
