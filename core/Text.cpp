#include "core/Text.h"

#include <charconv>
#include <cstdlib>

namespace viscera {

namespace {
// from_chars rejects a leading '+'; "+-1" and "++1" stay invalid.
std::string_view dropPlus(std::string_view s) {
  if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  return s;
}
}  // namespace

bool parseNumber(std::string_view s, double& out) {
  s = dropPlus(s);
  if (s.empty()) return false;
  double v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v, std::chars_format::general);
  if (end != s.data() + s.size()) return false;
  if (ec == std::errc::result_out_of_range) {
    // strtod rounds the same text to +-HUGE_VAL (overflow) or to 0 / a subnormal (underflow).
    v = std::strtod(std::string(s).c_str(), nullptr);
  } else if (ec != std::errc()) {
    return false;
  }
  out = v;
  return true;
}

bool parseInteger(std::string_view s, long long& out) {
  s = dropPlus(s);
  if (s.empty()) return false;
  long long v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size()) return false;
  out = v;
  return true;
}

std::string formatNumber(double v) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, ec == std::errc() ? end : buffer);
}

}  // namespace viscera
