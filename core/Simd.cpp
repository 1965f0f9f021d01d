#include "core/Simd.h"

#include <cstdlib>
#include <cstring>

namespace viscera {

namespace {

enum class Level { Generic, Avx2, Avx512 };

Level level() {
  static const Level l = [] {
    Level cpu = Level::Generic;
#if defined(__x86_64__)
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
      cpu = Level::Avx2;
      // libgcc's check includes the operating system's support for the AVX-512 registers.
      if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl")) cpu = Level::Avx512;
    }
#endif
    const char* v = std::getenv("VISCERA_SIMD");
    if (v && std::strcmp(v, "generic") == 0) return Level::Generic;
    if (v && std::strcmp(v, "avx2") == 0 && cpu == Level::Avx512) return Level::Avx2;
    return cpu;
  }();
  return l;
}

}  // namespace

bool useAvx2() { return level() != Level::Generic; }
bool useAvx512() { return level() == Level::Avx512; }

}  // namespace viscera
