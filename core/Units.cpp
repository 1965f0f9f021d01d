#include "core/Units.h"

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace viscera {

std::string Dimension::str() const {
  std::string s;
  auto part = [&s](const char* n, int e) {
    if (e == 0) return;
    if (!s.empty()) s += " ";
    s += n;
    if (e != 1) s += "^" + std::to_string(e);
  };
  part("L", L);
  part("M", M);
  part("T", T);
  return s.empty() ? "1" : s;
}

namespace {

struct BaseUnit {
  const char* symbol;
  double si;
  Dimension dim;
};

// Units with their SI size. Prefixed forms are listed explicitly: "m" would otherwise be
// ambiguous between metre and milli-.
const BaseUnit kUnits[] = {
    {"m", 1.0, Dimension::length()},      {"cm", 1e-2, Dimension::length()},
    {"mm", 1e-3, Dimension::length()},    {"um", 1e-6, Dimension::length()},
    {"km", 1e3, Dimension::length()},     {"kg", 1.0, Dimension::mass()},
    {"g", 1e-3, Dimension::mass()},       {"mg", 1e-6, Dimension::mass()},
    {"t", 1e3, Dimension::mass()},        {"s", 1.0, Dimension::time()},
    {"ms", 1e-3, Dimension::time()},      {"us", 1e-6, Dimension::time()},
    {"min", 60.0, Dimension::time()},     {"h", 3600.0, Dimension::time()},
    {"N", 1.0, Dimension::force()},       {"mN", 1e-3, Dimension::force()},
    {"kN", 1e3, Dimension::force()},      {"Pa", 1.0, Dimension::pressure()},
    {"kPa", 1e3, Dimension::pressure()},  {"MPa", 1e6, Dimension::pressure()},
    {"GPa", 1e9, Dimension::pressure()},  {"Hz", 1.0, Dimension::frequency()},
    {"J", 1.0, {2, 1, -2}},               {"rad", 1.0, Dimension::none()},
    {"deg", M_PI / 180.0, Dimension::none()},
};

Dimension scaled(const Dimension& d, int e) { return {d.L * e, d.M * e, d.T * e}; }
Dimension added(const Dimension& a, const Dimension& b) { return {a.L + b.L, a.M + b.M, a.T + b.T}; }

}  // namespace

Unit parseUnit(const std::string& text) {
  Unit u;
  size_t i = 0;
  int sign = +1;  // +1 before '/', -1 after
  bool any = false;
  while (i < text.size()) {
    char c = text[i];
    if (c == ' ' || c == '*' || c == '.') {
      ++i;
      continue;
    }
    if (c == '/') {
      sign = -1;
      ++i;
      continue;
    }
    size_t j = i;
    while (j < text.size() && (std::isalpha(static_cast<unsigned char>(text[j])) || text[j] == '1')) ++j;
    std::string sym = text.substr(i, j - i);
    int exponent = 1;
    if (j < text.size() && text[j] == '^') {
      size_t k = j + 1;
      if (k < text.size() && (text[k] == '-' || text[k] == '+')) ++k;
      while (k < text.size() && std::isdigit(static_cast<unsigned char>(text[k]))) ++k;
      std::string e = text.substr(j + 1, k - j - 1);
      if (e.empty() || e == "-" || e == "+") throw std::invalid_argument("bad exponent in unit '" + text + "'");
      exponent = std::atoi(e.c_str());
      j = k;
    }
    if (sym.empty()) throw std::invalid_argument("unexpected '" + std::string(1, c) + "' in unit '" + text + "'");
    i = j;
    any = true;
    if (sym == "1") continue;  // as in "1/s"
    const BaseUnit* found = nullptr;
    for (const auto& b : kUnits)
      if (sym == b.symbol) found = &b;
    if (!found) throw std::invalid_argument("unknown unit '" + sym + "'");
    int e = sign * exponent;
    u.si *= std::pow(found->si, e);
    u.dim = added(u.dim, scaled(found->dim, e));
  }
  if (!any) throw std::invalid_argument("empty unit");
  return u;
}

UnitSystem UnitSystem::parse(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> parts;
  for (std::string p; in >> p;) parts.push_back(p);
  if (parts.size() != 3)
    throw std::invalid_argument("expected three units 'length mass time' (e.g. \"mm g s\"), got '" + text + "'");
  UnitSystem s;
  const Dimension want[3] = {Dimension::length(), Dimension::mass(), Dimension::time()};
  const char* what[3] = {"length", "mass", "time"};
  for (int k = 0; k < 3; ++k) {
    Unit u = parseUnit(parts[k]);
    if (!(u.dim == want[k]))
      throw std::invalid_argument("'" + parts[k] + "' is not a unit of " + what[k]);
    s.si_[k] = u.si;
    s.names_[k] = parts[k];
  }
  return s;
}

double UnitSystem::siOf(const Dimension& d) const {
  return std::pow(si_[0], d.L) * std::pow(si_[1], d.M) * std::pow(si_[2], d.T);
}

double UnitSystem::convert(double value, const Unit& unit, const Dimension& expected) const {
  if (!(unit.dim == expected))
    throw std::invalid_argument("unit has dimension " + unit.dim.str() + ", expected " + expected.str());
  return value * unit.si / siOf(expected);
}

}  // namespace viscera
