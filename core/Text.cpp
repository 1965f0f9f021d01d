#include "core/Text.h"

#include <algorithm>
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

namespace {

// The length of the valid UTF-8 sequence at `s[i]` (1 to 4), or 0 if it is not one.
size_t utf8Length(std::string_view s, size_t i) {
  const auto byte = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = byte(i);
  const size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
  if (n == 0 || i + n > s.size()) return 0;
  for (size_t k = 1; k < n; ++k)
    if ((byte(i + k) >> 6) != 0x2) return 0;
  return n;
}

}  // namespace

std::string printable(std::string_view message, size_t longestRun) {
  // Escape first, so that cutting counts what is shown.
  std::string shown;
  shown.reserve(message.size());
  for (size_t i = 0; i < message.size();) {
    const unsigned char c = static_cast<unsigned char>(message[i]);
    const size_t n = utf8Length(message, i);
    if (n == 0 || (c < 0x20 && c != '\n' && c != '\t') || c == 0x7F) {
      static const char* const kHex = "0123456789ABCDEF";
      shown += "\\x";
      shown += kHex[c >> 4];
      shown += kHex[c & 0xF];
      ++i;
      continue;
    }
    shown.append(message.substr(i, n));
    i += n;
  }
  std::string out;
  out.reserve(std::min(shown.size(), size_t(1) << 16));
  const size_t keep = longestRun / 2;
  for (size_t i = 0; i < shown.size();) {
    size_t j = i;
    while (j < shown.size() && shown[j] != ' ' && shown[j] != '\n' && shown[j] != '\t') ++j;
    if (j - i > longestRun) {
      // Cut at character boundaries (never inside a UTF-8 sequence).
      size_t head = i + keep, tail = j - keep;
      while (head > i && (static_cast<unsigned char>(shown[head]) >> 6) == 0x2) --head;
      while (tail < j && (static_cast<unsigned char>(shown[tail]) >> 6) == 0x2) ++tail;
      out.append(shown, i, head - i);
      out += "...[" + std::to_string(tail - head) + " characters left out]...";
      out.append(shown, tail, j - tail);
    } else {
      out.append(shown, i, j - i);
    }
    if (j < shown.size()) out += shown[j++];
    i = j;
  }
  return out;
}

}  // namespace viscera
