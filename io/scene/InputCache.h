// Input files read once per process and shared by every scene built from them: scene variants of
// a batch study name the same meshes, trajectories and transforms thousands of times. An entry is
// keyed by what it is read as, the file's canonical path, size and modification time, so a file
// that changed is read again. Reading errors are not cached. Thread-safe.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <typeinfo>

namespace viscera::io {

namespace detail {
std::shared_ptr<const void> cachedInput(const std::string& path, const std::type_info& type,
                                        const std::function<std::shared_ptr<const void>()>& read);
}  // namespace detail

// The result of read(path), read once while the file is unchanged. `read` throws on bad input.
template <class T, class Read>
std::shared_ptr<const T> cachedRead(const std::string& path, Read&& read) {
  return std::static_pointer_cast<const T>(
      detail::cachedInput(path, typeid(T), [&]() -> std::shared_ptr<const void> { return std::make_shared<const T>(read(path)); }));
}

struct InputCacheStats {
  long hits = 0, reads = 0, entries = 0;
};
InputCacheStats inputCacheStats();
// Forgets every entry (shared copies stay valid).
void clearInputCache();

}  // namespace viscera::io
