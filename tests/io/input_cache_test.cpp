// The per-process input cache: a file is read once while it is unchanged and again when it
// changes; reading errors are not cached; derived values are shared by equal keys only.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "core/Error.h"
#include "io/scene/InputCache.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using viscera::test_support::TempDir;

namespace {

TEST(InputCache, ReadsOnceUntilTheFileChanges) {
  io::clearInputCache();
  TempDir tmp;
  const std::string path = tmp / "value.txt";
  std::ofstream(path) << "1";
  int reads = 0;
  auto read = [&](const std::string& p) {
    ++reads;
    std::ifstream in(p);
    int v = 0;
    in >> v;
    return v;
  };
  EXPECT_EQ(*io::cachedRead<int>(path, read), 1);
  EXPECT_EQ(*io::cachedRead<int>(path, read), 1);
  EXPECT_EQ(*io::cachedRead<int>(tmp.str() + "/./value.txt", read), 1);  // the same file by another name
  EXPECT_EQ(reads, 1);
  // A new size and modification time: read again.
  std::ofstream(path) << "22";
  std::filesystem::last_write_time(path, std::filesystem::last_write_time(path) + std::chrono::seconds(2));
  EXPECT_EQ(*io::cachedRead<int>(path, read), 22);
  EXPECT_EQ(reads, 2);
  // Read as another type: another entry.
  EXPECT_EQ(*io::cachedRead<long>(path, [&](const std::string& p) { return static_cast<long>(read(p)); }), 22);
  EXPECT_EQ(reads, 3);
}

TEST(InputCache, ErrorsAreNotCached) {
  io::clearInputCache();
  TempDir tmp;
  const std::string path = tmp / "bad.txt";
  std::ofstream(path) << "x";
  int calls = 0;
  auto failing = [&](const std::string& p) -> int {
    ++calls;
    throw Error(SourceLoc{p, 1}, "not a number");
  };
  EXPECT_THROW(io::cachedRead<int>(path, failing), Error);
  EXPECT_THROW(io::cachedRead<int>(path, failing), Error);
  EXPECT_EQ(calls, 2);
}

TEST(InputCache, DerivedValuesAreKeyedByContent) {
  io::clearInputCache();
  int computed = 0;
  auto twice = [&](int v) {
    return *io::cachedDerived<int>("twice", std::to_string(v), [&] {
      ++computed;
      return 2 * v;
    });
  };
  EXPECT_EQ(twice(3), 6);
  EXPECT_EQ(twice(3), 6);
  EXPECT_EQ(twice(4), 8);
  EXPECT_EQ(computed, 2);
  // Many threads asking at once get one value.
  io::clearInputCache();
  computed = 0;
  std::vector<std::thread> pool;
  for (int t = 0; t < 8; ++t) pool.emplace_back([&] { EXPECT_EQ(twice(5), 10); });
  for (auto& t : pool) t.join();
  EXPECT_EQ(computed, 1);
}

}  // namespace
