#include "apps/viscera/Gnuplot.h"

#include <fcntl.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <vector>

#include "core/Error.h"

extern char** environ;

namespace viscera {

namespace fs = std::filesystem;

void plotWithGnuplot(const fs::path& dir, const std::string& script, const std::string& image) {
  std::string temp = (dir / (image + ".XXXXXX")).string();
  const int fd = ::mkstemp(temp.data());
  if (fd < 0) throw Error(SourceLoc{(dir / image).string()}, std::string("cannot create the plot: ") + std::strerror(errno));
  // mkstemp makes the file private; the plot is as readable as the other outputs.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::fchmod(fd, 0666 & ~mask);
  ::close(fd);
  const std::string tempName = fs::path(temp).filename().string();
  auto fail = [&](const std::string& what) {
    std::error_code ec;
    fs::remove(temp, ec);
    throw Error(SourceLoc{(dir / script).string()}, what);
  };

  const std::vector<std::string> args = {"gnuplot", "-e", "outfile='" + tempName + "'", script};
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addchdir_np(&actions, dir.c_str());
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int err = ::posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (err == ENOENT)
    fail("gnuplot was not found on PATH, so " + image + " was not made (install the Debian package gnuplot-nox, or pass "
         "--no-plot); the other outputs are written");
  if (err != 0) fail(std::string("cannot run gnuplot: ") + std::strerror(err));
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) fail(std::string("lost the gnuplot process: ") + std::strerror(errno));
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    fail("gnuplot failed on the plot script (" +
         (WIFEXITED(status) ? "exit code " + std::to_string(WEXITSTATUS(status)) : std::string("killed by a signal")) + ")");
  if (fs::file_size(temp) == 0) fail("gnuplot wrote no image");
  std::error_code ec;
  fs::rename(temp, dir / image, ec);
  if (ec) fail("cannot move the plot into place: " + ec.message());
}

}  // namespace viscera
