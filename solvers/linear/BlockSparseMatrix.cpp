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
  // One double of padding: the vector kernels load each block column as four doubles.
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

using RowsKernel = void (*)(const int* rowStart, const int* cols, const double* values, const double* x, double* y,
                            int r0, int r1);

void multiplyRowsBaseline(const int* rowStart, const int* cols, const double* values, const double* x, double* y,
                          int r0, int r1) {
  for (int i = r0; i < r1; ++i) {
    Eigen::Vector3d acc = Eigen::Vector3d::Zero();
    for (int s = rowStart[i]; s < rowStart[i + 1]; ++s)
      acc.noalias() += Eigen::Map<const Eigen::Matrix3d>(values + 9 * s) * Eigen::Map<const Eigen::Vector3d>(x + 3 * cols[s]);
    Eigen::Map<Eigen::Vector3d>(y + 3 * i) = acc;
  }
}

#if defined(__x86_64__)
// One block = three columns; each is loaded as four doubles (the fourth belongs to the next
// block, or to the padding after the last: its lane is never stored).
__attribute__((target("avx2,fma"))) void multiplyRowsAvx2(const int* rowStart, const int* cols, const double* values,
                                                          const double* x, double* y, int r0, int r1) {
  for (int i = r0; i < r1; ++i) {
    __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd();
    int s = rowStart[i];
    const int end = rowStart[i + 1];
    for (; s + 1 < end; s += 2) {
      const double* b = values + 9 * s;
      const double* u = x + 3 * cols[s];
      const double* w = x + 3 * cols[s + 1];
      a0 = _mm256_fmadd_pd(_mm256_loadu_pd(b), _mm256_broadcast_sd(u), a0);
      a1 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 9), _mm256_broadcast_sd(w), a1);
      a0 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 3), _mm256_broadcast_sd(u + 1), a0);
      a1 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 12), _mm256_broadcast_sd(w + 1), a1);
      a0 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 6), _mm256_broadcast_sd(u + 2), a0);
      a1 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 15), _mm256_broadcast_sd(w + 2), a1);
    }
    if (s < end) {
      const double* b = values + 9 * s;
      const double* u = x + 3 * cols[s];
      a0 = _mm256_fmadd_pd(_mm256_loadu_pd(b), _mm256_broadcast_sd(u), a0);
      a0 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 3), _mm256_broadcast_sd(u + 1), a0);
      a0 = _mm256_fmadd_pd(_mm256_loadu_pd(b + 6), _mm256_broadcast_sd(u + 2), a0);
    }
    alignas(32) double out[4];
    _mm256_store_pd(out, _mm256_add_pd(a0, a1));
    y[3 * i] = out[0];
    y[3 * i + 1] = out[1];
    y[3 * i + 2] = out[2];
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
  auto rowsRange = [&](int r0, int r1) { kernel(rowStart_.data(), cols_.data(), values_.data(), x.data(), y.data(), r0, r1); };
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
