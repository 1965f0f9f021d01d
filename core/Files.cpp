#include "core/Files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <thread>

#include "core/Error.h"

namespace viscera {

namespace {

// Writes all of `content` to `fd`; false with errno set on failure.
bool writeAll(int fd, const std::string& content) {
  size_t done = 0;
  while (done < content.size()) {
    const ssize_t n = ::write(fd, content.data() + done, content.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      if (n == 0) errno = EIO;
      return false;
    }
    done += static_cast<size_t>(n);
  }
  return true;
}

}  // namespace

void writeFileAtomic(const std::string& path, const std::string& content) {
  // What is at the path decides how: a regular file (or nothing) is replaced atomically; a link
  // is refused (an output never follows one out of its folder); a device or FIFO is written
  // through, never replaced by a file (/dev/null works, /dev/full reports its error).
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (S_ISLNK(st.st_mode))
      throw Error(SourceLoc{path}, "cannot write file: it is a symbolic link, and outputs do not follow links (nothing was written)");
    if (S_ISDIR(st.st_mode)) throw Error(SourceLoc{path}, "cannot write file: it is a directory");
    if (!S_ISREG(st.st_mode)) {
      const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC | (S_ISFIFO(st.st_mode) ? O_NONBLOCK : 0));
      if (fd < 0) throw Error(SourceLoc{path}, std::string("cannot write to the device or FIFO: ") + std::strerror(errno));
      const bool ok = writeAll(fd, content);
      const int err = errno;
      if (::close(fd) != 0 || !ok)
        throw Error(SourceLoc{path}, std::string("cannot write to the device or FIFO: ") + std::strerror(ok ? errno : err));
      return;
    }
  }
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
  if (!writeAll(fd, content)) {
    const int err = errno;
    ::close(fd);
    failWith(err, "writing", true);
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

std::string readInputFile(const std::string& path, const std::string& what, std::uintmax_t maxBytes) {
  const std::string prefix = "cannot open" + (what.empty() ? std::string() : " " + what) + ": ";
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw Error(SourceLoc{path}, prefix + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) throw Error(SourceLoc{path}, prefix + "it is a directory");
  if (!S_ISREG(st.st_mode))
    throw Error(SourceLoc{path}, prefix + "it is not a regular file (a device, FIFO or socket could be endless or block)");
  if (static_cast<std::uintmax_t>(st.st_size) > maxBytes)
    throw Error(SourceLoc{path}, prefix + "it holds " + std::to_string(st.st_size) + " bytes, more than the " +
                                     std::to_string(maxBytes) + " an input file may have");
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) throw Error(SourceLoc{path}, prefix + std::strerror(errno));
  std::string bytes;
  bytes.reserve(static_cast<size_t>(st.st_size));
  char buffer[1 << 16];
  size_t got;
  while ((got = std::fread(buffer, 1, sizeof buffer, file.get())) > 0) {
    bytes.append(buffer, got);
    if (bytes.size() > maxBytes) throw Error(SourceLoc{path}, prefix + "it grew past the limit while being read");
  }
  if (std::ferror(file.get())) throw Error(SourceLoc{path}, "cannot read" + (what.empty() ? std::string() : " " + what) + ": " + std::strerror(errno));
  return bytes;
}

}  // namespace viscera
