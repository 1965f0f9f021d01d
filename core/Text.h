// Numbers as text, read and written the same way everywhere (scenes, tables, meshes, clouds,
// command lines), so that what one part writes another reads back exactly.
#pragma once

#include <string>
#include <string_view>

namespace viscera {

// The whole of `s` as a number (no blanks around it; a leading '+' is accepted). Magnitudes out
// of double range read as +-infinity (1e999) or as their nearest value (1e-999: 0), so callers
// report overflow as "not finite" rather than "not a number". "nan" and "inf" parse: callers that
// need finite values check.
bool parseNumber(std::string_view s, double& out);
// The number at the start of `s` ("5kPa" -> 5, "1e3" -> 1000) by the same rules; returns how
// many characters it took (0: `s` does not start with a number). Hexadecimal ("0x1F") is not a
// number here: it reads as 0 followed by "x1F".
size_t parseNumberPrefix(std::string_view s, double& out);
// The whole of `s` as an integer (a leading '+' accepted); false if it does not fit.
bool parseInteger(std::string_view s, long long& out);
// The shortest text that reads back as exactly `v` ("0.1", "1e-07", "0.3333333333333333").
std::string formatNumber(double v);

// Text as the line-based readers take it: a UTF-8 byte-order mark dropped (spreadsheet exports
// start with one) and lone carriage returns (old Mac line ends) turned into line feeds; CR LF pairs
// are left to the readers, which accept them.
std::string plainText(std::string_view text);

// A message as a terminal should show it: bytes that are not printable UTF-8 (control characters,
// binary data) written as \xNN, and any run of more than `longestRun` characters without a blank
// (an attribute value pasted 100,000 times) cut to its start, its end and how much was left out.
std::string printable(std::string_view message, size_t longestRun = 160);

}  // namespace viscera
