// Physical units: a scene declares its unit system (length, mass, time) and attribute values may
// carry a unit ("5 kPa", "9.81 m/s^2"), converted into the scene's system.
#pragma once

#include <array>
#include <optional>
#include <string>

namespace viscera {

// Exponents of length, mass and time, e.g. pressure = {-1, 1, -2}.
struct Dimension {
  int L = 0, M = 0, T = 0;
  bool operator==(const Dimension&) const = default;
  std::string str() const;  // e.g. "L^-1 M T^-2", "1" for dimensionless

  static constexpr Dimension none() { return {0, 0, 0}; }
  static constexpr Dimension length() { return {1, 0, 0}; }
  static constexpr Dimension mass() { return {0, 1, 0}; }
  static constexpr Dimension time() { return {0, 0, 1}; }
  static constexpr Dimension velocity() { return {1, 0, -1}; }
  static constexpr Dimension acceleration() { return {1, 0, -2}; }
  static constexpr Dimension force() { return {1, 1, -2}; }
  static constexpr Dimension pressure() { return {-1, 1, -2}; }
  static constexpr Dimension density() { return {-3, 1, 0}; }
  static constexpr Dimension stiffness() { return {0, 1, -2}; }  // N/m
  static constexpr Dimension frequency() { return {0, 0, -1}; }
};

// A parsed unit expression: its size in SI and its dimension.
struct Unit {
  double si = 1.0;
  Dimension dim;
};

// Parses "kPa", "mm/s^2", "g/mm^3", "N*m", "1/s". Throws std::invalid_argument naming the part
// it does not know.
Unit parseUnit(const std::string& text);

// The unit system of a scene: SI sizes of its length, mass and time units.
class UnitSystem {
 public:
  UnitSystem() = default;  // m, kg, s
  // Parses "mm g s" (three base units, in the order length mass time).
  static UnitSystem parse(const std::string& text);

  // SI size of one scene unit of the given dimension.
  double siOf(const Dimension& d) const;
  // Converts `value` in `unit` into this system; throws std::invalid_argument if the unit does
  // not have dimension `expected`.
  double convert(double value, const Unit& unit, const Dimension& expected) const;
  std::string str() const { return names_[0] + " " + names_[1] + " " + names_[2]; }

 private:
  std::array<double, 3> si_{1.0, 1.0, 1.0};
  std::array<std::string, 3> names_{"m", "kg", "s"};
};

}  // namespace viscera
