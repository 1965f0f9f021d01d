#include <cholmod.h>
#include <dlfcn.h>

#include <cmath>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "solvers/linear/LinearSolver.h"

namespace viscera {

namespace {

// Debian's serial OpenBLAS (the BLAS CHOLMOD's supernodal path calls) is built without locking:
// two threads in it at once corrupt each other's buffers, and simulations run in parallel threads
// gave results that changed from run to run. Supernodal factorisations and solves therefore take
// this lock; simplicial ones call no BLAS and run in parallel.
std::mutex& blasMutex() {
  static std::mutex m;
  return m;
}

// Symbolic analyses (fill-reducing ordering and symbolic factor) shared by every solver that
// factorises the same block pattern: scene variants that change only parameters analyse once per
// process. Orderings run under the cache's lock (METIS keeps global state).
class SymbolicCache {
 public:
  SymbolicCache() { cholmod_start(&common_); }
  ~SymbolicCache() {
    clear();
    cholmod_finish(&common_);
  }
  void clear() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& e : entries_) cholmod_free_factor(&e.L, &common_);
    entries_.clear();
  }
  // A symbolic factor of A (whose block pattern is rowStart/cols) owned by `common`'s caller.
  cholmod_factor* analyse(cholmod_sparse* A, const std::vector<int>& rowStart, const std::vector<int>& cols,
                          cholmod_common& common) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& e : entries_)
      if (e.supernodal == common.supernodal && e.rowStart == rowStart && e.cols == cols) return cholmod_copy_factor(e.L, &common);
    cholmod_factor* L = cholmod_analyze(A, &common);
    if (!L) return nullptr;
    // A bounded number of patterns: a batch study has a few.
    if (entries_.size() >= 8) {
      cholmod_free_factor(&entries_.front().L, &common_);
      entries_.erase(entries_.begin());
    }
    entries_.push_back({rowStart, cols, common.supernodal, cholmod_copy_factor(L, &common_)});
    return L;
  }

 private:
  struct Entry {
    std::vector<int> rowStart, cols;
    int supernodal;
    cholmod_factor* L;
  };
  std::mutex mutex_;
  cholmod_common common_;
  std::vector<Entry> entries_;
};

SymbolicCache& symbolicCache() {
  static SymbolicCache c;
  return c;
}

// Debian's CHOLMOD opens OpenMP regions with a fixed team size inside its supernodal
// factorisation; their thread wake-ups and barriers made the gel phantom's factorisation three
// times slower (57.6 -> 18.0 ms a step, wall; CPU time fell too) and left the core idle while
// waiting. Parallel work here comes from TBB and from simulations run side by side, so CHOLMOD
// runs serially: OpenMP's max-active-levels set to 0 makes every region run on its calling
// thread. libgomp keeps that setting per thread, so each thread that factorises or solves sets
// it once. Looked up at run time: a CHOLMOD built without OpenMP needs nothing, and nothing else
// in the program uses OpenMP.
void serialOpenMp() {
  thread_local bool done = false;
  if (done) return;
  done = true;
  using SetLevels = void (*)(int);
  static const auto set = reinterpret_cast<SetLevels>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"));
  if (set) set(0);
}

}  // namespace

// Below this many unknowns the simplicial factorisation is used: no BLAS and no OpenMP regions,
// whose thread wake-ups cost more than the arithmetic on small systems (measured with
// BM_CoarseVariantBuild: the 975-unknown compliance of the coarse phantom).
constexpr int kSimplicialBelow = 3000;

struct CholmodSolver::Impl {
  cholmod_common common;
  cholmod_sparse* A = nullptr;     // lower triangle, scalar CSC, pattern fixed once analysed
  cholmod_factor* L = nullptr;
  std::vector<int> blockToValue;   // for each stored scalar entry: index into the block values
  std::vector<int> rowStart, cols; // pattern the analysis was made for
  bool indefinite = false;         // negative pivots accepted (simplicial LDL^T)

  Impl() {
    cholmod_start(&common);
    common.supernodal = CHOLMOD_AUTO;
    common.final_ll = false;  // keep LDL^T where CHOLMOD factors simplicially
    common.print = 0;         // failures are reported to the caller, not printed
  }
  ~Impl() {
    if (L) cholmod_free_factor(&L, &common);
    if (A) cholmod_free_sparse(&A, &common);
    cholmod_finish(&common);
  }

  // Builds the scalar lower-triangle CSC for the block pattern and the map from its entries
  // into the block value array.
  void buildPattern(const BlockSparseMatrix& M) {
    if (L) cholmod_free_factor(&L, &common);
    if (A) cholmod_free_sparse(&A, &common);
    const int n = M.rows();
    common.supernodal = n < kSimplicialBelow ? CHOLMOD_SIMPLICIAL : CHOLMOD_AUTO;
    // Count lower-triangle scalar entries per scalar column.
    std::vector<int> colCount(n, 0);
    const auto& rs = M.rowStart();
    const auto& cs = M.cols();
    // The matrix is symmetric: block row i lists block columns j; the scalar column 3j+b
    // receives rows 3i+a with 3i+a >= 3j+b.
    for (int i = 0; i < M.blockRows(); ++i)
      for (int s = rs[i]; s < rs[i + 1]; ++s) {
        int j = cs[s];
        if (j > i) continue;
        for (int b = 0; b < 3; ++b)
          for (int a = 0; a < 3; ++a)
            if (3 * i + a >= 3 * j + b) colCount[3 * j + b]++;
      }
    size_t nnz = 0;
    for (int c : colCount) nnz += c;
    A = cholmod_allocate_sparse(n, n, nnz, true, true, -1, CHOLMOD_REAL, &common);
    int* Ap = static_cast<int*>(A->p);
    int* Ai = static_cast<int*>(A->i);
    Ap[0] = 0;
    for (int c = 0; c < n; ++c) Ap[c + 1] = Ap[c] + colCount[c];
    std::vector<int> fill(Ap, Ap + n);
    blockToValue.assign(nnz, 0);
    // Block rows are visited in increasing order, so row indices in each column come out sorted.
    for (int i = 0; i < M.blockRows(); ++i)
      for (int s = rs[i]; s < rs[i + 1]; ++s) {
        int j = cs[s];
        if (j > i) continue;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) {
            if (3 * i + a < 3 * j + b) continue;
            int col = 3 * j + b;
            int k = fill[col]++;
            Ai[k] = 3 * i + a;
            blockToValue[k] = 9 * s + 3 * a + b;  // row-major block storage
          }
      }
    rowStart = rs;
    cols = cs;
  }
};

CholmodSolver::CholmodSolver() : impl_(new Impl()) {}
void CholmodSolver::clearSharedAnalyses() { symbolicCache().clear(); }
CholmodSolver::~CholmodSolver() { delete impl_; }

bool CholmodSolver::factorize(const BlockSparseMatrix& M, std::string& message) {
  serialOpenMp();
  Impl& d = *impl_;
  if (!d.A || d.rowStart != M.rowStart() || d.cols != M.cols()) {
    d.buildPattern(M);
    d.L = symbolicCache().analyse(d.A, d.rowStart, d.cols, d.common);
    ++analyses_;
    if (!d.L) {
      message = "CHOLMOD analysis failed";
      return false;
    }
  }
  double* Ax = static_cast<double*>(d.A->x);
  const double* vals = M.values();
  for (size_t k = 0; k < d.blockToValue.size(); ++k) Ax[k] = vals[d.blockToValue[k]];
  std::optional<std::lock_guard<std::mutex>> lock;
  if (d.L->is_super) lock.emplace(blasMutex());
  bool ok = cholmod_factorize(d.A, d.L, &d.common) && d.common.status == CHOLMOD_OK;
  if (!ok && d.indefinite && d.common.status == CHOLMOD_NOT_POSDEF && d.L->is_super) {
    // Supernodal factorisation is LL^T: an indefinite matrix takes the simplicial LDL^T, for good.
    lock.reset();
    cholmod_free_factor(&d.L, &d.common);
    d.common.supernodal = CHOLMOD_SIMPLICIAL;
    d.L = symbolicCache().analyse(d.A, d.rowStart, d.cols, d.common);
    ++analyses_;
    if (!d.L) {
      d.rowStart.clear();  // the next call analyses afresh
      message = "CHOLMOD analysis failed";
      return false;
    }
    ok = cholmod_factorize(d.A, d.L, &d.common) && d.common.status == CHOLMOD_OK;
  }
  if (!ok) {
    // Simplicial LDL^T stops at a zero pivot with the same status as LL^T at a negative one.
    message = d.common.status != CHOLMOD_NOT_POSDEF ? "CHOLMOD factorization failed"
              : d.indefinite && !d.L->is_super   ? "matrix is singular (CHOLMOD, zero pivot)"
                                                 : "matrix is not positive definite (CHOLMOD)";
    return false;
  }
  // CHOLMOD's supernodal factorization is LL^T and fails on an indefinite matrix; its simplicial
  // LDL^T would not, so check D to behave the same whatever the size (and, where indefinite
  // matrices are accepted, refuse only a zero pivot).
  if (!d.L->is_super) {
    const int* Lp = static_cast<const int*>(d.L->p);
    const double* Lx = static_cast<const double*>(d.L->x);
    for (size_t j = 0; j < d.L->n; ++j) {
      const double pivot = Lx[Lp[j]];
      if (d.indefinite ? !(pivot != 0.0 && std::isfinite(pivot)) : !(pivot > 0.0)) {
        message = (d.indefinite ? "matrix is singular (CHOLMOD, zero pivot " : "matrix is not positive definite (CHOLMOD, pivot ") +
                  std::to_string(j) + ")";
        return false;
      }
    }
  }
  return true;
}

void CholmodSolver::allowIndefinite(bool on) { impl_->indefinite = on; }

void CholmodSolver::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  serialOpenMp();
  Impl& d = *impl_;
  cholmod_dense* B = cholmod_allocate_dense(b.size(), 1, b.size(), CHOLMOD_REAL, &d.common);
  std::copy(b.data(), b.data() + b.size(), static_cast<double*>(B->x));
  std::optional<std::lock_guard<std::mutex>> lock;
  if (d.L->is_super) lock.emplace(blasMutex());
  cholmod_dense* X = cholmod_solve(CHOLMOD_A, d.L, B, &d.common);
  lock.reset();
  x.resize(b.size());
  std::copy(static_cast<double*>(X->x), static_cast<double*>(X->x) + b.size(), x.data());
  cholmod_free_dense(&X, &d.common);
  cholmod_free_dense(&B, &d.common);
}

}  // namespace viscera
