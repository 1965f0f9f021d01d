#include "solvers/linear/BlockSparseMatrix.h"
#include "core/Simd.h"

#include <algorithm>
#if defined(__x86_64__)
#include <immintrin.h>
#endif
#include <tbb/parallel_for.h>

namespace viscera {

void BlockSparseMatrix::setPattern(int nBlocks, const std::vector<std::pair<int, int>>& pairs) {
  n_ = nBlocks;
  std::vector<std::vector<int>> rows(n_);
  for (int i = 0; i < n_; ++i) rows[i].push_back(i);
  for (const auto& [i, j] : pairs) {
    rows[i].push_back(j);
    rows[j].push_back(i);
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
  // One double of padding: the vector kernels load each block row as four doubles.
  values_.assign(9 * cols_.size() + 1, 0.0);
}

int BlockSparseMatrix::slot(int i, int j) const {
  auto b = cols_.begin() + rowStart_[i], e = cols_.begin() + rowStart_[i + 1];
  auto it = std::lower_bound(b, e, j);
  return it != e && *it == j ? static_cast<int>(it - cols_.begin()) : -1;
}

void BlockSparseMatrix::setZero() { std::fill(values_.begin(), values_.end(), 0.0); }

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
#endif

RowsKernel rowsKernel() {
#if defined(__x86_64__)
  static const RowsKernel k = useAvx2() ? multiplyRowsAvx2 : multiplyRowsBaseline;
  return k;
#else
  return multiplyRowsBaseline;
#endif
}

}  // namespace

void BlockSparseMatrix::multiply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const {
  const RowsKernel kernel = rowsKernel();
  auto rowsRange = [&](int r0, int r1) { kernel(rowStart_.data(), cols_.data(), values_.data(), x.data(), y.data(), r0, r1, n_); };
  if (n_ < 512) {
    rowsRange(0, n_);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<int>(0, n_, 256),
                    [&](const tbb::blocked_range<int>& r) { rowsRange(r.begin(), r.end()); });
}

void BlockSparseMatrix::constrainNodes(const std::vector<int>& nodes) {
  std::vector<char> fixed(n_, 0);
  for (int i : nodes) fixed[i] = 1;
  for (int i = 0; i < n_; ++i)
    for (int s = rowStart_[i]; s < rowStart_[i + 1]; ++s)
      if (fixed[i] || fixed[cols_[s]]) block(s).setZero();
  for (int i : nodes) block(diag_[i]).setIdentity();
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
    for (int s = rowStart_[i]; s < rowStart_[i + 1]; ++s) d.block<3, 3>(3 * i, 3 * cols_[s]) = block(s);
  return d;
}

}  // namespace viscera
