// Files written whole or not at all, and input files read whole with their limits checked.
#pragma once

#include <cstdint>
#include <string>

namespace viscera {

// The largest input file read whole (scenes, tables, meshes, transforms): 2 GiB.
constexpr std::uintmax_t kMaxInputBytes = std::uintmax_t{2} << 30;

// The bytes of the input file `path`. Throws viscera::Error naming the path, "cannot open WHAT: "
// + the reason, for a missing or unreadable file, a folder, a file larger than `maxBytes`, and
// anything that is not a regular file (a device such as /dev/zero, a FIFO, a socket), which could
// be endless or block. `what` names the kind of file in the message ("trajectory", "mesh file";
// empty: none).
std::string readInputFile(const std::string& path, const std::string& what = "", std::uintmax_t maxBytes = kMaxInputBytes);

// Writes `content` to `path` through a temporary file in the same folder and a rename, so that
// readers never see a half-written file. A device or FIFO at `path` is written through instead
// (never replaced by a file); a symbolic link or a folder is refused. Throws viscera::Error naming
// the path on failure.
void writeFileAtomic(const std::string& path, const std::string& content);

// An output folder held by one run for as long as the object lives: `folder/.viscera.lock`,
// locked with flock (released by the system when the process ends, however it ends) and removed
// on destruction. The folder is created if missing; temporaries of writeFileAtomic left by a run
// killed mid-write are removed once it is held. A second run into the same folder throws
// viscera::Error naming the folder and the process that holds it (its id and command line).
class FolderLock {
 public:
  explicit FolderLock(const std::string& folder);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  std::string path_;
  int fd_ = -1;
};

}  // namespace viscera
