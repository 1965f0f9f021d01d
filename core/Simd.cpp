#include "core/Simd.h"

#include <cstdlib>
#include <cstring>

namespace viscera {

bool useAvx2() {
  static const bool on = [] {
    if (const char* v = std::getenv("VISCERA_SIMD"); v && std::strcmp(v, "generic") == 0) return false;
#if defined(__x86_64__)
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
    return false;
#endif
  }();
  return on;
}

}  // namespace viscera
