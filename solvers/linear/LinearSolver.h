// Linear solvers for the implicit step: conjugate gradient (assembled or matrix-free) and sparse
// LDL^T through CHOLMOD. The ODE solver hands them a LinearProblem each step.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "core/State.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

struct LinearProblem {
  // The assembled, constrained matrix, or nullptr when only the operator is available.
  const BlockSparseMatrix* matrix = nullptr;
  // q = A p with constraints applied; always available.
  std::function<void(const Eigen::VectorXd& p, Eigen::VectorXd& q)> apply;
  // q = A p returning p . q, where the product can give it in the same pass (else empty).
  std::function<double(const Eigen::VectorXd& p, Eigen::VectorXd& q)> applyDot;
  // Diagonal of A, for Jacobi preconditioning (empty if unknown).
  Eigen::VectorXd diagonal;
};

struct LinearSolveInfo {
  bool ok = true;          // false: breakdown, factorization failure or non-finite result
  int iterations = 0;
  double relResidual = 0;  // ||b - A x|| / ||b|| as the solver saw it
  std::string message;
};

// The role of a linear solver component. Its workspace (factorisations, preconditioners) is in
// the simulation's state: it is rebuilt as the simulation steps and never saved.
class LinearSolver : public Stateful {
 public:
  // Whether the ODE solver must assemble the matrix for this solver.
  virtual bool needsMatrix() const = 0;
  // Whether the assembled matrix may come in upper storage (BlockSparseMatrix::Storage::Upper):
  // solvers that only multiply by it and read its diagonal.
  virtual bool takesUpperMatrix() const { return false; }
  // Solves A x = b. `x` holds the previous solution on entry (used by warm starts).
  virtual LinearSolveInfo solve(State& s, const LinearProblem& problem, const Eigen::VectorXd& b,
                                Eigen::VectorXd& x) const = 0;
  // No workspace by default.
  std::unique_ptr<ComponentState> initialState() const override;
};

struct CgOptions {
  int maxIterations = 25;
  double tolerance = 1e-5;  // stop when ||r|| / ||b|| <= tolerance
  double threshold = 1e-5;  // stop when |p^T A p| <= threshold (SOFA's test)
  bool warmStart = false;
  enum class Preconditioner { None, Jacobi } preconditioner = Preconditioner::None;
};

// Conjugate gradient as SOFA's CGLinearSolver runs it: starts from zero (or x on warm start),
// stops on the iteration count, the relative residual, or a small curvature p^T A p.
LinearSolveInfo conjugateGradient(const LinearProblem& problem, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                  const CgOptions& options);

// MINRES (Paige and Saunders) from zero: for symmetric, possibly indefinite A; stops after
// `maxIterations` or when ||r|| / ||b|| <= tolerance.
LinearSolveInfo minimumResidual(const LinearProblem& problem, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                int maxIterations, double tolerance);

// z = M^-1 r for a preconditioner M.
using Preconditioner = std::function<void(const Eigen::VectorXd& r, Eigen::VectorXd& z)>;
// Preconditioned conjugate gradient as SOFA's PCGLinearSolver runs it: starts from x (the previous
// solution), and stops after `maxIterations` or when r^T M^-1 r <= tolerance b^T b (without a
// preconditioner: the squared relative residual). `precondition` may be null.
LinearSolveInfo preconditionedConjugateGradient(const LinearProblem& problem, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                                int maxIterations, double tolerance, const Preconditioner* precondition);
// Preconditioners built from the assembled matrix as it is now: its diagonal, its 3x3 diagonal
// blocks, and SSOR with relaxation omega (symmetric Gauss-Seidel at 1).
Preconditioner jacobiPreconditioner(const BlockSparseMatrix& A);
Preconditioner blockJacobiPreconditioner(const BlockSparseMatrix& A);
Preconditioner ssorPreconditioner(const BlockSparseMatrix& A, double omega);

// How each node of a body has turned since rest (SOFA's rotation finders: the corotational force
// fields), as of their last force evaluation: the warp preconditioners turn a matrix factorised
// earlier with these rotations.
class RotationFinder {
 public:
  virtual ~RotationFinder() = default;
  // One rest -> current rotation per node of the body.
  virtual void nodeRotations(const State& s, std::vector<Eigen::Matrix3d>& R) const = 0;
};
// The rotation of each of `nodeCount` nodes from those of the elements around it: the orthonormal
// (polar) factor of their sum, identity for a node in no element. Element e has the
// `nodesPerElement` nodes elementNodes[e * nodesPerElement ...].
std::vector<Eigen::Matrix3d> averageNodeRotations(int nodeCount, const int* elementNodes, int nodesPerElement,
                                                  const Eigen::Matrix3d* elementRotations, int elementCount);

// Sparse LDL^T (CHOLMOD). The symbolic analysis is done once for a pattern and reused.
class CholmodSolver {
 public:
  CholmodSolver();
  ~CholmodSolver();
  CholmodSolver(const CholmodSolver&) = delete;
  CholmodSolver& operator=(const CholmodSolver&) = delete;
  // Factorizes A (symmetric; the lower triangle is read). Returns false with a message if A is
  // not positive definite (unless allowed below), has a zero pivot, or the factorization fails.
  bool factorize(const BlockSparseMatrix& A, std::string& message);
  // Accept symmetric indefinite matrices (LDL^T with negative pivots, as SOFA's SparseLDLSolver):
  // a matrix the supernodal LL^T refuses is factorised again simplicially as LDL^T.
  void allowIndefinite(bool on);
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  int analyses() const { return analyses_; }
  // Symbolic analyses are shared by every solver of the process that factorises the same
  // pattern; this forgets them (benchmarks of a cold start).
  static void clearSharedAnalyses();

 private:
  struct Impl;
  Impl* impl_;
  int analyses_ = 0;
};

}  // namespace viscera
