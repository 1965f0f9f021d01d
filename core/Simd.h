// Which vector instructions the hand-vectorised kernels may use. The build targets a baseline
// x86-64 (x86-64-v2, which any recent machine runs); kernels with an AVX2 + FMA version take it when the CPU has both,
// unless the environment says VISCERA_SIMD=generic (to compare, or to rule the kernels out).
#pragma once

namespace viscera {

// True when the AVX2 + FMA versions run (decided once per process).
bool useAvx2();

}  // namespace viscera
