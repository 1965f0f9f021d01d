#include <cmath>

#include "solvers/linear/LinearSolver.h"

namespace viscera {

LinearSolveInfo conjugateGradient(const LinearProblem& problem, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                  const CgOptions& o) {
  LinearSolveInfo info;
  const Eigen::Index n = b.size();
  Eigen::VectorXd r(n), p(n), q(n), z;
  const double normb = b.norm();
  if (!std::isfinite(normb)) {
    info.ok = false;
    info.message = "right-hand side is not finite";
    return info;
  }
  if (normb == 0.0) {
    x.setZero();
    return info;
  }
  if (o.warmStart && x.size() == n) {
    problem.apply(x, q);
    r = b - q;
  } else {
    x.setZero(n);
    r = b;
  }
  const bool jacobi = o.preconditioner == CgOptions::Preconditioner::Jacobi && problem.diagonal.size() == n;
  Eigen::VectorXd invDiag;
  if (jacobi) invDiag = problem.diagonal.unaryExpr([](double d) { return d != 0.0 ? 1.0 / d : 1.0; });
  double rho = 0, rhoPrev = 0;
  for (int it = 1; it <= o.maxIterations; ++it) {
    info.relResidual = r.norm() / normb;
    if (info.relResidual <= o.tolerance) break;
    if (jacobi) {
      z = invDiag.cwiseProduct(r);
      rho = r.dot(z);
    } else {
      rho = r.squaredNorm();
    }
    if (it == 1) p = jacobi ? z : r;
    else p = (jacobi ? z : r) + (rho / rhoPrev) * p;
    problem.apply(p, q);
    const double den = p.dot(q);
    if (!std::isfinite(den)) {
      info.ok = false;
      info.message = "conjugate gradient broke down (non-finite p^T A p)";
      return info;
    }
    if (std::abs(den) <= o.threshold || den == 0.0) break;
    const double alpha = rho / den;
    x.noalias() += alpha * p;
    r.noalias() -= alpha * q;
    rhoPrev = rho;
    info.iterations = it;
  }
  info.relResidual = r.norm() / normb;
  if (!std::isfinite(info.relResidual)) {
    info.ok = false;
    info.message = "conjugate gradient produced a non-finite residual";
  }
  return info;
}

}  // namespace viscera
