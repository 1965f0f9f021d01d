#include "io/scene/InputCache.h"

#include <filesystem>
#include <deque>
#include <map>
#include <mutex>
#include <tuple>

namespace viscera::io {

namespace {

struct Key {
  std::string type, path;
  std::uintmax_t size;
  std::filesystem::file_time_type mtime;
  bool operator<(const Key& o) const { return std::tie(type, path, size, mtime) < std::tie(o.type, o.path, o.size, o.mtime); }
};

struct Cache {
  std::mutex mutex;
  std::map<Key, std::shared_ptr<const void>> entries;
  // Derived values: (what, type, key bytes), oldest first.
  std::deque<std::pair<std::tuple<std::string, std::string, std::string>, std::shared_ptr<const void>>> derived;
  long hits = 0, reads = 0;
};

constexpr size_t kDerivedEntries = 32;

Cache& cache() {
  static Cache c;
  return c;
}

}  // namespace

namespace detail {

std::shared_ptr<const void> cachedInput(const std::string& path, const std::type_info& type,
                                        const std::function<std::shared_ptr<const void>()>& read) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path canonical = fs::canonical(path, ec);
  // Only regular files are cached: a device or a pipe is read by the reader, which says what is wrong.
  if (ec || !fs::is_regular_file(canonical, ec)) return read();
  const std::uintmax_t size = fs::file_size(canonical, ec);
  const auto mtime = fs::last_write_time(canonical, ec);
  if (ec) return read();
  const Key key{type.name(), canonical.string(), size, mtime};
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  auto it = c.entries.find(key);
  if (it != c.entries.end()) {
    ++c.hits;
    return it->second;
  }
  // An older version of the same file is dropped.
  for (auto e = c.entries.begin(); e != c.entries.end();)
    e = e->first.type == key.type && e->first.path == key.path ? c.entries.erase(e) : std::next(e);
  auto value = read();
  ++c.reads;
  c.entries.emplace(key, value);
  return value;
}

std::shared_ptr<const void> cachedDerived(const std::string& what, const std::type_info& type, std::string key,
                                          const std::function<std::shared_ptr<const void>()>& compute) {
  Cache& c = cache();
  auto id = std::make_tuple(what, std::string(type.name()), std::move(key));
  std::lock_guard<std::mutex> lock(c.mutex);
  for (const auto& [k, v] : c.derived)
    if (k == id) {
      ++c.hits;
      return v;
    }
  auto value = compute();
  if (c.derived.size() >= kDerivedEntries) c.derived.pop_front();
  c.derived.emplace_back(std::move(id), value);
  return value;
}

}  // namespace detail

InputCacheStats inputCacheStats() {
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  return {c.hits, c.reads, static_cast<long>(c.entries.size())};
}

std::vector<std::string> cachedFiles() {
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  std::vector<std::string> files;
  for (const auto& [key, value] : c.entries) files.push_back(key.path);
  return files;
}

void clearInputCache() {
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  c.entries.clear();
  c.derived.clear();
}

}  // namespace viscera::io
