#include "engine/fem/TetSimd.h"

#include "core/Simd.h"

#include <cmath>
#include <cstring>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace viscera::fem {

namespace {

// Fields per element in largeTetrahedraLanes: X (12), G (12), volume, lambda, mu, unused; and
// elements per group there (field k of a group's elements is contiguous).
constexpr int kLaneFields = 28;
constexpr int kLaneGroup = 8;

// Field 0 of element e in the lanes; field k follows at k * kLaneGroup.
inline const double* laneData(const double* lanes, int e) {
  return lanes + kLaneFields * kLaneGroup * static_cast<long>(e / kLaneGroup) + e % kLaneGroup;
}

using BlocksKernel = void (*)(const ElementRest*, const double*, const int*, int, int, double, double*, const std::uint16_t*);

// fresh: the element's first-writer bits (addTetrahedraBlocks), by slot index.
inline void blocksGeneric(const double* R, const double* G, double la, double ma, double* values, const int* slots,
                          std::uint16_t fresh) {
  double h[12];  // h = R^T G, column-major 3 x 4
  for (int k = 0; k < 4; ++k)
    for (int r = 0; r < 3; ++r) h[3 * k + r] = R[3 * r] * G[3 * k] + R[3 * r + 1] * G[3 * k + 1] + R[3 * r + 2] * G[3 * k + 2];
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const double* hi = h + 3 * i;
      const double* hj = h + 3 * j;
      if (slots[4 * j + i] < 0) continue;  // not stored (upper storage)
      const double d = ma * (G[3 * i] * G[3 * j] + G[3 * i + 1] * G[3 * j + 1] + G[3 * i + 2] * G[3 * j + 2]);
      double* k = values + 9 * static_cast<long>(slots[4 * j + i]);  // K_ij by columns = K_ji by rows
      if (fresh >> (4 * j + i) & 1) std::fill_n(k, 9, 0.0);
      for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) k[3 * c + r] += la * hi[r] * hj[c] + ma * hj[r] * hi[c] + (r == c ? d : 0.0);
    }
}

// Four or eight doubles, one element per lane (GCC's vector extension: the operators compile to
// AVX or AVX-512 in the kernels of that level and are used nowhere else).
typedef double Lanes __attribute__((vector_size(32)));
typedef double Lanes8 __attribute__((vector_size(64)));

// The factor that normalises a vector of squared length v, lane by lane: 1 / sqrt(v), or 1 for a
// zero vector, which stays zero (as Eigen's normalized(): a collapsed element gets a zero frame
// and finite forces, and the health check names it). Arguments by reference: no vector crosses
// a call boundary. The lane versions take one vector square root and one division (the same
// rounding as the scalar one); they are inlined into the kernels of their level, which are
// flattened for that (an always_inline chain cannot reach a function of a higher level).
inline void reciprocalRoot(const double& v, double& out) { out = v > 0.0 ? 1.0 / std::sqrt(v) : 1.0; }
#if defined(__x86_64__)
__attribute__((target("avx2,fma"))) inline void reciprocalRoot(const Lanes& v, Lanes& out) {
  __m256d w;
  std::memcpy(&w, &v, sizeof w);
  const __m256d one = _mm256_set1_pd(1.0);
  w = _mm256_div_pd(one, _mm256_blendv_pd(one, _mm256_sqrt_pd(w), _mm256_cmp_pd(w, _mm256_setzero_pd(), _CMP_GT_OQ)));
  std::memcpy(&out, &w, sizeof w);
}
__attribute__((target("avx512f,avx512vl,fma"))) inline void reciprocalRoot(const Lanes8& v, Lanes8& out) {
  __m512d w;
  std::memcpy(&w, &v, sizeof w);
  const __m512d one = _mm512_set1_pd(1.0);
  w = _mm512_div_pd(one, _mm512_mask_sqrt_pd(one, _mm512_cmp_pd_mask(w, _mm512_setzero_pd(), _CMP_GT_OQ), w));
  std::memcpy(&out, &w, sizeof w);
}
#endif

// The stress of the corotational ("large") tetrahedron in its frame, for one element (T = double)
// or four or eight (T = Lanes, Lanes8). p: node positions; X, G: rest positions in the element
// frame and shape-function gradients (column-major 3 x 4; In: a pointer, or LaneFields); ex, ey,
// ez: the frame's axes; s: sigma's entries (00, 11, 22, 01, 02, 12).
template <class T, class In>
__attribute__((always_inline)) inline void largeStress(const T (&p)[4][3], In X, In G, const T& lambda, const T& mu, T (&ex)[3],
                                                       T (&ey)[3], T (&ez)[3], T (&s)[6]) {
  T e[4][3];  // edges from node 0 (e[0] = 0)
  for (int k = 0; k < 4; ++k)
    for (int r = 0; r < 3; ++r) e[k][r] = p[k][r] - p[0][r];
  // Frame: x along edge 1, z normal to edges 1 and 2, y = z cross x.
  T ia, iw;
  reciprocalRoot(e[1][0] * e[1][0] + e[1][1] * e[1][1] + e[1][2] * e[1][2], ia);
  for (int r = 0; r < 3; ++r) ex[r] = e[1][r] * ia;
  const T w[3] = {ex[1] * e[2][2] - ex[2] * e[2][1], ex[2] * e[2][0] - ex[0] * e[2][2], ex[0] * e[2][1] - ex[1] * e[2][0]};
  reciprocalRoot(w[0] * w[0] + w[1] * w[1] + w[2] * w[2], iw);
  for (int r = 0; r < 3; ++r) ez[r] = w[r] * iw;
  ey[0] = ez[1] * ex[2] - ez[2] * ex[1];
  ey[1] = ez[2] * ex[0] - ez[0] * ex[2];
  ey[2] = ez[0] * ex[1] - ez[1] * ex[0];
  // Displacements in the element frame, U_k = R (p_k - p_0) - X_k, and their gradient H = U G^T.
  T H[3][3] = {};
  for (int k = 0; k < 4; ++k) {
    const T u[3] = {ex[0] * e[k][0] + ex[1] * e[k][1] + ex[2] * e[k][2] - X[3 * k],
                    ey[0] * e[k][0] + ey[1] * e[k][1] + ey[2] * e[k][2] - X[3 * k + 1],
                    ez[0] * e[k][0] + ez[1] * e[k][1] + ez[2] * e[k][2] - X[3 * k + 2]};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) H[r][c] += u[r] * G[3 * k + c];
  }
  // sigma = lambda tr(H) I + mu (H + H^T).
  const T tr = lambda * (H[0][0] + H[1][1] + H[2][2]);
  s[0] = tr + 2.0 * mu * H[0][0];
  s[1] = tr + 2.0 * mu * H[1][1];
  s[2] = tr + 2.0 * mu * H[2][2];
  s[3] = mu * (H[0][1] + H[1][0]);
  s[4] = mu * (H[0][2] + H[2][0]);
  s[5] = mu * (H[1][2] + H[2][1]);
}

// The element force of the corotational tetrahedron (as largeStress, with its volume): R, the
// frame (column-major); f, the nodal forces -V R^T sigma g_k.
template <class T, class In>
__attribute__((always_inline)) inline void largeForce(const T (&p)[4][3], In X, In G, const T& volume, const T& lambda, const T& mu,
                                                      T (&R)[9], T (&f)[4][3]) {
  T ex[3], ey[3], ez[3], s[6];
  largeStress(p, X, G, lambda, mu, ex, ey, ez, s);
  for (int c = 0; c < 3; ++c) {
    R[3 * c] = ex[c];
    R[3 * c + 1] = ey[c];
    R[3 * c + 2] = ez[c];
  }
  for (int k = 0; k < 4; ++k) {
    const In g = G + 3 * k;
    const T l0 = -volume * (s[0] * g[0] + s[3] * g[1] + s[4] * g[2]);
    const T l1 = -volume * (s[3] * g[0] + s[1] * g[1] + s[5] * g[2]);
    const T l2 = -volume * (s[4] * g[0] + s[5] * g[1] + s[2] * g[2]);
    for (int r = 0; r < 3; ++r) f[k][r] = l0 * ex[r] + l1 * ey[r] + l2 * ez[r];
  }
}

// The von Mises stress of sigma (largeStress's entries), squared.
template <class T>
__attribute__((always_inline)) inline T vonMisesSquared(const T (&s)[6]) {
  const T a = s[0] - s[1], b = s[1] - s[2], c = s[2] - s[0];
  return 0.5 * (a * a + b * b + c * c) + 3.0 * (s[3] * s[3] + s[5] * s[5] + s[4] * s[4]);
}

using VonMisesKernel = void (*)(const double*, const int*, int, const ElementRest*, const double*, double*);

void largeVonMisesGeneric(const double* x, const int* tets, int count, const ElementRest* rest, const double*, double* out) {
  for (int e = 0; e < count; ++e) {
    const ElementRest& r = rest[e];
    double p[4][3], ex[3], ey[3], ez[3], s[6];
    for (int k = 0; k < 4; ++k)
      for (int c = 0; c < 3; ++c) p[k][c] = x[3 * static_cast<long>(tets[4 * e + k]) + c];
    largeStress(p, r.X.data(), r.G.data(), r.lame.lambda, r.lame.mu, ex, ey, ez, s);
    out[e] = std::sqrt(vonMisesSquared(s));
  }
}

// One element, from the model's rest data.
__attribute__((always_inline)) inline void largeForceOne(const double* x, const int* nodes, const double* X, const double* G,
                                                         double volume, double lambda, double mu, double* R, double* f) {
  double p[4][3], Rl[9], fl[4][3];
  for (int k = 0; k < 4; ++k)
    for (int r = 0; r < 3; ++r) p[k][r] = x[3 * static_cast<long>(nodes[k]) + r];
  largeForce(p, X, G, volume, lambda, mu, Rl, fl);
  for (int c = 0; c < 9; ++c) R[c] = Rl[c];
  for (int k = 0; k < 4; ++k)
    for (int r = 0; r < 3; ++r) f[3 * static_cast<long>(nodes[k]) + r] += fl[k][r];
}

using ForcesKernel = void (*)(const double*, const int*, int, int, const ElementRest*, const double*, double*, double*);

void largeForcesGeneric(const double* x, const int* tets, int first, int count, const ElementRest* rest, const double*,
                        double* R, double* f) {
  for (int e = first; e < first + count; ++e) {
    const ElementRest& r = rest[e];
    largeForceOne(x, tets + 4 * e, r.X.data(), r.G.data(), r.volume, r.lame.lambda, r.lame.mu, R + 9 * e, f);
  }
}

#if defined(__x86_64__)
// Groups of four (or eight) elements starting at a multiple of four (eight) run in the lanes; the
// rest one by one. A group's rest values are read from the lanes where they are used, each field a
// vector of V (copied first to the stack, the group's 28 fields waited on their loads at once).
template <class V>
struct LaneFields {
  const double* at;  // field 0 of the group's first element
  __attribute__((always_inline)) V operator[](int k) const {
    V v;
    std::memcpy(&v, at + kLaneGroup * k, sizeof v);  // unaligned
    return v;
  }
  LaneFields operator+(int k) const { return {at + kLaneGroup * k}; }
};

// The positions of the nodes of the group starting at e, one element per lane.
__attribute__((target("avx2,fma"))) inline void loadPositions(const double* x, const int* tets, int e, Lanes (&p)[4][3]) {
  const int* t = tets + 4 * e;
  for (int k = 0; k < 4; ++k)
    for (int r = 0; r < 3; ++r)
      p[k][r] = Lanes{x[3 * static_cast<long>(t[k]) + r], x[3 * static_cast<long>(t[4 + k]) + r],
                      x[3 * static_cast<long>(t[8 + k]) + r], x[3 * static_cast<long>(t[12 + k]) + r]};
}

__attribute__((target("avx512f,avx512vl,fma"))) inline void loadPositions(const double* x, const int* tets, int e, Lanes8 (&p)[4][3]) {
  const int* t = tets + 4 * e;
  const auto at = [&](int l, int k, int r) { return x[3 * static_cast<long>(t[4 * l + k]) + r]; };
  for (int k = 0; k < 4; ++k)
    for (int r = 0; r < 3; ++r)
      p[k][r] = Lanes8{at(0, k, r), at(1, k, r), at(2, k, r), at(3, k, r), at(4, k, r), at(5, k, r), at(6, k, r), at(7, k, r)};
}

// The W elements starting at e in the lanes of V: their frames into R, their forces added to f
// (element by element, in order).
template <class V, int W>
__attribute__((always_inline)) inline void largeForcesGroup(const double* x, const int* tets, const double* lanes, int e, double* R,
                                                            double* f) {
  V p[4][3], Rl[9], fl[4][3];
  loadPositions(x, tets, e, p);
  const LaneFields<V> in{laneData(lanes, e)};
  largeForce(p, in, in + 12, in[24], in[25], in[26], Rl, fl);
  const int* t = tets + 4 * e;
  for (int l = 0; l < W; ++l) {
    double* Re = R + 9 * static_cast<long>(e + l);
    for (int c = 0; c < 9; ++c) Re[c] = Rl[c][l];
    for (int k = 0; k < 4; ++k)
      for (int r = 0; r < 3; ++r) f[3 * static_cast<long>(t[4 * l + k]) + r] += fl[k][r][l];
  }
}

__attribute__((target("avx2,fma"), flatten)) void largeForcesAvx2(const double* x, const int* tets, int first, int count,
                                                                  const ElementRest* rest, const double* lanes, double* R, double* f) {
  const int end = first + count;
  for (int e = first; e < end;) {
    if (e % 4 == 0 && e + 4 <= end) {
      largeForcesGroup<Lanes, 4>(x, tets, lanes, e, R, f);
      e += 4;
      continue;
    }
    const ElementRest& r = rest[e];
    largeForceOne(x, tets + 4 * e, r.X.data(), r.G.data(), r.volume, r.lame.lambda, r.lame.mu, R + 9 * e, f);
    ++e;
  }
}

// Eight lanes: the chain of square roots and divisions that builds each frame takes as long as
// with four, for twice the elements.
__attribute__((target("avx512f,avx512vl,fma"), flatten)) void largeForcesAvx512(const double* x, const int* tets, int first, int count,
                                                                                const ElementRest* rest, const double* lanes,
                                                                                double* R, double* f) {
  const int end = first + count;
  for (int e = first; e < end;) {
    if (e % 8 == 0 && e + 8 <= end) {
      largeForcesGroup<Lanes8, 8>(x, tets, lanes, e, R, f);
      e += 8;
    } else if (e % 4 == 0 && e + 4 <= end) {
      largeForcesGroup<Lanes, 4>(x, tets, lanes, e, R, f);
      e += 4;
    } else {
      const ElementRest& r = rest[e];
      largeForceOne(x, tets + 4 * e, r.X.data(), r.G.data(), r.volume, r.lame.lambda, r.lame.mu, R + 9 * e, f);
      ++e;
    }
  }
}

// A 3 x 3 block by columns is nine doubles: two four-lane vectors, (B00 B10 B20 B01) and
// (B11 B21 B02 B12), and B22 (the matrix stores its blocks by rows, so K_ij is written, by
// columns, where K_ji goes). With P = (h0 h1 h2 h0), S = (h0 h0 h0 h1), Q = (h1 h2 h0 h1),
// T = (h1 h1 h2 h2) of a node's h, the block (i, j) is
//   la P_i S_j + ma P_j S_i,   la Q_i T_j + ma Q_j T_i,   (la + ma) h_i2 h_j2,
// plus d = ma g_i . g_j on its diagonal (lanes 0 of both vectors and B22). Loads and stores never
// overlap, so no store has to be forwarded to a wider load.
__attribute__((target("avx2,fma"), always_inline)) inline void blocksAvx2(const double* R, const double* G, double la, double ma,
                                                                          double* values, const int* slots, std::uint16_t fresh) {
  double h[4][3];  // h = R^T G, the multiply-adds spelt out: blocksAvx512 forms them in this order
  for (int k = 0; k < 4; ++k)
    for (int r = 0; r < 3; ++r)
      h[k][r] = std::fma(R[3 * r + 2], G[3 * k + 2], std::fma(R[3 * r], G[3 * k], R[3 * r + 1] * G[3 * k + 1]));
  __m256d S[4], T[4], laP[4], laQ[4], maP[4], maQ[4];
  for (int k = 0; k < 4; ++k) {
    const double* v = h[k];
    const __m256d P = _mm256_set_pd(v[0], v[2], v[1], v[0]);
    const __m256d Q = _mm256_set_pd(v[1], v[0], v[2], v[1]);
    S[k] = _mm256_set_pd(v[1], v[0], v[0], v[0]);
    T[k] = _mm256_set_pd(v[2], v[2], v[1], v[1]);
    laP[k] = _mm256_mul_pd(_mm256_set1_pd(la), P);
    laQ[k] = _mm256_mul_pd(_mm256_set1_pd(la), Q);
    maP[k] = _mm256_mul_pd(_mm256_set1_pd(ma), P);
    maQ[k] = _mm256_mul_pd(_mm256_set1_pd(ma), Q);
  }
  const double lm = la + ma;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      if (slots[4 * j + i] < 0) continue;
      const double d = ma * (G[3 * i] * G[3 * j] + G[3 * i + 1] * G[3 * j + 1] + G[3 * i + 2] * G[3 * j + 2]);
      const __m256d diag = _mm256_set_pd(0, 0, 0, d);
      const __m256d v0 = _mm256_fmadd_pd(laP[i], S[j], _mm256_fmadd_pd(maP[j], S[i], diag));
      const __m256d v1 = _mm256_fmadd_pd(laQ[i], T[j], _mm256_fmadd_pd(maQ[j], T[i], diag));
      double* k = values + 9 * static_cast<long>(slots[4 * j + i]);  // K_ij by columns = K_ji by rows
      const bool set = fresh >> (4 * j + i) & 1;
      const __m256d keep = _mm256_castsi256_pd(_mm256_set1_epi64x(set ? 0 : -1));  // the earlier value, or zero
      _mm256_storeu_pd(k, _mm256_add_pd(_mm256_and_pd(_mm256_loadu_pd(k), keep), v0));
      _mm256_storeu_pd(k + 4, _mm256_add_pd(_mm256_and_pd(_mm256_loadu_pd(k + 4), keep), v1));
      k[8] = (set ? 0.0 : k[8]) + (lm * h[i][2] * h[j][2] + d);
    }
}

// Elements [first, first + count): one call per run, so no call per element.
__attribute__((target("avx2,fma"))) void blocksRangeAvx2(const ElementRest* rest, const double* R, const int* slots, int first,
                                                         int count, double kFactor, double* values,
                                                         const std::uint16_t* firstWriter) {
  for (int e = first; e < first + count; ++e) {
    const ElementRest& r = rest[e];
    const double a = -kFactor * r.volume;
    blocksAvx2(R + 9 * static_cast<long>(e), r.G.data(), a * r.lame.lambda, a * r.lame.mu, values, slots + 16 * static_cast<long>(e),
               firstWriter ? firstWriter[e] : std::uint16_t{0});
  }
}

// The same blocks with AVX-512: eight of a block's nine entries (by columns) in one vector, so
// that each block is two fused multiply-adds and one load-add-store (a third less time than
// blocksAvx2 on the gel phantom); the ninth entry as there. h = R^T G is formed in the lanes' own
// patterns from R's entries (h written as scalars and read back as a vector waited on the stores:
// a quarter of this kernel's time), with the multiply-adds of blocksAvx2 in their order: the same
// results to the bit. The loops over the node pairs are unrolled: all vectors stay in registers.
__attribute__((target("avx512f,avx512vl,fma"), always_inline)) inline void blocksAvx512(const double* R, const double* G, double la,
                                                                                       double ma, double* values, const int* slots,
                                                                                       std::uint16_t fresh) {
  // Lane p of a block holds entry (r, c) = (p % 3, p / 3): P = h by rows, S = h by columns, so
  // P_k = sum_m R(p % 3, m) g_km and S_k = sum_m R(p / 3, m) g_km, R by rows (index 8: R(2, 2)).
  const __m512d r07 = _mm512_loadu_pd(R), r8 = _mm512_set1_pd(R[8]);
  const __m512d byRow[3] = {_mm512_permutex2var_pd(r07, _mm512_set_epi64(3, 0, 6, 3, 0, 6, 3, 0), r8),
                            _mm512_permutex2var_pd(r07, _mm512_set_epi64(4, 1, 7, 4, 1, 7, 4, 1), r8),
                            _mm512_permutex2var_pd(r07, _mm512_set_epi64(5, 2, 8, 5, 2, 8, 5, 2), r8)};
  const __m512d byCol[3] = {_mm512_permutex2var_pd(r07, _mm512_set_epi64(6, 6, 3, 3, 3, 0, 0, 0), r8),
                            _mm512_permutex2var_pd(r07, _mm512_set_epi64(7, 7, 4, 4, 4, 1, 1, 1), r8),
                            _mm512_permutex2var_pd(r07, _mm512_set_epi64(8, 8, 5, 5, 5, 2, 2, 2), r8)};
  __m512d S[4], laP[4], maP[4];
  double h2[4];  // h's third entries, for the ninth entry of each block
  for (int k = 0; k < 4; ++k) {
    const double* g = G + 3 * k;
    const __m512d g0 = _mm512_set1_pd(g[0]), g1 = _mm512_set1_pd(g[1]), g2 = _mm512_set1_pd(g[2]);
    const __m512d P = _mm512_fmadd_pd(byRow[2], g2, _mm512_fmadd_pd(byRow[0], g0, _mm512_mul_pd(byRow[1], g1)));
    S[k] = _mm512_fmadd_pd(byCol[2], g2, _mm512_fmadd_pd(byCol[0], g0, _mm512_mul_pd(byCol[1], g1)));
    h2[k] = std::fma(R[8], g[2], std::fma(R[6], g[0], R[7] * g[1]));
    laP[k] = _mm512_mul_pd(_mm512_set1_pd(la), P);
    maP[k] = _mm512_mul_pd(_mm512_set1_pd(ma), P);
  }
  const double lm = la + ma;
#pragma GCC unroll 4
  for (int i = 0; i < 4; ++i)
#pragma GCC unroll 4
    for (int j = 0; j < 4; ++j) {
      if (slots[4 * j + i] < 0) continue;
      const double d = ma * (G[3 * i] * G[3 * j] + G[3 * i + 1] * G[3 * j + 1] + G[3 * i + 2] * G[3 * j + 2]);
      const __m512d diag = _mm512_maskz_mov_pd(0x11, _mm512_set1_pd(d));  // entries (0, 0) and (1, 1)
      const __m512d v = _mm512_fmadd_pd(laP[i], S[j], _mm512_fmadd_pd(maP[j], S[i], diag));
      double* k = values + 9 * static_cast<long>(slots[4 * j + i]);  // K_ij by columns = K_ji by rows
      const bool set = fresh >> (4 * j + i) & 1;
      _mm512_storeu_pd(k, _mm512_add_pd(_mm512_maskz_loadu_pd(set ? 0 : 0xff, k), v));  // the earlier value, or zero
      k[8] = (set ? 0.0 : k[8]) + (lm * h2[i] * h2[j] + d);
    }
}

__attribute__((target("avx512f,avx512vl,fma"))) void blocksRangeAvx512(const ElementRest* rest, const double* R, const int* slots,
                                                                      int first, int count, double kFactor, double* values,
                                                                      const std::uint16_t* firstWriter) {
  for (int e = first; e < first + count; ++e) {
    const ElementRest& r = rest[e];
    const double a = -kFactor * r.volume;
    blocksAvx512(R + 9 * static_cast<long>(e), r.G.data(), a * r.lame.lambda, a * r.lame.mu, values, slots + 16 * static_cast<long>(e),
               firstWriter ? firstWriter[e] : std::uint16_t{0});
  }
}
#endif

void blocksRangeGeneric(const ElementRest* rest, const double* R, const int* slots, int first, int count, double kFactor,
                        double* values, const std::uint16_t* firstWriter) {
  for (int e = first; e < first + count; ++e) {
    const ElementRest& r = rest[e];
    const double a = -kFactor * r.volume;
    blocksGeneric(R + 9 * static_cast<long>(e), r.G.data(), a * r.lame.lambda, a * r.lame.mu, values, slots + 16 * static_cast<long>(e),
               firstWriter ? firstWriter[e] : std::uint16_t{0});
  }
}

// Orientation test of one or four elements: the determinant of the edges from node 0 times the
// rest orientation; an element whose product is not positive (or not a number) is inverted.
template <class T>
__attribute__((always_inline)) inline void orientedVolume(const T (&p)[4][3], const T& sign, T& v) {
  const T a[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
  const T b[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
  const T c[3] = {p[3][0] - p[0][0], p[3][1] - p[0][1], p[3][2] - p[0][2]};
  v = sign * (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]));
}

using InvertedKernel = void (*)(const double*, const int*, int, int, const double*, std::vector<int>&);

// Elements [first, end); sign: each element's rest orientation, contiguous (read from the elements'
// rest data, one cache line each, it took most of this check's time).
void invertedGeneric(const double* x, const int* tets, int first, int end, const double* sign, std::vector<int>& bad) {
  for (int e = first; e < end; ++e) {
    double p[4][3];
    for (int k = 0; k < 4; ++k)
      for (int r = 0; r < 3; ++r) p[k][r] = x[3 * static_cast<long>(tets[4 * e + k]) + r];
    double v;
    orientedVolume(p, sign[e], v);
    if (!(v > 0.0)) bad.push_back(e);
  }
}

#if defined(__x86_64__)
// Whether every lane is above zero (a NaN is not): one comparison, where a test per lane branched.
__attribute__((target("avx2,fma"))) inline bool allPositive(const Lanes& v) {
  __m256d m;
  std::memcpy(&m, &v, sizeof m);
  return _mm256_movemask_pd(_mm256_cmp_pd(m, _mm256_setzero_pd(), _CMP_GT_OQ)) == 0xf;
}

__attribute__((target("avx512f,avx512vl,fma"))) inline bool allPositive(const Lanes8& v) {
  __m512d m;
  std::memcpy(&m, &v, sizeof m);
  return _mm512_cmp_pd_mask(m, _mm512_setzero_pd(), _CMP_GT_OQ) == 0xff;
}

// The groups of W elements (lanes of V) from `first` on while a whole group fits before `end`;
// returns where they stop.
template <class V, int W>
__attribute__((always_inline)) inline int invertedGroups(const double* x, const int* tets, int first, int end, const double* sign,
                                                         std::vector<int>& bad) {
  int e = first;
  for (; e + W <= end; e += W) {
    V p[4][3], sg, v;
    loadPositions(x, tets, e, p);
    std::memcpy(&sg, sign + e, sizeof sg);
    orientedVolume(p, sg, v);
    if (allPositive(v)) continue;
    for (int l = 0; l < W; ++l)
      if (!(v[l] > 0.0)) bad.push_back(e + l);
  }
  return e;
}

__attribute__((target("avx2,fma"), flatten)) void invertedAvx2(const double* x, const int* tets, int first, int end, const double* sign,
                                                               std::vector<int>& bad) {
  invertedGeneric(x, tets, invertedGroups<Lanes, 4>(x, tets, first, end, sign, bad), end, sign, bad);
}

__attribute__((target("avx512f,avx512vl,fma"), flatten)) void invertedAvx512(const double* x, const int* tets, int first, int end,
                                                                             const double* sign, std::vector<int>& bad) {
  const int e = invertedGroups<Lanes, 4>(x, tets, invertedGroups<Lanes8, 8>(x, tets, first, end, sign, bad), end, sign, bad);
  invertedGeneric(x, tets, e, end, sign, bad);
}

__attribute__((target("avx2,fma"), flatten)) void largeVonMisesAvx2(const double* x, const int* tets, int count, const ElementRest* rest,
                                                           const double* lanes, double* out) {
  int e = 0;
  for (; e + 4 <= count; e += 4) {
    Lanes p[4][3], ex[3], ey[3], ez[3], s[6];
    loadPositions(x, tets, e, p);
    const LaneFields<Lanes> in{laneData(lanes, e)};
    largeStress(p, in, in + 12, in[25], in[26], ex, ey, ez, s);
    const Lanes v = vonMisesSquared(s);
    for (int l = 0; l < 4; ++l) out[e + l] = std::sqrt(v[l]);
  }
  largeVonMisesGeneric(x, tets + 4 * e, count - e, rest + e, nullptr, out + e);
}
#endif

// Chosen once, on first use.
struct Kernels {
  const char* version = "generic";
  BlocksKernel blocks = blocksRangeGeneric;
  ForcesKernel forces = largeForcesGeneric;
  InvertedKernel inverted = invertedGeneric;
  VonMisesKernel vonMises = largeVonMisesGeneric;
  Kernels() {
#if defined(__x86_64__)
    if (useAvx2()) {
      version = "avx2";
      blocks = blocksRangeAvx2;
      forces = largeForcesAvx2;
      inverted = invertedAvx2;
      vonMises = largeVonMisesAvx2;
    }
    if (useAvx512()) {
      version = "avx512";
      blocks = blocksRangeAvx512;
      forces = largeForcesAvx512;
      inverted = invertedAvx512;
    }
#endif
  }
};

const Kernels& kernels() {
  static const Kernels k;
  return k;
}

}  // namespace

void addTetrahedraBlocks(const std::vector<ElementRest>& rest, const Eigen::Matrix3d* R, const std::array<int, 16>* slots,
                         int first, int count, double kFactor, double* values, const std::uint16_t* firstWriter) {
  kernels().blocks(rest.data(), R->data(), slots->data(), first, count, kFactor, values, firstWriter);
}

void largeTetrahedraVonMises(const double* x, const int* tets, const std::vector<ElementRest>& rest,
                             const std::vector<double>& lanes, double* out) {
  kernels().vonMises(x, tets, static_cast<int>(rest.size()), rest.data(), lanes.data(), out);
}

std::vector<double> largeTetrahedraLanes(const std::vector<ElementRest>& rest) {
  const size_t groups = (rest.size() + kLaneGroup - 1) / kLaneGroup;
  std::vector<double> lanes(kLaneFields * kLaneGroup * groups, 0.0);
  for (size_t e = 0; e < rest.size(); ++e) {
    double* g = lanes.data() + (laneData(lanes.data(), static_cast<int>(e)) - lanes.data());
    const ElementRest& r = rest[e];
    for (int k = 0; k < 12; ++k) {
      g[kLaneGroup * k] = r.X.data()[k];
      g[kLaneGroup * (12 + k)] = r.G.data()[k];
    }
    g[kLaneGroup * 24] = r.volume;
    g[kLaneGroup * 25] = r.lame.lambda;
    g[kLaneGroup * 26] = r.lame.mu;
  }
  return lanes;
}

void addLargeTetrahedraForces(const double* x, const int* tets, int first, int count, const std::vector<ElementRest>& rest,
                              const std::vector<double>& lanes, Eigen::Matrix3d* R, double* f) {
  kernels().forces(x, tets, first, count, rest.data(), lanes.data(), R->data(), f);
}

std::vector<double> restSigns(const std::vector<ElementRest>& rest) {
  std::vector<double> sign(rest.size());
  for (size_t e = 0; e < rest.size(); ++e) sign[e] = rest[e].sign;
  return sign;
}

std::vector<int> invertedTetrahedra(const double* x, const int* tets, const std::vector<double>& sign) {
  std::vector<int> bad;
  kernels().inverted(x, tets, 0, static_cast<int>(sign.size()), sign.data(), bad);
  return bad;
}

const char* tetrahedronKernelsVersion() { return kernels().version; }

}  // namespace viscera::fem
