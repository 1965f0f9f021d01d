// Helpers shared by the fuzz targets: an input's bytes as a file, for the readers that take a
// path, and the one kind of exception a reader may throw on bad input.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <set>
#include <string>

#include "core/Error.h"

namespace viscera_fuzz {

// Writes `size` bytes to a file of this process with the extension `ext` (".msh", ".pcd", ...) and
// returns its path; the same path is reused by every input of the process.
// The files asFile wrote, and the output folders named after them (PATH.d), removed when the
// process exits normally.
struct TemporaryFiles {
  std::set<std::string> paths;
  ~TemporaryFiles() {
    std::error_code ec;
    for (const auto& p : paths) {
      std::filesystem::remove_all(p, ec);
      std::filesystem::remove_all(p + ".d", ec);
    }
  }
};

inline std::string asFile(const uint8_t* data, size_t size, const std::string& ext) {
  static TemporaryFiles written;
  const char* dir = std::getenv("TMPDIR");
  const std::string path = std::string(dir && *dir ? dir : "/tmp") + "/viscera-fuzz-" + std::to_string(::getpid()) + ext;
  written.paths.insert(path);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  if (size && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  return path;
}

// Runs `read` on one input: viscera::Error is the answer to bad input; anything else escaping
// (std::bad_alloc, std::out_of_range, ...) is a bug, reported as a crash. With VISCERA_FUZZ_VERBOSE
// set, each input's error is printed (to see what a corpus exercises).
template <typename Read>
void expectOnlyInputErrors(Read&& read) {
  static const bool verbose = std::getenv("VISCERA_FUZZ_VERBOSE") != nullptr;
  try {
    read();
    if (verbose) std::fprintf(stderr, "ok\n");
  } catch (const viscera::Error& e) {
    if (verbose) std::fprintf(stderr, "error: %.300s\n", e.what());
  }
}

}  // namespace viscera_fuzz
