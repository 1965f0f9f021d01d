// A square matrix of 3x3 blocks in compressed block rows. The pattern is built once (from node
// pairs); values are refreshed every step in place. Each block is stored row by row: the product
// takes dot products of block rows with the vector's node triples, which needs fewer loads than
// broadcasting the vector (13 % faster on the phantom's pattern).
//
// Storage::Full keeps both triangles. Storage::Upper keeps the blocks on and above the diagonal of
// a symmetric matrix, half the memory, which the product streams a quarter faster (each block
// serves its row and, transposed, its column). Below the diagonal slot() returns -1: a writer
// skips those blocks, its contribution being symmetric and written at (j, i) as well.
#pragma once

#include <Eigen/Core>
#include <utility>
#include <vector>

namespace viscera {

class BlockSparseMatrix {
 public:
  enum class Storage { Full, Upper };
  // Builds the pattern for `nBlocks` block rows from (i, j) node pairs; both (i, j) and (j, i)
  // (Upper: the one on or above the diagonal) and every diagonal block are included.
  void setPattern(int nBlocks, const std::vector<std::pair<int, int>>& pairs, Storage storage = Storage::Full);

  bool upper() const { return storage_ == Storage::Upper; }
  int blockRows() const { return n_; }
  int rows() const { return 3 * n_; }
  int nonZeroBlocks() const { return static_cast<int>(cols_.size()); }
  // Index of block (i, j) in the value array, or -1 if it is not stored.
  int slot(int i, int j) const;
  int diagonalSlot(int i) const { return diag_[i]; }

  // K_ij += B for a symmetric contribution, which also adds B^T at (j, i): in upper storage the
  // block below the diagonal is skipped. A pair outside the pattern is a logic_error.
  void addSymmetric(int i, int j, const Eigen::Matrix3d& B);

  void setZero();
  using Block = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
  // Block at `slot` (row-major 3x3).
  Eigen::Map<Block> block(int s) {
    held_ = false;
    return Eigen::Map<Block>(values_.data() + 9 * s);
  }
  Eigen::Map<const Block> block(int s) const { return Eigen::Map<const Block>(values_.data() + 9 * s); }
  double* values() {
    held_ = false;
    return values_.data();
  }
  const double* values() const { return values_.data(); }
  const std::vector<int>& rowStart() const { return rowStart_; }  // #blockRows + 1
  const std::vector<int>& cols() const { return cols_; }          // #nonZeroBlocks

  // y = A x (x, y of size 3 * blockRows), in parallel over block rows. Upper storage gives the
  // same result, to the bit, on one thread (each block's row and column in one pass) and on several
  // (each row gathers its column's blocks): the same operations in the same order. With xDotY,
  // also x . y (on one thread, upper storage: in the same sweep), the same to the bit either way.
  void multiply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y, double* xDotY = nullptr) const;
  // A = a * A (values only).
  void scale(double a);
  // Replaces block rows and columns of `nodes` by identity rows/columns (projective constraints).
  // In upper storage the product then skips the held rows' other blocks, until values are written
  // again (setZero, block(), values()).
  void constrainNodes(const std::vector<int>& nodes);
  // For nodes whose motion is projected by P (partly held): block (i, j) becomes P_i A_ij P_j and
  // each such diagonal block gains I - P_i, so that the held directions solve to zero.
  void projectNodes(const std::vector<std::pair<int, Eigen::Matrix3d>>& projectors);
  // Dense copy (both triangles), for tests and small problems.
  Eigen::MatrixXd toDense() const;

 private:
  Storage storage_ = Storage::Full;
  int n_ = 0;
  std::vector<int> rowStart_, cols_, diag_;
  // Upper storage: for each block row j, the blocks (k, j) above it (k < j, ascending) as
  // (k, slot) pairs, from colStart_[j]; the threaded product gathers them.
  std::vector<int> colStart_;
  std::vector<std::pair<int, int>> colBlocks_;
  std::vector<double> values_;
  // constrainNodes' last nodes, the slots of their rows' and columns' blocks, and where each row's
  // blocks end for the product once they are cleared (held_: in upper storage, until the next write).
  std::vector<int> heldNodes_, heldSlots_, rowEnd_;
  bool held_ = false;
};

}  // namespace viscera
