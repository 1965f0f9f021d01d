#include "core/Files.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
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

namespace {

// This process's command line, its arguments separated by blanks.
std::string ownCommandLine() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  while (!s.empty() && s.back() == '\0') s.pop_back();
  for (char& c : s)
    if (c == '\0') c = ' ';
  return s.size() > 300 ? s.substr(0, 300) + "..." : s;
}

// With the folder held, no other run writes into it: a temporary of writeFileAtomic still there
// (NAME.tmp.PID.N) was left by a run killed mid-write, and goes.
void removeStaleTemporaries(const std::string& folder) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    const size_t at = name.rfind(".tmp.");
    if (at == std::string::npos || !e.is_regular_file(ec)) continue;
    const std::string ids = name.substr(at + 5);
    const size_t dot = ids.find('.');
    const auto digits = [](const std::string& s) {
      return !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
    };
    if (dot != std::string::npos && digits(ids.substr(0, dot)) && digits(ids.substr(dot + 1)))
      std::filesystem::remove(e.path(), ec);
  }
}

}  // namespace

FolderLock::FolderLock(const std::string& folder) : path_((std::filesystem::path(folder) / ".viscera.lock").string()) {
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec) throw Error(SourceLoc{folder}, "cannot create the output folder: " + ec.message());
  // The lock file may be removed by its holder between our open and our lock: lock, then check
  // that the name still leads to the file locked, else try again.
  for (int attempt = 0; attempt < 100; ++attempt) {
    const int fd = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) throw Error(SourceLoc{folder}, std::string("cannot lock the output folder: ") + std::strerror(errno));
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      std::string holder;
      char buffer[512];
      const ssize_t n = ::pread(fd, buffer, sizeof buffer - 1, 0);
      if (n > 0) holder.assign(buffer, static_cast<size_t>(n));
      ::close(fd);
      while (!holder.empty() && (holder.back() == '\n' || holder.back() == '\0')) holder.pop_back();
      if (err == EWOULDBLOCK)
        throw Error(SourceLoc{folder}, "the output folder is in use by another run (" +
                                           (holder.empty() ? std::string("process unknown") : holder) +
                                           "); wait for it to end or choose another folder");
      throw Error(SourceLoc{folder}, std::string("cannot lock the output folder: ") + std::strerror(err));
    }
    struct stat held {}, named {};
    if (::fstat(fd, &held) == 0 && ::stat(path_.c_str(), &named) == 0 && held.st_ino == named.st_ino &&
        held.st_dev == named.st_dev) {
      const std::string who = "process " + std::to_string(::getpid()) + ": " + ownCommandLine() + "\n";
      if (::ftruncate(fd, 0) == 0 && ::pwrite(fd, who.data(), who.size(), 0) < 0) {
        // The holder's description is a courtesy to the next run; the lock holds without it.
      }
      fd_ = fd;
      removeStaleTemporaries(folder);
      return;
    }
    ::close(fd);
  }
  throw Error(SourceLoc{folder}, "cannot lock the output folder: its lock file keeps changing");
}

FolderLock::~FolderLock() {
  if (fd_ < 0) return;
  ::unlink(path_.c_str());
  ::close(fd_);
}

}  // namespace viscera
