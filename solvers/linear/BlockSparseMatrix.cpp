#include "solvers/linear/BlockSparseMatrix.h"
#include "core/Simd.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#if defined(__x86_64__)
#include <immintrin.h>
#endif
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace viscera {

void BlockSparseMatrix::setPattern(int nBlocks, const std::vector<std::pair<int, int>>& pairs, Storage storage) {
  storage_ = storage;
  n_ = nBlocks;
  held_ = false;
  heldNodes_.clear();
  heldSlots_.clear();
  rowEnd_.clear();
  std::vector<std::vector<int>> rows(n_);
  for (int i = 0; i < n_; ++i) rows[i].push_back(i);
  for (const auto& [i, j] : pairs) {
    if (storage != Storage::Upper || i <= j) rows[i].push_back(j);
    if (storage != Storage::Upper || j <= i) rows[j].push_back(i);
  }
  rowStart_.assign(n_ + 1, 0);
  cols_.clear();
  diag_.assign(n_, -1);
  for (int i = 0; i < n_; ++i) {
    auto& r = rows[i];
    std::sort(r.begin(), r.end());
    r.erase(std::unique(r.begin(), r.end()), r.end());
    rowStart_[i] = static_cast<int>(cols_.size());
    for (int j : r) {
      if (j == i) diag_[i] = static_cast<int>(cols_.size());
      cols_.push_back(j);
    }
  }
  rowStart_[n_] = static_cast<int>(cols_.size());
  colStart_.clear();
  colBlocks_.clear();
  if (upper()) {
    colStart_.assign(n_ + 1, 0);
    for (int k = 0; k < n_; ++k)
      for (int s = rowStart_[k] + 1; s < rowStart_[k + 1]; ++s) ++colStart_[cols_[s] + 1];
    for (int j = 0; j < n_; ++j) colStart_[j + 1] += colStart_[j];
    colBlocks_.resize(colStart_[n_]);
    std::vector<int> next(colStart_.begin(), colStart_.end() - 1);
    for (int k = 0; k < n_; ++k)  // rows in order: each column's list comes out ascending
      for (int s = rowStart_[k] + 1; s < rowStart_[k + 1]; ++s) colBlocks_[next[cols_[s]]++] = {k, s};
  }
  // One double of padding: the vector kernels load each block row as four doubles.
  values_.assign(9 * cols_.size() + 1, 0.0);
}

int BlockSparseMatrix::slot(int i, int j) const {
  if (upper() && j < i) return -1;
  auto b = cols_.begin() + rowStart_[i], e = cols_.begin() + rowStart_[i + 1];
  auto it = std::lower_bound(b, e, j);
  return it != e && *it == j ? static_cast<int>(it - cols_.begin()) : -1;
}

void BlockSparseMatrix::addSymmetric(int i, int j, const Eigen::Matrix3d& B) {
  if (upper() && j < i) return;
  const int s = slot(i, j);
  if (s < 0) throw std::logic_error("block (" + std::to_string(i) + ", " + std::to_string(j) + ") is not in the matrix's pattern");
  block(s) += B;
}

void BlockSparseMatrix::setZero() {
  held_ = false;
  std::fill(values_.begin(), values_.end(), 0.0);
}

void BlockSparseMatrix::scale(double a) {
  for (double& v : values_) v *= a;
}

namespace {

// Block rows [r0, r1) of y = A x; n is the number of block rows (x has 3 n entries).
using RowsKernel = void (*)(const int* rowStart, const int* cols, const double* values, const double* x, double* y,
                            int r0, int r1, int n);

void multiplyRowsBaseline(const int* rowStart, const int* cols, const double* values, const double* x, double* y,
                          int r0, int r1, int) {
  for (int i = r0; i < r1; ++i) {
    Eigen::Vector3d acc = Eigen::Vector3d::Zero();
    for (int s = rowStart[i]; s < rowStart[i + 1]; ++s)
      acc.noalias() += Eigen::Map<const BlockSparseMatrix::Block>(values + 9 * s) * Eigen::Map<const Eigen::Vector3d>(x + 3 * cols[s]);
    Eigen::Map<Eigen::Vector3d>(y + 3 * i) = acc;
  }
}

// Upper storage: row i's first block is its diagonal. Block (i, j) above the diagonal adds
// B x_j to y_i and B^T x_i to y_j. One thread sweeps the rows and scatters the transposed products
// (y zeroed first); several threads gather them, row j taking its column's blocks (k, j) in
// ascending k. Both add each transposed product t to y_j (or its running sum) in that order, then
// the row's own sum: the same result to the bit.
struct UpperPattern {
  const int* rowStart;
  const int* rowEnd;  // where a row's blocks end for the product: rowStart + 1, or, for a held row, its diagonal + 1
  const int* cols;
  const double* values;
  const int* colStart;
  const std::pair<int, int>* colBlocks;
  int n;
};
// A by value: a local copy, which no store through y can alias (so its fields stay in registers).
// The scatter sweep also returns x . y in *dot when dot is not null (the gather ignores it).
using UpperKernel = void (*)(UpperPattern A, const double* x, double* y, int r0, int r1, double* dot);
// x . y over n node triples, summed as the scatter sweeps sum it (rowDot's order).
using DotKernel = double (*)(const double* x, const double* y, int n);

// x_i . y_i added to the sums of the triples' entries d.
inline void rowDot(const double* xi, const double* yi, double (&d)[3]) {
  for (int k = 0; k < 3; ++k) d[k] += xi[k] * yi[k];
}

double dotBaseline(const double* x, const double* y, int n) {
  double d[3] = {0, 0, 0};
  for (long i = 0; i < n; ++i) rowDot(x + 3 * i, y + 3 * i, d);
  return d[0] + d[1] + d[2];
}

// B^T u, for the block at b (row-major).
inline void transposedTimes(const double* b, const double* u, double (&t)[3]) {
  for (int c = 0; c < 3; ++c) t[c] = b[c] * u[0] + b[3 + c] * u[1] + b[6 + c] * u[2];
}

// Row i's own sum: its blocks times the x_j, added to acc.
inline void upperRowSum(const UpperPattern& A, const double* x, int i, double (&acc)[3]) {
  double r[3] = {0, 0, 0};
  for (int s = A.rowStart[i]; s < A.rowEnd[i]; ++s) {
    const double* b = A.values + 9 * static_cast<long>(s);
    const double* u = x + 3 * static_cast<long>(A.cols[s]);
    for (int k = 0; k < 3; ++k) r[k] += b[3 * k] * u[0] + b[3 * k + 1] * u[1] + b[3 * k + 2] * u[2];
  }
  for (int k = 0; k < 3; ++k) acc[k] += r[k];
}

void upperScatterBaseline(UpperPattern A, const double* x, double* y, int, int, double* dot) {
  double d[3] = {0, 0, 0};
  std::fill(y, y + 3 * static_cast<long>(A.n), 0.0);
  for (int i = 0; i < A.n; ++i) {
    for (int s = A.rowStart[i] + 1; s < A.rowEnd[i]; ++s) {
      double t[3];
      transposedTimes(A.values + 9 * static_cast<long>(s), x + 3 * static_cast<long>(i), t);
      for (int c = 0; c < 3; ++c) y[3 * static_cast<long>(A.cols[s]) + c] += t[c];
    }
    double acc[3] = {y[3 * i], y[3 * i + 1], y[3 * i + 2]};
    upperRowSum(A, x, i, acc);
    for (int k = 0; k < 3; ++k) y[3 * i + k] = acc[k];
    rowDot(x + 3 * static_cast<long>(i), y + 3 * static_cast<long>(i), d);
  }
  if (dot) *dot = d[0] + d[1] + d[2];
}

void upperGatherBaseline(UpperPattern A, const double* x, double* y, int r0, int r1, double*) {
  for (int j = r0; j < r1; ++j) {
    double acc[3] = {0, 0, 0};
    for (int q = A.colStart[j]; q < A.colStart[j + 1]; ++q) {
      const auto [k, s] = A.colBlocks[q];
      double t[3];
      transposedTimes(A.values + 9 * static_cast<long>(s), x + 3 * static_cast<long>(k), t);
      for (int c = 0; c < 3; ++c) acc[c] += t[c];
    }
    upperRowSum(A, x, j, acc);
    for (int k = 0; k < 3; ++k) y[3 * j + k] = acc[k];
  }
}

#if defined(__x86_64__)
// Each block row is loaded as four doubles (the fourth belongs to the next row or block, or to the
// padding after the last) and multiplied lane by lane with the node triple x_j, also loaded as
// four doubles (the last node's with a mask: nothing follows it); the fourth lanes are dropped
// before the rows' sums. Two blocks at a time, in separate accumulators.
__attribute__((target("avx2,fma"), always_inline)) inline __m256d triple(const double* x, int j, int n, __m256i three) {
  return j + 1 < n ? _mm256_loadu_pd(x + 3 * j) : _mm256_maskload_pd(x + 3 * j, three);
}

__attribute__((target("avx2,fma"))) void multiplyRowsAvx2(const int* rowStart, const int* cols, const double* values,
                                                          const double* x, double* y, int r0, int r1, int n) {
  const __m256i three = _mm256_set_epi64x(0, -1, -1, -1);
  for (int i = r0; i < r1; ++i) {
    __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd(), a2 = _mm256_setzero_pd();
    __m256d b0 = _mm256_setzero_pd(), b1 = _mm256_setzero_pd(), b2 = _mm256_setzero_pd();
    int s = rowStart[i];
    const int end = rowStart[i + 1];
    for (; s + 1 < end; s += 2) {
      const double* b = values + 9 * s;
      const __m256d u = triple(x, cols[s], n, three), w = triple(x, cols[s + 1], n, three);
      a0 = _mm256_fmadd_pd(_mm256_loadu_pd(b), u, a0);
      a1 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 3), u, a1);
      a2 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 6), u, a2);
      b0 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 9), w, b0);
      b1 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 12), w, b1);
      b2 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 15), w, b2);
    }
    if (s < end) {
      const double* b = values + 9 * s;
      const __m256d u = triple(x, cols[s], n, three);
      a0 = _mm256_fmadd_pd(_mm256_loadu_pd(b), u, a0);
      a1 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 3), u, a1);
      a2 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 6), u, a2);
    }
    const __m256d keep = _mm256_castsi256_pd(three);
    a0 = _mm256_and_pd(_mm256_add_pd(a0, b0), keep);
    a1 = _mm256_and_pd(_mm256_add_pd(a1, b1), keep);
    a2 = _mm256_and_pd(_mm256_add_pd(a2, b2), keep);
    // Row sums: (a0, a1) pairwise, then the halves; a2 alone.
    const __m256d h01 = _mm256_hadd_pd(a0, a1), h22 = _mm256_hadd_pd(a2, a2);
    const __m128d s01 = _mm_add_pd(_mm256_castpd256_pd128(h01), _mm256_extractf128_pd(h01, 1));
    const __m128d s22 = _mm_add_sd(_mm256_castpd256_pd128(h22), _mm256_extractf128_pd(h22, 1));
    _mm_storeu_pd(y + 3 * i, s01);
    y[3 * i + 2] = _mm_cvtsd_f64(s22);
  }
}

// The upper-storage product with AVX2: block rows loaded as in multiplyRowsAvx2. Their fourth
// lanes are never cleared: in the row sums they are dropped at the end (rowSumFinish), and of the
// transposed product only the first three lanes are used. The transposed products are summed in
// four-double node slots (Quad below), not in y: four doubles stored into y's node triples would
// overlap the next node's entries, whose load would then wait on store forwarding.
__attribute__((target("avx2,fma"), always_inline)) inline void upperLoad(const double* b, __m256d (&r)[3]) {
  for (int k = 0; k < 3; ++k) {
    r[k] = _mm256_loadu_pd(b + 3 * k);
    // Held in a register: folded into both products' instructions, each row would be loaded twice.
    __asm__("" : "+x"(r[k]));
  }
}

// B^T u from B's rows r and u's entries broadcast in u0, u1, u2 (the fourth lane is garbage).
__attribute__((target("avx2,fma"), always_inline)) inline __m256d upperTransposed(const __m256d (&r)[3], __m256d u0, __m256d u1,
                                                                                __m256d u2) {
  return _mm256_fmadd_pd(r[2], u2, _mm256_fmadd_pd(r[1], u1, _mm256_mul_pd(r[0], u0)));
}

// Row i's own sum (the diagonal block first, then the others in order, as multiplyRowsAvx2 but
// in one set of accumulators), in three steps: start, add a block, finish by adding the row's
// sums to (lo, hi) = y_i's first two entries and its third.
struct RowSum {
  __m256d a0, a1, a2;
};

__attribute__((target("avx2,fma"), always_inline)) inline void rowSumStart(RowSum& r, const double* d, __m256d xi) {
  r.a0 = _mm256_mul_pd(_mm256_loadu_pd(d), xi);
  r.a1 = _mm256_mul_pd(_mm256_loadu_pd(d + 3), xi);
  r.a2 = _mm256_mul_pd(_mm256_loadu_pd(d + 6), xi);
}

__attribute__((target("avx2,fma"), always_inline)) inline void rowSumAdd(RowSum& r, const __m256d (&b)[3], __m256d u) {
  r.a0 = _mm256_fmadd_pd(b[0], u, r.a0);
  r.a1 = _mm256_fmadd_pd(b[1], u, r.a1);
  r.a2 = _mm256_fmadd_pd(b[2], u, r.a2);
}

__attribute__((target("avx2,fma"), always_inline)) inline void rowSumFinish(const RowSum& r, __m256d keep, __m128d& lo, double& hi) {
  const __m256d a0 = _mm256_and_pd(r.a0, keep), a1 = _mm256_and_pd(r.a1, keep), a2 = _mm256_and_pd(r.a2, keep);
  const __m256d h01 = _mm256_hadd_pd(a0, a1), h22 = _mm256_hadd_pd(a2, a2);
  lo = _mm_add_pd(lo, _mm_add_pd(_mm256_castpd256_pd128(h01), _mm256_extractf128_pd(h01, 1)));
  hi += _mm_cvtsd_f64(_mm_add_sd(_mm256_castpd256_pd128(h22), _mm256_extractf128_pd(h22, 1)));
}

// x_i . y_i added to (lo, hi), the sums of the triples' first two entries and of their third,
// with fused multiply-adds.
__attribute__((target("avx2,fma"), always_inline)) inline void rowDotAvx2(const double* xi, __m128d yLo, double yHi, __m128d& lo,
                                                                          __m128d& hi) {
  lo = _mm_fmadd_pd(_mm_loadu_pd(xi), yLo, lo);
  hi = _mm_fmadd_sd(_mm_load_sd(xi + 2), _mm_set_sd(yHi), hi);
}

__attribute__((target("avx2,fma"))) double dotAvx2(const double* x, const double* y, int n) {
  __m128d lo = _mm_setzero_pd(), hi = _mm_setzero_pd();
  for (long i = 0; i < n; ++i) rowDotAvx2(x + 3 * i, _mm_loadu_pd(y + 3 * i), y[3 * i + 2], lo, hi);
  return _mm_cvtsd_f64(lo) + _mm_cvtsd_f64(_mm_unpackhi_pd(lo, lo)) + _mm_cvtsd_f64(hi);
}

// The scatter sweep's sums of transposed products, four doubles per node (the fourth is not used):
// one aligned load-add-store per block, where three-double triples take two and an extraction.
struct alignas(32) Quad {
  double v[4];
};

// Block (i, j) above the diagonal in the scatter sweep: B x_j (xj) into row i's sum, B^T x_i (x_i
// broadcast in x0, x1, x2) added to t_j.
__attribute__((target("avx2,fma"), always_inline)) inline void upperScatterBlock(RowSum& sum, const double* b, __m256d xj, __m256d x0,
                                                                                 __m256d x1, __m256d x2, Quad& tj) {
  __m256d r[3];
  upperLoad(b, r);
  rowSumAdd(sum, r, xj);
  _mm256_store_pd(tj.v, _mm256_add_pd(_mm256_load_pd(tj.v), upperTransposed(r, x0, x1, x2)));
}

// Row i of the scatter sweep: each block (i, j) adds to row i's sum and, transposed, to t_j; y_i is
// t_i plus the row's sum. Columns ascend in a row, so only a row's last block can be in the last
// column, whose x_j is loaded with a mask (nothing follows it). Last: the row may have such a
// block, or be the last row; rows before the first that can are swept without the tests.
template <bool Last>
__attribute__((target("avx2,fma"), always_inline)) inline void upperScatterRow(const UpperPattern& A, const double* x, double* y, Quad* t,
                                                                               int i, __m256i three, __m128d& dotLo, __m128d& dotHi) {
  // Broadcast once: y's stores could alias x as far as the compiler knows.
  const double* xi = x + 3 * static_cast<long>(i);
  const __m256d x0 = _mm256_set1_pd(xi[0]), x1 = _mm256_set1_pd(xi[1]), x2 = _mm256_set1_pd(xi[2]);
  const int begin = A.rowStart[i], end = A.rowEnd[i];
  const int open = Last && end - 1 > begin && A.cols[end - 1] == A.n - 1 ? end - 1 : end;
  RowSum sum;
  rowSumStart(sum, A.values + 9 * static_cast<long>(begin), Last ? triple(x, i, A.n, three) : _mm256_loadu_pd(xi));
  for (int s = begin + 1; s < open; ++s) {
    const long j = A.cols[s];
    upperScatterBlock(sum, A.values + 9 * static_cast<long>(s), _mm256_loadu_pd(x + 3 * j), x0, x1, x2, t[j]);
  }
  if (Last && open < end)
    upperScatterBlock(sum, A.values + 9 * static_cast<long>(open), _mm256_maskload_pd(x + 3 * static_cast<long>(A.n - 1), three), x0, x1,
                      x2, t[A.n - 1]);
  __m128d lo = _mm_load_pd(t[i].v);
  double hi = t[i].v[2];
  rowSumFinish(sum, _mm256_castsi256_pd(three), lo, hi);
  _mm_storeu_pd(y + 3 * static_cast<long>(i), lo);
  y[3 * static_cast<long>(i) + 2] = hi;
  rowDotAvx2(xi, lo, hi, dotLo, dotHi);
}

__attribute__((target("avx2,fma"))) void upperScatterAvx2(UpperPattern A, const double* x, double* y, int, int, double* dot) {
  const __m256i three = _mm256_set_epi64x(0, -1, -1, -1);
  __m128d dotLo = _mm_setzero_pd(), dotHi = _mm_setzero_pd();
  thread_local std::vector<Quad> sums;
  sums.assign(static_cast<size_t>(A.n), Quad{});
  Quad* t = sums.data();
  // The first row with a block in the last column (colBlocks: rows ascending), else the last row.
  const int lastFrom = A.n == 0 ? 0 : A.colStart[A.n - 1] < A.colStart[A.n] ? A.colBlocks[A.colStart[A.n - 1]].first : A.n - 1;
  int i = 0;
  for (; i < lastFrom; ++i) upperScatterRow<false>(A, x, y, t, i, three, dotLo, dotHi);
  for (; i < A.n; ++i) upperScatterRow<true>(A, x, y, t, i, three, dotLo, dotHi);
  if (dot) *dot = _mm_cvtsd_f64(dotLo) + _mm_cvtsd_f64(_mm_unpackhi_pd(dotLo, dotLo)) + _mm_cvtsd_f64(dotHi);
}

__attribute__((target("avx2,fma"))) void upperGatherAvx2(UpperPattern A, const double* x, double* y, int r0, int r1, double*) {
  const __m256i three = _mm256_set_epi64x(0, -1, -1, -1);
  const __m256d keep = _mm256_castsi256_pd(three);
  for (int j = r0; j < r1; ++j) {
    __m128d lo = _mm_setzero_pd();
    double hi = 0;
    for (int q = A.colStart[j]; q < A.colStart[j + 1]; ++q) {
      const auto [k, s] = A.colBlocks[q];
      __m256d r[3];
      upperLoad(A.values + 9 * static_cast<long>(s), r);
      const double* xk = x + 3 * static_cast<long>(k);
      const __m256d t = upperTransposed(r, _mm256_set1_pd(xk[0]), _mm256_set1_pd(xk[1]), _mm256_set1_pd(xk[2]));
      lo = _mm_add_pd(lo, _mm256_castpd256_pd128(t));
      hi += _mm_cvtsd_f64(_mm256_extractf128_pd(t, 1));
    }
    RowSum sum;
    rowSumStart(sum, A.values + 9 * static_cast<long>(A.rowStart[j]), triple(x, j, A.n, three));
    for (int s = A.rowStart[j] + 1; s < A.rowEnd[j]; ++s) {
      __m256d r[3];
      upperLoad(A.values + 9 * static_cast<long>(s), r);
      rowSumAdd(sum, r, triple(x, A.cols[s], A.n, three));
    }
    rowSumFinish(sum, keep, lo, hi);
    _mm_storeu_pd(y + 3 * static_cast<long>(j), lo);
    y[3 * static_cast<long>(j) + 2] = hi;
  }
}

#endif

RowsKernel rowsKernel() {
#if defined(__x86_64__)
  static const RowsKernel k = useAvx2() ? multiplyRowsAvx2 : multiplyRowsBaseline;
  return k;
#else
  return multiplyRowsBaseline;
#endif
}

struct UpperKernels {
  UpperKernel scatter, gather;
  DotKernel dot;
};

UpperKernels upperKernels() {
#if defined(__x86_64__)
  if (useAvx2()) return {upperScatterAvx2, upperGatherAvx2, dotAvx2};
#endif
  return {upperScatterBaseline, upperGatherBaseline, dotBaseline};
}

}  // namespace

void BlockSparseMatrix::multiply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y, double* xDotY) const {
  static const UpperKernels k = upperKernels();
  if (upper()) {
    const UpperPattern A{rowStart_.data(), held_ ? rowEnd_.data() : rowStart_.data() + 1, cols_.data(), values_.data(), colStart_.data(),
                         colBlocks_.data(), n_};
    const size_t threads = std::min(static_cast<size_t>(tbb::this_task_arena::max_concurrency()),
                                    tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    // On two threads the gather (each block read for its row and again for its column) is no
    // faster than one thread's scatter, which reads it once: it pays from three threads on.
    if (n_ < 512 || threads < 3) {
      k.scatter(A, x.data(), y.data(), 0, n_, xDotY);
      return;
    }
    tbb::parallel_for(tbb::blocked_range<int>(0, n_, 256),
                      [&](const tbb::blocked_range<int>& r) { k.gather(A, x.data(), y.data(), r.begin(), r.end(), nullptr); });
  } else {
    const RowsKernel kernel = rowsKernel();
    auto rowsRange = [&](int r0, int r1) { kernel(rowStart_.data(), cols_.data(), values_.data(), x.data(), y.data(), r0, r1, n_); };
    if (n_ < 512) rowsRange(0, n_);
    else
      tbb::parallel_for(tbb::blocked_range<int>(0, n_, 256),
                        [&](const tbb::blocked_range<int>& r) { rowsRange(r.begin(), r.end()); });
  }
  if (xDotY) *xDotY = k.dot(x.data(), y.data(), n_);
}

void BlockSparseMatrix::constrainNodes(const std::vector<int>& nodes) {
  if (rowEnd_.size() != static_cast<size_t>(n_) || nodes != heldNodes_) {
    // The blocks to clear and the rows' ends, found once for a set of nodes (every step has the same).
    std::vector<char> fixed(n_, 0);
    for (int i : nodes) fixed[i] = 1;
    heldSlots_.clear();
    for (int i = 0; i < n_; ++i)
      for (int s = rowStart_[i]; s < rowStart_[i + 1]; ++s)
        if (fixed[i] || fixed[cols_[s]]) heldSlots_.push_back(s);
    // A held row is its diagonal now: the product skips its other blocks, all zero, until the
    // values are written again. (Its column's blocks in other rows are zero too, but multiplied.)
    rowEnd_.assign(rowStart_.begin() + 1, rowStart_.end());
    for (int i : nodes) rowEnd_[i] = diag_[i] + 1;
    heldNodes_ = nodes;
  }
  for (int s : heldSlots_) std::fill_n(values_.begin() + 9 * static_cast<long>(s), 9, 0.0);
  for (int i : nodes) Eigen::Map<Block>(values_.data() + 9 * static_cast<long>(diag_[i])).setIdentity();
  held_ = upper();
}

void BlockSparseMatrix::projectNodes(const std::vector<std::pair<int, Eigen::Matrix3d>>& projectors) {
  if (projectors.empty()) return;
  std::vector<const Eigen::Matrix3d*> P(n_, nullptr);
  for (const auto& [i, p] : projectors) P[i] = &p;
  for (int i = 0; i < n_; ++i)
    for (int s = rowStart_[i]; s < rowStart_[i + 1]; ++s) {
      const int j = cols_[s];
      if (!P[i] && !P[j]) continue;
      Eigen::Matrix3d b = block(s);
      if (P[i]) b = *P[i] * b;
      if (P[j]) b = b * *P[j];
      block(s) = b;
    }
  for (const auto& [i, p] : projectors) block(diag_[i]) += Eigen::Matrix3d::Identity() - p;
}

Eigen::MatrixXd BlockSparseMatrix::toDense() const {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(3 * n_, 3 * n_);
  for (int i = 0; i < n_; ++i)
    for (int s = rowStart_[i]; s < rowStart_[i + 1]; ++s) {
      d.block<3, 3>(3 * i, 3 * cols_[s]) = block(s);
      if (upper() && cols_[s] != i) d.block<3, 3>(3 * cols_[s], 3 * i) = block(s).transpose();
    }
  return d;
}

}  // namespace viscera
