// Which vector instructions the hand-vectorised kernels may use. The build targets a baseline
// x86-64 (x86-64-v2, which any recent machine runs); kernels with an AVX2 + FMA version take it when
// the CPU has both, and the few with an AVX-512 version take that where the CPU (and the operating
// system) has AVX-512F and VL. The environment can lower the level: VISCERA_SIMD=generic (to compare,
// or to rule the kernels out) or VISCERA_SIMD=avx2 (no AVX-512).
#pragma once

namespace viscera {

// True when the AVX2 + FMA versions run (decided once per process).
bool useAvx2();
// True when the AVX-512 versions run (implies useAvx2()).
bool useAvx512();

}  // namespace viscera
