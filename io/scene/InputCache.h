// Input files read once per process and shared by every scene built from them: scene variants of
// a batch study name the same meshes, trajectories and transforms thousands of times. An entry is
// keyed by what it is read as, the file's canonical path, size and modification time, so a file
// that changed is read again. Reading errors are not cached. Thread-safe.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <typeinfo>
#include <vector>

namespace viscera::io {

namespace detail {
std::shared_ptr<const void> cachedInput(const std::string& path, const std::type_info& type,
                                        const std::function<std::shared_ptr<const void>()>& read);
std::shared_ptr<const void> cachedDerived(const std::string& what, const std::type_info& type, std::string key,
                                          const std::function<std::shared_ptr<const void>()>& compute);
}  // namespace detail

// The result of read(path), read once while the file is unchanged. `read` throws on bad input.
template <class T, class Read>
std::shared_ptr<const T> cachedRead(const std::string& path, Read&& read) {
  return std::static_pointer_cast<const T>(
      detail::cachedInput(path, typeid(T), [&]() -> std::shared_ptr<const void> { return std::make_shared<const T>(read(path)); }));
}

// What `compute()` derives from the inputs whose bytes are `key` (a mesh's elements and rest
// positions, say), computed once while an equal key is asked for: scene variants share their
// topology-derived data (element colourings, boundary surfaces) as they share the files.
// `what` names the computation. At most a few dozen entries are kept (the oldest go first).
template <class T, class Compute>
std::shared_ptr<const T> cachedDerived(const std::string& what, std::string key, Compute&& compute) {
  return std::static_pointer_cast<const T>(detail::cachedDerived(
      what, typeid(T), std::move(key), [&]() -> std::shared_ptr<const void> { return std::make_shared<const T>(compute()); }));
}
// The bytes of a dense Eigen matrix (its shape, then its coefficients), as a cachedDerived key.
template <class M>
std::string keyBytes(const M& m) {
  std::string k(reinterpret_cast<const char*>(m.data()), sizeof(typename M::Scalar) * static_cast<size_t>(m.size()));
  k += "/" + std::to_string(m.rows()) + "x" + std::to_string(m.cols());
  return k;
}

struct InputCacheStats {
  long hits = 0, reads = 0, entries = 0;
};
InputCacheStats inputCacheStats();
// The files read through the cache so far (canonical paths): the inputs of a run, which its
// outputs must not overwrite.
std::vector<std::string> cachedFiles();
// Forgets every entry (shared copies stay valid).
void clearInputCache();

}  // namespace viscera::io
