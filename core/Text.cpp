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

size_t parseNumberPrefix(std::string_view s, double& out) {
  const std::string_view body = dropPlus(s);
  const size_t plus = s.size() - body.size();
  if (body.empty()) return 0;
  double v = 0;
  const auto [end, ec] = std::from_chars(body.data(), body.data() + body.size(), v, std::chars_format::general);
  const size_t used = static_cast<size_t>(end - body.data());
  if (ec == std::errc::result_out_of_range) {
    // strtod rounds the same text to +-HUGE_VAL (overflow) or to 0 / a subnormal (underflow).
    v = std::strtod(std::string(body.substr(0, used)).c_str(), nullptr);
  } else if (ec != std::errc()) {
    return 0;
  }
  out = v;
  return plus + used;
}

bool parseNumber(std::string_view s, double& out) {
  double v = 0;
  if (s.empty() || parseNumberPrefix(s, v) != s.size()) return false;
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

std::string plainText(std::string_view text) {
  if (text.size() >= 3 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  std::string out(text);
  for (size_t i = 0; i < out.size(); ++i)
    if (out[i] == '\r' && (i + 1 == out.size() || out[i + 1] != '\n')) out[i] = '\n';
  return out;
}

}  // namespace viscera
