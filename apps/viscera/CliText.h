// Small text helpers shared by the command modules: option words and JSON strings.
#pragma once

#include <string>
#include <vector>

namespace viscera::cli {

// Words separated by blanks and/or commas ("1 2 3", "1,2,3", "1, 2, 3").
std::vector<std::string> words(const std::string& s);

// `s` as a quoted JSON string: quotes and backslashes escaped, newlines as \n, other control
// characters as blanks.
std::string jsonString(const std::string& s);

}  // namespace viscera::cli
