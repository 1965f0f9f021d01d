// Helpers for the command-line tests: run the built `viscera` binary in a shell, capture its exit
// code, stdout and stderr, and give each test its own temporary folder.
#pragma once

#include "tests/support/TempDir.h"
#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace viscera_test {

namespace fs = std::filesystem;

inline std::string sourcePath(const std::string& rel) { return std::string(VISCERA_SOURCE_DIR) + "/" + rel; }
inline std::string badPath(const std::string& name) { return sourcePath("tests/data/bad/" + name); }

inline std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Single-quotes a word for /bin/sh.
inline std::string shellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

using viscera::test_support::TempDir;

struct RunResult {
  int rc = -1;  // exit code, or -1 if the process did not exit normally
  std::string out, err;
};

inline std::ostream& operator<<(std::ostream& o, const RunResult& r) {
  return o << "exit code " << r.rc << "\n--- stdout ---\n" << r.out << "\n--- stderr ---\n" << r.err;
}

// Runs `viscera <args...>` (each argument quoted) and captures everything.
// `prefix` goes before the binary (a launcher such as "mpirun -n 2", with its environment).
inline RunResult runViscera(const std::vector<std::string>& args, const std::string& prefix = "") {
  TempDir io;
  std::string cmd = prefix + shellQuote(VISCERA_BINARY);
  for (const auto& a : args) {
    cmd += ' ';
    cmd += shellQuote(a);
  }
  cmd += " >";
  cmd += shellQuote(io / "stdout");
  cmd += " 2>";
  cmd += shellQuote(io / "stderr");
  cmd += " </dev/null";
  RunResult r;
  int status = std::system(cmd.c_str());
  r.rc = status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(io / "stdout");
  r.err = slurp(io / "stderr");
  return r;
}

// 1-based number of the first line of `file` that contains `needle` (0 if none).
inline int lineOf(const std::string& file, const std::string& needle) {
  std::istringstream in(slurp(file));
  std::string line;
  for (int n = 1; std::getline(in, line); ++n)
    if (line.find(needle) != std::string::npos) return n;
  return 0;
}

// Whether a folder is absent or empty.
inline bool absentOrEmpty(const fs::path& p) { return !fs::exists(p) || (fs::is_directory(p) && fs::is_empty(p)); }

// Lines of a text file, without the trailing empty line.
inline std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> v;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

}  // namespace viscera_test
