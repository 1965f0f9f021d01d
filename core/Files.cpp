#include "core/Files.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <functional>
#include <thread>

#include "core/Error.h"

namespace viscera {

void writeFileAtomic(const std::string& path, const std::string& content) {
  // Same folder as the target, so the rename stays on one file system and is atomic; named by
  // process and thread, so that runs in parallel threads never share a temporary.
  const std::string temp = path + ".tmp." + std::to_string(::getpid()) + "." +
                           std::to_string(std::hash<std::thread::id>()(std::this_thread::get_id()) % 1000000);
  auto failWith = [&](int err, const char* step, bool removeTemp) {
    if (removeTemp) ::unlink(temp.c_str());
    throw Error(SourceLoc{path}, std::string("cannot write file: ") + step + " " + temp + " failed: " + std::strerror(err));
  };
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) {
    const int err = errno;
    failWith(err, "creating", false);
  }
  size_t done = 0;
  while (done < content.size()) {
    const ssize_t n = ::write(fd, content.data() + done, content.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      failWith(err, "writing", true);
    }
    done += static_cast<size_t>(n);
  }
  if (::close(fd) != 0) {  // deferred write errors (e.g. a full disk on NFS) show up here
    const int err = errno;
    failWith(err, "closing", true);
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    failWith(err, "renaming", true);
  }
}

}  // namespace viscera
