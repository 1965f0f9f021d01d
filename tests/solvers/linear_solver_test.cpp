// Linear algebra of the implicit step: BlockSparseMatrix (pattern, product, constraints),
// conjugateGradient (accuracy and each stopping rule, Jacobi preconditioning, warm start), SOFA's
// preconditioned CG with its preconditioners, MINRES, and
// CholmodSolver (accuracy, reuse of the symbolic analysis, failure on indefinite matrices),
// against dense Eigen references built independently here.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#include <utility>
#include <vector>

#include "solvers/linear/BlockSparseMatrix.h"
#include "solvers/linear/LinearSolver.h"

using namespace viscera;
using Eigen::MatrixXd;
using Eigen::VectorXd;

namespace {

// A random symmetric block matrix: ~`perRow` random off-diagonal block pairs per block row and
// diagonal blocks C C^T + (row sum of |off-diagonal entries| + shift) I, hence SPD for shift > 0
// (diagonally dominant). `dense` receives the same matrix, built independently of the class.
struct RandomSystem {
  BlockSparseMatrix A;
  MatrixXd dense;
  std::vector<std::pair<int, int>> pairs;  // unique, i < j
};

RandomSystem randomSymmetric(int n, int perRow, double shift, unsigned seed,
                             BlockSparseMatrix::Storage storage = BlockSparseMatrix::Storage::Full) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::uniform_real_distribution<double> u(-1, 1);
  std::set<std::pair<int, int>> set;
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < perRow; ++k) {
      int j = pick(rng);
      if (j != i) set.insert({std::min(i, j), std::max(i, j)});
    }
  RandomSystem s;
  s.pairs.assign(set.begin(), set.end());
  // Give setPattern duplicates and both orders: it must cope.
  std::vector<std::pair<int, int>> given = s.pairs;
  for (size_t k = 0; k < s.pairs.size(); k += 3) given.push_back({s.pairs[k].second, s.pairs[k].first});
  s.A.setPattern(n, given, storage);
  s.dense = MatrixXd::Zero(3 * n, 3 * n);
  for (auto [i, j] : s.pairs) {
    Eigen::Matrix3d B;
    for (int k = 0; k < 9; ++k) B.data()[k] = u(rng);
    s.dense.block<3, 3>(3 * i, 3 * j) = B;
    s.dense.block<3, 3>(3 * j, 3 * i) = B.transpose();
  }
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix3d C;
    for (int k = 0; k < 9; ++k) C.data()[k] = u(rng);
    const double rowSum = s.dense.middleRows(3 * i, 3).cwiseAbs().rowwise().sum().maxCoeff();
    s.dense.block<3, 3>(3 * i, 3 * i) = C * C.transpose() + (rowSum + shift) * Eigen::Matrix3d::Identity();
  }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int sl = s.A.slot(i, j);
      if (sl >= 0) s.A.block(sl) = s.dense.block<3, 3>(3 * i, 3 * j);
    }
  return s;
}

LinearProblem problemOf(const BlockSparseMatrix& A, bool withDiagonal = true) {
  LinearProblem p;
  p.matrix = &A;
  p.apply = [&A](const VectorXd& x, VectorXd& y) {
    y.resize(x.size());
    A.multiply(x, y);
  };
  if (withDiagonal) {
    p.diagonal.resize(A.rows());
    for (int i = 0; i < A.blockRows(); ++i) p.diagonal.segment<3>(3 * i) = A.block(A.diagonalSlot(i)).diagonal();
  }
  return p;
}

VectorXd randomVector(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  VectorXd v(n);
  for (int i = 0; i < n; ++i) v[i] = g(rng);
  return v;
}

// A random SPD system (150 block rows) scaled symmetrically by S = diag(10^u), u uniform in
// [-decades, decades]: condition numbers up to 10^(4 decades) times the original's.
RandomSystem badlyScaled(unsigned seed, double decades) {
  RandomSystem s = randomSymmetric(150, 4, 0.5, seed);
  std::mt19937 rng(seed + 1);
  std::uniform_real_distribution<double> u(-decades, decades);
  VectorXd S(s.A.rows());
  for (int i = 0; i < S.size(); ++i) S[i] = std::pow(10.0, u(rng));
  s.dense = S.asDiagonal() * s.dense * S.asDiagonal();
  for (int i = 0; i < s.A.blockRows(); ++i)
    for (int sl = s.A.rowStart()[i]; sl < s.A.rowStart()[i + 1]; ++sl)
      s.A.block(sl) = s.dense.block<3, 3>(3 * i, 3 * s.A.cols()[sl]);
  return s;
}

double relResidual(const MatrixXd& A, const VectorXd& x, const VectorXd& b) { return (b - A * x).norm() / b.norm(); }

// Textbook unpreconditioned CG from zero, recording p_k^T A p_k of every iteration.
VectorXd referenceCG(const MatrixXd& A, const VectorXd& b, int iterations, std::vector<double>* curvatures = nullptr) {
  VectorXd x = VectorXd::Zero(b.size()), r = b, p = r;
  double rho = r.squaredNorm();
  for (int k = 0; k < iterations; ++k) {
    const VectorXd q = A * p;
    const double den = p.dot(q);
    if (curvatures) curvatures->push_back(den);
    const double alpha = rho / den;
    x += alpha * p;
    r -= alpha * q;
    const double rhoNew = r.squaredNorm();
    p = r + (rhoNew / rho) * p;
    rho = rhoNew;
  }
  return x;
}

}  // namespace

// The pattern holds both (i, j) and (j, i) and every diagonal block, nothing else; toDense and
// multiply (serial below 512 block rows, parallel above) equal the dense matrix and its product
// (1e-13 relative); scale scales every value.
TEST(BlockSparseMatrix, PatternProductAndScale) {
  for (int n : {40, 700}) {
    RandomSystem s = randomSymmetric(n, 4, 1.0, 1 + n);
    std::set<std::pair<int, int>> expected;
    for (auto [i, j] : s.pairs) expected.insert({i, j}), expected.insert({j, i});
    for (int i = 0; i < n; ++i) expected.insert({i, i});
    EXPECT_EQ(s.A.nonZeroBlocks(), static_cast<int>(expected.size()));
    EXPECT_EQ(s.A.blockRows(), n);
    EXPECT_EQ(s.A.rows(), 3 * n);
    int found = 0;
    for (int i = 0; i < n; ++i) {
      EXPECT_EQ(s.A.slot(i, i), s.A.diagonalSlot(i));
      for (int j = 0; j < n; ++j) {
        const bool in = expected.count({i, j}) > 0;
        EXPECT_EQ(s.A.slot(i, j) >= 0, in) << i << "," << j;
        found += in;
      }
    }
    EXPECT_EQ(found, s.A.nonZeroBlocks());
    EXPECT_EQ((s.A.toDense() - s.dense).norm(), 0.0);
    const VectorXd x = randomVector(3 * n, 5);
    VectorXd y(3 * n);
    s.A.multiply(x, y);
    EXPECT_LT((y - s.dense * x).norm(), 1e-13 * (s.dense * x).norm()) << "n = " << n;
    s.A.scale(-2.5);
    EXPECT_LT((s.A.toDense() + 2.5 * s.dense).norm(), 1e-14 * s.dense.norm());
    s.A.setZero();
    EXPECT_EQ(s.A.toDense().norm(), 0.0);
  }
}

// The product reads four doubles per node triple and per block row: what lies beyond them (the
// next node's first entry, the next row) must not reach the result. A chain of three nodes whose
// last is not a number: the rows of the first node, which does not touch it, stay exact. Both
// storages (the pairs given in either order).
TEST(BlockSparseMatrix, ANonFiniteNodeReachesOnlyTheRowsThatTouchIt) {
  for (auto storage : {BlockSparseMatrix::Storage::Full, BlockSparseMatrix::Storage::Upper}) {
    BlockSparseMatrix A;
    A.setPattern(3, {{0, 1}, {2, 1}}, storage);
    for (int s = 0; s < A.nonZeroBlocks(); ++s)
      for (int k = 0; k < 9; ++k) A.block(s)(k / 3, k % 3) = 1 + s + 0.1 * k;
    VectorXd x(9);
    x << 1, 2, 3, 4, 5, 6, std::nan(""), 8, 9;
    VectorXd y(9);
    A.multiply(x, y);
    const Eigen::MatrixXd D = A.toDense();
    EXPECT_TRUE(y.head<3>().allFinite());
    EXPECT_LT((y.head<3>() - D.topLeftCorner(3, 6) * x.head<6>()).norm(), 1e-13 * y.head<3>().norm());
    EXPECT_FALSE(y.segment<3>(3).allFinite());  // node 1 couples to the NaN node
  }
}

// constrainNodes: the rows and columns of the constrained nodes become identity rows/columns,
// every other entry is untouched (exact).
TEST(BlockSparseMatrix, ConstrainNodesGivesIdentityRowsAndColumns) {
  RandomSystem s = randomSymmetric(30, 4, 1.0, 77);
  const std::vector<int> fixed{0, 7, 8, 29};
  s.A.constrainNodes(fixed);
  MatrixXd expected = s.dense;
  for (int i : fixed) {
    expected.middleRows(3 * i, 3).setZero();
    expected.middleCols(3 * i, 3).setZero();
    expected.block<3, 3>(3 * i, 3 * i).setIdentity();
  }
  EXPECT_EQ((s.A.toDense() - expected).norm(), 0.0);
}

// Upper storage: the blocks on and above the diagonal only (slot -1 below), the same matrix as
// the full storage (toDense, exactly), and the product of the symmetric matrix to round-off. The
// one-thread product (rows and transposed columns in one sweep) and the threaded one (each row
// gathering its column; from three threads on) give the same result to the bit.
TEST(BlockSparseMatrixUpper, PatternAndProductOfTheSymmetricMatrix) {
  using Storage = BlockSparseMatrix::Storage;
  for (int n : {40, 700}) {
    RandomSystem s = randomSymmetric(n, 4, 1.0, 1 + n, Storage::Upper);
    ASSERT_TRUE(s.A.upper());
    EXPECT_EQ(s.A.nonZeroBlocks(), static_cast<int>(s.pairs.size()) + n);
    for (int i = 0; i < n; ++i) {
      EXPECT_EQ(s.A.diagonalSlot(i), s.A.rowStart()[i]);  // the diagonal leads its row
      for (int j = 0; j < i; ++j) EXPECT_EQ(s.A.slot(i, j), -1);
    }
    for (auto [i, j] : s.pairs) EXPECT_GE(s.A.slot(i, j), 0);
    EXPECT_EQ((s.A.toDense() - s.dense).norm(), 0.0);
    const VectorXd x = randomVector(3 * n, 5);
    VectorXd one(3 * n), two(3 * n);
    {
      tbb::task_arena arena(1);
      arena.execute([&] { s.A.multiply(x, one); });
    }
    {
      tbb::global_control allow(tbb::global_control::max_allowed_parallelism, 4);  // also on a machine with fewer cores
      tbb::task_arena arena(4);
      arena.execute([&] { s.A.multiply(x, two); });
    }
    EXPECT_LT((one - s.dense * x).norm(), 1e-13 * (s.dense * x).norm()) << "n = " << n;
    EXPECT_EQ((one - two).cwiseAbs().maxCoeff(), 0.0) << "n = " << n;
    // y is written, not added to.
    VectorXd again = VectorXd::Constant(3 * n, 7.0);
    s.A.multiply(x, again);
    EXPECT_EQ((again - one).cwiseAbs().maxCoeff(), 0.0);
  }
}

// constrainNodes and projectNodes on the upper storage give the matrix they give on the full one.
TEST(BlockSparseMatrixUpper, ConstraintsAsOnTheFullStorage) {
  using Storage = BlockSparseMatrix::Storage;
  RandomSystem full = randomSymmetric(30, 4, 1.0, 77), up = randomSymmetric(30, 4, 1.0, 77, Storage::Upper);
  ASSERT_EQ((full.A.toDense() - up.A.toDense()).norm(), 0.0);
  const std::vector<int> fixed{0, 7, 8, 29};
  full.A.constrainNodes(fixed);
  up.A.constrainNodes(fixed);
  EXPECT_EQ((full.A.toDense() - up.A.toDense()).norm(), 0.0);
  const Eigen::Vector3d n = Eigen::Vector3d(1, 2, 2).normalized();
  const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - n * n.transpose();
  full.A.projectNodes({{3, P}, {12, P}});
  up.A.projectNodes({{3, P}, {12, P}});
  EXPECT_LT((full.A.toDense() - up.A.toDense()).norm(), 1e-14 * full.A.toDense().norm());
}

// After constrainNodes the upper-storage product skips the held rows' other blocks (all zero):
// the product of the constrained matrix, on one thread and on four (the gathering product), to
// the bit alike, and x . y from the product's sweep equal to the separate one to round-off and the
// same on any thread count. A block written after the constraint is multiplied again (the skip
// ends with the write).
TEST(BlockSparseMatrixUpper, ProductOfTheConstrainedMatrixAndItsDot) {
  using Storage = BlockSparseMatrix::Storage;
  for (int n : {40, 700}) {
    RandomSystem s = randomSymmetric(n, 4, 1.0, 9 + n, Storage::Upper);
    std::vector<int> fixed;
    for (int i = 0; i < n; i += 5) fixed.push_back(i);
    s.A.constrainNodes(fixed);
    const MatrixXd D = s.A.toDense();
    const VectorXd x = randomVector(3 * n, 6);
    VectorXd one(3 * n), two(3 * n);
    double dotOne = 0, dotTwo = 0;
    {
      tbb::task_arena arena(1);
      arena.execute([&] { s.A.multiply(x, one, &dotOne); });
    }
    {
      tbb::global_control allow(tbb::global_control::max_allowed_parallelism, 4);
      tbb::task_arena arena(4);
      arena.execute([&] { s.A.multiply(x, two, &dotTwo); });
    }
    EXPECT_LT((one - D * x).norm(), 1e-13 * (D * x).norm()) << "n = " << n;
    EXPECT_EQ((one - two).cwiseAbs().maxCoeff(), 0.0) << "n = " << n;
    EXPECT_EQ(dotOne, dotTwo) << "n = " << n;
    EXPECT_LT(std::abs(dotOne - x.dot(one)), 1e-13 * x.norm() * one.norm()) << "n = " << n;
    // A coupling written into a held row after the constraint reaches the product.
    const int j = s.A.cols()[s.A.rowStart()[0] + 1];
    s.A.block(s.A.rowStart()[0] + 1)(0, 0) = 3.0;
    MatrixXd D2 = D;
    D2(0, 3 * j) = D2(3 * j, 0) = 3.0;
    s.A.multiply(x, one);
    EXPECT_LT((one - D2 * x).norm(), 1e-13 * (D2 * x).norm()) << "n = " << n;
  }
}

// The full storage's product gives x . y as well.
TEST(BlockSparseMatrix, ProductGivesItsDot) {
  RandomSystem s = randomSymmetric(300, 4, 1.0, 21);
  const VectorXd x = randomVector(s.A.rows(), 8);
  VectorXd y(s.A.rows());
  double xy = 0;
  s.A.multiply(x, y, &xy);
  EXPECT_LT(std::abs(xy - x.dot(y)), 1e-13 * x.norm() * y.norm());
}

// CG solves a random SPD system (600 unknowns) to 1e-10 relative residual (tolerance 1e-12, so
// the residual it reports must match the true one) and agrees with a dense LDL^T solution to
// cond(A) * 1e-12 (<= 1e-9 here).
TEST(ConjugateGradient, SolvesRandomSpdSystem) {
  RandomSystem s = randomSymmetric(200, 4, 0.5, 3);
  const VectorXd b = randomVector(s.A.rows(), 4);
  const VectorXd exact = s.dense.ldlt().solve(b);
  Eigen::SelfAdjointEigenSolver<MatrixXd> es(s.dense);
  ASSERT_GT(es.eigenvalues()[0], 0.0);
  const double cond = es.eigenvalues().maxCoeff() / es.eigenvalues().minCoeff();
  CgOptions o;
  o.maxIterations = 1000;
  o.tolerance = 1e-12;
  o.threshold = 0;
  for (bool jacobi : {false, true}) {
    o.preconditioner = jacobi ? CgOptions::Preconditioner::Jacobi : CgOptions::Preconditioner::None;
    VectorXd x;
    const LinearSolveInfo info = conjugateGradient(problemOf(s.A), b, x, o);
    EXPECT_TRUE(info.ok) << info.message;
    EXPECT_LT(relResidual(s.dense, x, b), 1e-10);
    EXPECT_LE(info.relResidual, 1e-12);
    EXPECT_NEAR(info.relResidual, relResidual(s.dense, x, b), 1e-13);
    EXPECT_LT((x - exact).norm(), std::max(cond, 10.0) * 1e-11 * exact.norm()) << "cond " << cond;
    EXPECT_GT(info.iterations, 5);
    EXPECT_LT(info.iterations, 1000);
  }
}

// Stopping rules. maxIterations: exactly that many iterations, and the iterate is the Krylov
// iterate of textbook CG (1e-10). tolerance: it stops at the first iteration whose residual is
// below the tolerance (one iteration fewer is not enough). threshold: it stops, before updating
// x, at the first p^T A p below the threshold.
TEST(ConjugateGradient, StoppingRules) {
  RandomSystem s = randomSymmetric(100, 4, 0.1, 9);
  const VectorXd b = randomVector(s.A.rows(), 10);
  const LinearProblem prob = problemOf(s.A);

  CgOptions o;
  o.tolerance = 0;
  o.threshold = 0;
  o.maxIterations = 5;
  VectorXd x;
  LinearSolveInfo info = conjugateGradient(prob, b, x, o);
  EXPECT_EQ(info.iterations, 5);
  EXPECT_GT(info.relResidual, 1e-3);
  const VectorXd x5 = referenceCG(s.dense, b, 5);
  EXPECT_LT((x - x5).norm(), 1e-10 * x5.norm());

  o.maxIterations = 1000;
  o.tolerance = 1e-4;
  info = conjugateGradient(prob, b, x, o);
  const int k = info.iterations;
  EXPECT_LE(relResidual(s.dense, x, b), 1e-4 * (1 + 1e-9));
  EXPECT_GT(k, 5);
  o.maxIterations = k - 1;
  info = conjugateGradient(prob, b, x, o);
  EXPECT_GT(relResidual(s.dense, x, b), 1e-4) << "stopped later than needed";

  // threshold: above b^T A b, nothing is done; between the curvatures of iterations 2 and 3,
  // exactly two iterations are done.
  std::vector<double> den;
  referenceCG(s.dense, b, 6, &den);
  o.maxIterations = 100;
  o.tolerance = 0;
  o.threshold = 2 * den[0];
  info = conjugateGradient(prob, b, x, o);
  EXPECT_EQ(info.iterations, 0);
  EXPECT_EQ(x.norm(), 0.0);
  ASSERT_LT(den[2], std::min(den[0], den[1]));  // this system's curvatures decrease
  o.threshold = 0.5 * (den[2] + std::min(den[0], den[1]));
  info = conjugateGradient(prob, b, x, o);
  EXPECT_EQ(info.iterations, 2);
  EXPECT_LT((x - referenceCG(s.dense, b, 2)).norm(), 1e-10 * x.norm());

  // Degenerate right-hand sides.
  x = VectorXd::Ones(b.size());
  info = conjugateGradient(prob, VectorXd::Zero(b.size()), x, o);
  EXPECT_TRUE(info.ok);
  EXPECT_EQ(x.norm(), 0.0);
  VectorXd bad = b;
  bad[3] = std::numeric_limits<double>::quiet_NaN();
  info = conjugateGradient(prob, bad, x, o);
  EXPECT_FALSE(info.ok);
  EXPECT_FALSE(info.message.empty());
}

// Warm start: from the exact solution nothing is done; from a nearby point fewer iterations are
// needed than from zero, for the same tolerance.
TEST(ConjugateGradient, WarmStart) {
  RandomSystem s = randomSymmetric(100, 4, 0.1, 21);
  const VectorXd b = randomVector(s.A.rows(), 22);
  const VectorXd exact = s.dense.ldlt().solve(b);
  CgOptions o;
  o.maxIterations = 1000;
  o.tolerance = 1e-8;
  o.threshold = 0;
  VectorXd x;
  const int cold = conjugateGradient(problemOf(s.A), b, x, o).iterations;
  o.warmStart = true;
  x = exact;
  EXPECT_EQ(conjugateGradient(problemOf(s.A), b, x, o).iterations, 0);
  EXPECT_LT((x - exact).norm(), 1e-12 * exact.norm());
  x = exact + 1e-5 * randomVector(s.A.rows(), 23);
  const LinearSolveInfo info = conjugateGradient(problemOf(s.A), b, x, o);
  EXPECT_LT(info.iterations, cold);
  EXPECT_LE(relResidual(s.dense, x, b), 1e-8 * (1 + 1e-9));
}

// Jacobi preconditioning on a badly scaled SPD matrix S A S (S = diag(10^u), u in [-2, 2]):
// unpreconditioned CG needs several times more iterations (or does not converge in 2000) than
// Jacobi CG, which reaches 1e-10 and agrees with LDL^T. Without a diagonal in the problem,
// Jacobi falls back to plain CG (same iteration count).
TEST(ConjugateGradient, JacobiHelpsBadlyScaledSystems) {
  RandomSystem s = badlyScaled(31, 2);
  const VectorXd b = randomVector(s.A.rows(), 33);
  CgOptions o;
  o.maxIterations = 2000;
  o.tolerance = 1e-10;
  o.threshold = 0;
  VectorXd x;
  const LinearSolveInfo plain = conjugateGradient(problemOf(s.A), b, x, o);
  o.preconditioner = CgOptions::Preconditioner::Jacobi;
  const LinearSolveInfo jac = conjugateGradient(problemOf(s.A), b, x, o);
  std::printf("  iterations: plain %d (residual %.1e), Jacobi %d (residual %.1e)\n", plain.iterations, plain.relResidual,
              jac.iterations, jac.relResidual);
  EXPECT_LE(jac.relResidual, 1e-10);
  EXPECT_LT(relResidual(s.dense, x, b), 1e-9);
  const VectorXd exact = s.dense.ldlt().solve(b);
  EXPECT_LT((x - exact).norm(), 1e-6 * exact.norm());
  EXPECT_LT(3 * jac.iterations, plain.iterations);
  const LinearSolveInfo noDiag = conjugateGradient(problemOf(s.A, false), b, x, o);
  EXPECT_EQ(noDiag.iterations, plain.iterations);
}

// CHOLMOD: solves random SPD systems (small: simplicial; large: supernodal) to 1e-10 relative
// residual; refactorizing new values on the same pattern reuses the symbolic analysis
// (analyses() stays 1) and each solve is right; a new pattern is analysed again.
TEST(CholmodSolver, SolvesAndReusesAnalysis) {
  for (int n : {30, 400}) {
    CholmodSolver chol;
    for (int round = 0; round < 3; ++round) {
      // Same pattern (same seed for the pattern), new values: rescale and reshift the diagonal.
      RandomSystem s = randomSymmetric(n, 4, 0.5, 100 + n);
      const double a = 1.0 + round;
      s.A.scale(a);
      s.dense *= a;
      for (int i = 0; i < n; ++i) {
        s.A.block(s.A.diagonalSlot(i)).diagonal().array() += round;
        s.dense.block<3, 3>(3 * i, 3 * i).diagonal().array() += round;
      }
      std::string msg;
      ASSERT_TRUE(chol.factorize(s.A, msg)) << msg;
      EXPECT_EQ(chol.analyses(), 1) << "n = " << n << ", round " << round;
      const VectorXd b = randomVector(3 * n, 200 + round);
      VectorXd x;
      chol.solve(b, x);
      ASSERT_EQ(x.size(), b.size());
      EXPECT_LT(relResidual(s.dense, x, b), 1e-10) << "n = " << n << ", round " << round;
    }
    RandomSystem other = randomSymmetric(n, 5, 0.5, 999);
    std::string msg;
    ASSERT_TRUE(chol.factorize(other.A, msg)) << msg;
    EXPECT_EQ(chol.analyses(), 2);
    const VectorXd b = randomVector(3 * n, 7);
    VectorXd x;
    chol.solve(b, x);
    EXPECT_LT(relResidual(other.dense, x, b), 1e-10);
  }
}

namespace {

// A random SPD system with one diagonal block shifted far below zero: symmetric indefinite.
RandomSystem indefinite(int n) {
  RandomSystem s = randomSymmetric(n, 4, 0.5, 300 + n);
  const int i = n / 2;
  s.A.block(s.A.diagonalSlot(i)).diagonal().array() -= 1e3;
  s.dense.block<3, 3>(3 * i, 3 * i).diagonal().array() -= 1e3;
  return s;
}

}  // namespace

// An indefinite matrix must not be factorized silently: factorize returns false with a message.
// Large matrix (CHOLMOD picks the supernodal LL^T factorization).
TEST(CholmodSolver, IndefiniteMatrixFailsSupernodal) {
  RandomSystem s = indefinite(400);
  CholmodSolver chol;
  std::string msg;
  EXPECT_FALSE(chol.factorize(s.A, msg));
  EXPECT_FALSE(msg.empty());
}

// The same for a small matrix, for which CHOLMOD_AUTO picks the simplicial LDL^T factorization:
// CHOLMOD then factorizes the indefinite matrix without pivoting and reports success, so
// whether SparseLDLSolver accepts an indefinite system depends on the size of the problem.
// (If the contract becomes "LDL^T accepts indefinite matrices", this test should instead require
// success on both paths and an accurate solve.)
TEST(CholmodSolver, IndefiniteMatrixFailsSimplicial) {
  RandomSystem s = indefinite(30);
  Eigen::SelfAdjointEigenSolver<MatrixXd> es(s.dense);
  ASSERT_LT(es.eigenvalues()[2], -100.0);  // three negative eigenvalues, the rest positive
  ASSERT_GT(es.eigenvalues()[3], 0.0);
  CholmodSolver chol;
  std::string msg;
  const bool ok = chol.factorize(s.A, msg);
  if (ok) {
    const VectorXd b = randomVector(s.A.rows(), 5);
    VectorXd x;
    chol.solve(b, x);
    std::printf("  indefinite 90 x 90 accepted; relative residual of the solve %.1e\n", relResidual(s.dense, x, b));
  }
  EXPECT_FALSE(ok) << "indefinite matrix factorized without error (simplicial LDL^T path)";
  EXPECT_FALSE(msg.empty());
}

// PCGLinearSolver's iteration (SOFA's): every preconditioner reaches the dense solution of a badly
// scaled SPD system; the diagonal ones in far fewer iterations than none. Without a
// preconditioner it stops at the first iterate whose squared relative residual is below the
// tolerance (the textbook CG iterate of that count), and it starts from the x it is given.
TEST(PreconditionedConjugateGradient, PreconditionersAndSofasStoppingRule) {
  RandomSystem s = badlyScaled(41, 1);
  const VectorXd b = randomVector(s.A.rows(), 43);
  const VectorXd exact = s.dense.ldlt().solve(b);
  const Preconditioner jacobi = jacobiPreconditioner(s.A), block = blockJacobiPreconditioner(s.A),
                       ssor = ssorPreconditioner(s.A, 1.0);
  int iterations[4];
  const Preconditioner* all[4] = {nullptr, &jacobi, &block, &ssor};
  for (int k = 0; k < 4; ++k) {
    VectorXd x;
    const LinearSolveInfo info = preconditionedConjugateGradient(problemOf(s.A), b, x, 5000, 1e-24, all[k]);
    ASSERT_TRUE(info.ok) << k;
    EXPECT_LT((x - exact).norm(), 1e-6 * exact.norm()) << k;
    iterations[k] = info.iterations;
  }
  std::printf("  iterations: none %d, Jacobi %d, block Jacobi %d, SSOR %d\n", iterations[0], iterations[1], iterations[2],
              iterations[3]);
  for (int k = 1; k < 4; ++k) EXPECT_LT(3 * iterations[k], iterations[0]) << k;

  // The stopping rule on a well-conditioned system: ||r||^2 <= tol ||b||^2, checked before each iteration.
  RandomSystem w = randomSymmetric(60, 3, 2.0, 44);
  const VectorXd bw = randomVector(w.A.rows(), 45);
  VectorXd x;
  const LinearSolveInfo info = preconditionedConjugateGradient(problemOf(w.A), bw, x, 1000, 1e-6, nullptr);
  EXPECT_LE(relResidual(w.dense, x, bw) * relResidual(w.dense, x, bw), 1e-6);
  const VectorXd before = referenceCG(w.dense, bw, info.iterations - 1);
  EXPECT_GT(relResidual(w.dense, before, bw) * relResidual(w.dense, before, bw), 1e-6);
  EXPECT_LT((x - referenceCG(w.dense, bw, info.iterations)).norm(), 1e-10 * x.norm());
  // Started at the solution, it does nothing.
  VectorXd solved = w.dense.ldlt().solve(bw);
  EXPECT_EQ(preconditionedConjugateGradient(problemOf(w.A), bw, solved, 1000, 1e-6, nullptr).iterations, 0);
}

// MINRES solves symmetric systems, indefinite ones included (where CG has no guarantee), to the
// tolerance on ||r|| / ||b||.
TEST(MinimumResidual, SolvesSymmetricIndefiniteSystems) {
  for (double shift : {0.5, -40.0}) {
    RandomSystem s = randomSymmetric(80, 3, 0.5, 51);
    // Shift the spectrum: -40 makes the matrix indefinite.
    for (int i = 0; i < s.A.blockRows(); ++i) {
      s.A.block(s.A.diagonalSlot(i)) += shift * Eigen::Matrix3d::Identity();
      s.dense.block<3, 3>(3 * i, 3 * i) += shift * Eigen::Matrix3d::Identity();
    }
    const Eigen::SelfAdjointEigenSolver<MatrixXd> eig(s.dense);
    if (shift < 0) ASSERT_LT(eig.eigenvalues().minCoeff(), 0.0);
    const VectorXd b = randomVector(s.A.rows(), 52);
    VectorXd x;
    const LinearSolveInfo info = minimumResidual(problemOf(s.A), b, x, 5000, 1e-10);
    ASSERT_TRUE(info.ok);
    EXPECT_LE(info.relResidual, 1e-10) << shift;
    EXPECT_LT(relResidual(s.dense, x, b), 1e-9) << shift;  // the recurrence's residual is the true one
  }
}

// projectNodes turns A into P A P + (I - P) on the partly held nodes' rows and columns.
TEST(BlockSparseMatrix, ProjectNodesGivesPAPPlusTheHeldIdentity) {
  RandomSystem s = randomSymmetric(12, 3, 1.0, 61);
  const Eigen::Vector3d n = Eigen::Vector3d(1, 2, 2).normalized();
  const Eigen::Matrix3d P1 = Eigen::Matrix3d::Identity() - n * n.transpose();
  Eigen::Matrix3d P5 = Eigen::Matrix3d::Identity();
  P5(0, 0) = P5(2, 2) = 0;  // x and z held
  s.A.projectNodes({{1, P1}, {5, P5}});
  MatrixXd P = MatrixXd::Identity(s.A.rows(), s.A.rows());
  P.block<3, 3>(3, 3) = P1;
  P.block<3, 3>(15, 15) = P5;
  const MatrixXd expected = P * s.dense * P + (MatrixXd::Identity(s.A.rows(), s.A.rows()) - P);
  EXPECT_LT((s.A.toDense() - expected).norm(), 1e-12 * expected.norm());
}
