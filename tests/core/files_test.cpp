// Atomic file writes: a file is replaced whole or not at all, and nothing is left behind when
// writing fails (missing folder, a file or folder in the way, no permission).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/Files.h"
#include "tests/support/ErrorOf.h"
#include "tests/support/TempDir.h"

namespace fs = std::filesystem;
using viscera::writeFileAtomic;
using viscera::test_support::errorOf;
using viscera::test_support::TempDir;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void spit(const fs::path& p, const std::string& content) { std::ofstream(p, std::ios::binary) << content; }

#define EXPECT_CONTAINS(text, part) EXPECT_NE(std::string(text).find(part), std::string::npos) << (text)

TEST(Files, AtomicWriteReplacesAndLeavesNoTemporary) {
  const TempDir tmp;
  const fs::path dir = tmp.path();
  const std::string path = (dir / "out.txt").string();
  writeFileAtomic(path, "first");
  writeFileAtomic(path, "second, longer content");
  EXPECT_EQ(slurp(path), "second, longer content");
  writeFileAtomic(path, "");
  EXPECT_EQ(slurp(path), "");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(Files, AtomicWriteIntoMissingFolderThrowsAndCreatesNothing) {
  const TempDir tmp;
  const fs::path dir = tmp.path();
  const fs::path missing = dir / "no_such_folder";
  const std::string path = (missing / "out.vtu").string();
  const std::string msg = errorOf([&] { writeFileAtomic(path, "data"); });
  EXPECT_CONTAINS(msg, path);
  EXPECT_CONTAINS(msg, "No such file or directory");
  EXPECT_FALSE(fs::exists(missing));
  EXPECT_TRUE(fs::is_empty(dir));

  spit(dir / "plain_file", "x");  // a file where a folder should be: fails even for root
  const std::string underFile = (dir / "plain_file" / "out.vtu").string();
  EXPECT_CONTAINS(errorOf([&] { writeFileAtomic(underFile, "data"); }), underFile);
  EXPECT_EQ(slurp(dir / "plain_file"), "x");
}

TEST(Files, AtomicWriteOverAFolderKeepsItAndRemovesTheTemporary) {
  const TempDir tmp;
  const fs::path dir = tmp.path();
  fs::create_directory(dir / "target");
  spit(dir / "target" / "inside", "kept");
  const std::string path = (dir / "target").string();
  const std::string msg = errorOf([&] { writeFileAtomic(path, "data"); });
  EXPECT_CONTAINS(msg, path);
  EXPECT_TRUE(fs::is_directory(dir / "target"));
  EXPECT_EQ(slurp(dir / "target" / "inside"), "kept");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(Files, AtomicWriteInReadOnlyFolderKeepsTheOldFile) {
  if (::geteuid() == 0) GTEST_SKIP() << "root ignores folder permissions";
  const TempDir tmp;
  const fs::path dir = tmp.path();
  const std::string path = (dir / "out.txt").string();
  writeFileAtomic(path, "old");
  fs::permissions(dir, fs::perms::owner_read | fs::perms::owner_exec);
  const std::string msg = errorOf([&] { writeFileAtomic(path, "new"); });
  fs::permissions(dir, fs::perms::owner_all);
  EXPECT_CONTAINS(msg, path);
  EXPECT_CONTAINS(msg, "Permission denied");
  EXPECT_EQ(slurp(path), "old");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

}  // namespace

// One holder at a time: a second lock on the folder names the first holder; the lock file goes
// with its holder, and temporaries left by a killed writer go when the folder is next held.
TEST(Files, AnOutputFolderHasOneHolderAndLosesStaleTemporaries) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  fs::create_directories(out);
  for (const char* name : {"frame_000010.vtu.tmp.4242.4243", "notes.tmp.txt", "x.tmp.12", "kept.vtu"})
    std::ofstream(out / name) << "part";
  {
    const viscera::FolderLock held(out.string());
    EXPECT_TRUE(fs::exists(out / ".viscera.lock"));
    EXPECT_FALSE(fs::exists(out / "frame_000010.vtu.tmp.4242.4243"));
    for (const char* kept : {"notes.tmp.txt", "x.tmp.12", "kept.vtu"}) EXPECT_TRUE(fs::exists(out / kept)) << kept;
    const std::string e = errorOf([&] { viscera::FolderLock second(out.string()); });
    EXPECT_NE(e.find("the output folder is in use by another run (process " + std::to_string(::getpid())), std::string::npos) << e;
  }
  EXPECT_FALSE(fs::exists(out / ".viscera.lock"));
  const viscera::FolderLock again((tmp.path() / "new" / "folder").string());  // created when missing
  EXPECT_TRUE(fs::is_directory(tmp.path() / "new" / "folder"));
}
