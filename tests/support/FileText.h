// Whole files as strings, for tests that write inputs and read outputs.
#pragma once

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace viscera::test_support {

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void spit(const std::filesystem::path& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }

}  // namespace viscera::test_support
