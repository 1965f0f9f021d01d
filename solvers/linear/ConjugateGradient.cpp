#include <Eigen/Dense>
#include <cmath>
#include <memory>
#include <vector>

#include "core/Simd.h"
#include "solvers/linear/LinearSolver.h"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace viscera {

namespace {

// The iteration's vector passes, fused: x += alpha p and r -= alpha q in one pass that also
// returns the new r . r (the next iteration's residual), and p = r + beta p. Four partial sums of
// r . r, lane by lane, added at the end.
using UpdateKernel = double (*)(double alpha, const double* p, const double* q, double* x, double* r, long n);
using DirectionKernel = void (*)(double beta, const double* r, double* p, long n);

double updateGeneric(double alpha, const double* p, const double* q, double* x, double* r, long n) {
  double s[4] = {0, 0, 0, 0};
  long i = 0;
  for (; i + 4 <= n; i += 4)
    for (int k = 0; k < 4; ++k) {
      x[i + k] += alpha * p[i + k];
      r[i + k] -= alpha * q[i + k];
      s[k] += r[i + k] * r[i + k];
    }
  for (; i < n; ++i) {
    x[i] += alpha * p[i];
    r[i] -= alpha * q[i];
    s[i % 4] += r[i] * r[i];
  }
  return (s[0] + s[1]) + (s[2] + s[3]);
}

void directionGeneric(double beta, const double* r, double* p, long n) {
  for (long i = 0; i < n; ++i) p[i] = r[i] + beta * p[i];
}

#if defined(__x86_64__)
__attribute__((target("avx2,fma"))) double updateAvx2(double alpha, const double* p, const double* q, double* x, double* r, long n) {
  const __m256d a = _mm256_set1_pd(alpha);
  __m256d s = _mm256_setzero_pd();
  long i = 0;
  for (; i + 4 <= n; i += 4) {
    _mm256_storeu_pd(x + i, _mm256_fmadd_pd(a, _mm256_loadu_pd(p + i), _mm256_loadu_pd(x + i)));
    const __m256d ri = _mm256_fnmadd_pd(a, _mm256_loadu_pd(q + i), _mm256_loadu_pd(r + i));
    _mm256_storeu_pd(r + i, ri);
    s = _mm256_fmadd_pd(ri, ri, s);
  }
  double lanes[4];
  _mm256_storeu_pd(lanes, s);
  for (; i < n; ++i) {
    x[i] = std::fma(alpha, p[i], x[i]);
    r[i] = std::fma(-alpha, q[i], r[i]);
    lanes[i % 4] = std::fma(r[i], r[i], lanes[i % 4]);
  }
  return (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
}

__attribute__((target("avx2,fma"))) void directionAvx2(double beta, const double* r, double* p, long n) {
  const __m256d b = _mm256_set1_pd(beta);
  long i = 0;
  for (; i + 4 <= n; i += 4) _mm256_storeu_pd(p + i, _mm256_fmadd_pd(b, _mm256_loadu_pd(p + i), _mm256_loadu_pd(r + i)));
  for (; i < n; ++i) p[i] = std::fma(beta, p[i], r[i]);
}
#endif

struct CgKernels {
  UpdateKernel update = updateGeneric;
  DirectionKernel direction = directionGeneric;
  CgKernels() {
#if defined(__x86_64__)
    if (useAvx2()) {
      update = updateAvx2;
      direction = directionAvx2;
    }
#endif
  }
};

}  // namespace

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
  static const CgKernels kernels;
  double rho = 0, rhoPrev = 0;
  double rr = r.squaredNorm();  // then from each iteration's update of r
  for (int it = 1; it <= o.maxIterations; ++it) {
    // The residual and, unpreconditioned, rho.
    info.relResidual = std::sqrt(rr) / normb;
    if (info.relResidual <= o.tolerance) break;
    if (jacobi) {
      z = invDiag.cwiseProduct(r);
      rho = r.dot(z);
    } else {
      rho = rr;
    }
    if (it == 1) p = jacobi ? z : r;
    else kernels.direction(rho / rhoPrev, jacobi ? z.data() : r.data(), p.data(), n);
    double den;
    if (problem.applyDot) {
      den = problem.applyDot(p, q);
    } else {
      problem.apply(p, q);
      den = p.dot(q);
    }
    if (!std::isfinite(den)) {
      info.ok = false;
      info.message = "conjugate gradient broke down (non-finite p^T A p)";
      return info;
    }
    if (std::abs(den) <= o.threshold || den == 0.0) break;
    const double alpha = rho / den;
    rr = kernels.update(alpha, p.data(), q.data(), x.data(), r.data(), n);
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

namespace viscera {

LinearSolveInfo preconditionedConjugateGradient(const LinearProblem& problem, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                                int maxIterations, double tolerance, const Preconditioner* precondition) {
  LinearSolveInfo info;
  const Eigen::Index n = b.size();
  const double bb = b.squaredNorm();
  if (!std::isfinite(bb)) {
    info.ok = false;
    info.message = "right-hand side is not finite";
    return info;
  }
  if (x.size() != n) x = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd r(n), w(n), s(n);
  problem.apply(x, s);
  r = b - s;
  auto apply = [&](const Eigen::VectorXd& in, Eigen::VectorXd& out) {
    if (precondition) (*precondition)(in, out);
    else out = in;
  };
  apply(r, w);
  double delta = r.dot(w);
  const double tol = tolerance * bb;
  int it = 1;
  while (it <= maxIterations && delta > tol) {
    problem.apply(w, s);
    const double den = w.dot(s);
    if (!std::isfinite(den) || den == 0.0) {
      info.ok = std::isfinite(den);
      if (!info.ok) info.message = "preconditioned conjugate gradient broke down (non-finite w^T A w)";
      break;
    }
    const double alpha = delta / den;
    x.noalias() += alpha * w;
    r.noalias() -= alpha * s;
    apply(r, s);
    const double previous = delta;
    delta = r.dot(s);
    w = s + (delta / previous) * w;
    info.iterations = it++;
  }
  info.relResidual = bb > 0 ? r.norm() / std::sqrt(bb) : 0.0;
  if (!x.allFinite()) {
    info.ok = false;
    info.message = "preconditioned conjugate gradient produced non-finite values";
  }
  return info;
}

Preconditioner jacobiPreconditioner(const BlockSparseMatrix& A) {
  Eigen::VectorXd inv(A.rows());
  for (int i = 0; i < A.blockRows(); ++i) {
    const auto D = A.block(A.diagonalSlot(i));
    for (int k = 0; k < 3; ++k) inv[3 * i + k] = D(k, k) != 0.0 ? 1.0 / D(k, k) : 1.0;
  }
  return [inv](const Eigen::VectorXd& r, Eigen::VectorXd& z) { z = inv.cwiseProduct(r); };
}

Preconditioner blockJacobiPreconditioner(const BlockSparseMatrix& A) {
  std::vector<Eigen::Matrix3d> inv(A.blockRows());
  for (int i = 0; i < A.blockRows(); ++i) {
    const Eigen::Matrix3d D = A.block(A.diagonalSlot(i));
    const double det = D.determinant();
    inv[i] = det != 0.0 && std::isfinite(det) ? Eigen::Matrix3d(D.inverse()) : Eigen::Matrix3d::Identity();
  }
  return [inv](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
    z.resize(r.size());
    for (size_t i = 0; i < inv.size(); ++i) z.segment<3>(3 * i) = inv[i] * r.segment<3>(3 * i);
  };
}

Preconditioner ssorPreconditioner(const BlockSparseMatrix& A, double omega) {
  // Entry-wise over the 3n unknowns: first (D/omega + U) t = r backwards, then
  // (I + omega D^-1 L) z = t forwards, the order SOFA's SSORPreconditioner uses. A copy of A
  // keeps the preconditioner fixed until it is rebuilt.
  auto M = std::make_shared<const BlockSparseMatrix>(A);
  Eigen::VectorXd invDiag(A.rows());
  for (int i = 0; i < A.blockRows(); ++i) {
    const auto D = A.block(A.diagonalSlot(i));
    for (int k = 0; k < 3; ++k) invDiag[3 * i + k] = D(k, k) != 0.0 ? 1.0 / D(k, k) : 1.0;
  }
  return [M, invDiag, omega](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
    const int nb = M->blockRows();
    const auto& start = M->rowStart();
    const auto& cols = M->cols();
    z.resize(r.size());
    for (int bi = nb - 1; bi >= 0; --bi)
      for (int k = 2; k >= 0; --k) {
        const int row = 3 * bi + k;
        double sum = 0;
        for (int s = start[bi]; s < start[bi + 1]; ++s) {
          const auto B = M->block(s);
          for (int c = 0; c < 3; ++c) {
            const int col = 3 * cols[s] + c;
            if (col > row) sum += B(k, c) * z[col];
          }
        }
        z[row] = (r[row] - sum) * omega * invDiag[row];
      }
    for (int bi = 0; bi < nb; ++bi)
      for (int k = 0; k < 3; ++k) {
        const int row = 3 * bi + k;
        double sum = 0;
        for (int s = start[bi]; s < start[bi + 1]; ++s) {
          const auto B = M->block(s);
          for (int c = 0; c < 3; ++c) {
            const int col = 3 * cols[s] + c;
            if (col < row) sum += B(k, c) * z[col];
          }
        }
        z[row] -= sum * omega * invDiag[row];
      }
  };
}

}  // namespace viscera

namespace viscera {

LinearSolveInfo minimumResidual(const LinearProblem& problem, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                int maxIterations, double tolerance) {
  // Paige and Saunders' MINRES: Lanczos vectors v, the QR of the tridiagonal by Givens rotations
  // (c, s), and search directions w; the residual norm is |phi| without forming r.
  LinearSolveInfo info;
  const Eigen::Index n = b.size();
  const double normb = b.norm();
  if (!std::isfinite(normb)) {
    info.ok = false;
    info.message = "right-hand side is not finite";
    return info;
  }
  x = Eigen::VectorXd::Zero(n);
  if (normb == 0.0) return info;
  Eigen::VectorXd vPrev = Eigen::VectorXd::Zero(n), v = b / normb, Av(n), wPrev = Eigen::VectorXd::Zero(n),
                  wPrev2 = Eigen::VectorXd::Zero(n);
  double beta = normb, cPrev = 1, c = 1, sPrev = 0, s = 0, phi = normb;
  for (int it = 1; it <= maxIterations; ++it) {
    problem.apply(v, Av);
    const double alpha = v.dot(Av);
    Eigen::VectorXd vNext = Av - alpha * v - beta * vPrev;
    const double betaNext = vNext.norm();
    // Apply the two previous rotations to the new column (beta, alpha, betaNext) of T.
    const double e = sPrev * beta, dTmp = cPrev * beta;
    const double d = c * dTmp + s * alpha, g = -s * dTmp + c * alpha;
    const double rho = std::hypot(g, betaNext);
    if (!(rho > 0) || !std::isfinite(rho)) {
      info.ok = std::isfinite(rho);
      if (!info.ok) info.message = "MINRES broke down (non-finite Lanczos step)";
      break;
    }
    const double cNext = g / rho, sNext = betaNext / rho;
    const Eigen::VectorXd w = (v - d * wPrev - e * wPrev2) / rho;
    x.noalias() += cNext * phi * w;
    phi = -sNext * phi;
    info.iterations = it;
    info.relResidual = std::abs(phi) / normb;
    if (info.relResidual <= tolerance || betaNext == 0.0) break;
    wPrev2 = wPrev;
    wPrev = w;
    vPrev = v;
    v = vNext / betaNext;
    beta = betaNext;
    cPrev = c;
    sPrev = s;
    c = cNext;
    s = sNext;
  }
  if (!x.allFinite()) {
    info.ok = false;
    info.message = "MINRES produced non-finite values";
  }
  return info;
}

}  // namespace viscera
