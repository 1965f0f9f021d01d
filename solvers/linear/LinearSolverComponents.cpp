// Scene components for the linear solvers: CGLinearSolver, PCGLinearSolver with its preconditioners,
// and SparseLDLSolver.
#include <Eigen/SVD>
#include <memory>

#include "core/Component.h"
#include "core/Registry.h"
#include "solvers/linear/LinearSolver.h"

namespace viscera {

namespace {

// A linear solver's state block when it keeps nothing between solves.
struct NoWorkspace : ComponentStateOf<NoWorkspace> {
  void save(StateWriter&) const override {}
  void load(StateReader&) override {}
};

class CGLinearSolver : public Component, public LinearSolver {
 public:
  using Component::Component;
  void init() override {
    o_.maxIterations = static_cast<int>(attrs_.integer("iterations"));
    o_.tolerance = attrs_.real("tolerance");
    o_.threshold = attrs_.real("threshold");
    o_.warmStart = attrs_.boolean("warmStart");
    o_.preconditioner = attrs_.str("preconditioner") == "jacobi" ? CgOptions::Preconditioner::Jacobi
                                                                  : CgOptions::Preconditioner::None;
    assembled_ = attrs_.boolean("assembled");
    if (!assembled_ && o_.preconditioner != CgOptions::Preconditioner::None)
      throw error("preconditioner", "needs the assembled matrix; remove it or set assembled=\"true\"");
  }
  bool needsMatrix() const override { return assembled_; }
  LinearSolveInfo solve(State&, const LinearProblem& p, const Eigen::VectorXd& b, Eigen::VectorXd& x) const override {
    return conjugateGradient(p, b, x, o_);
  }

 private:
  CgOptions o_;
  bool assembled_ = true;
};

class MinResLinearSolver : public Component, public LinearSolver {
 public:
  using Component::Component;
  bool needsMatrix() const override { return false; }
  LinearSolveInfo solve(State&, const LinearProblem& p, const Eigen::VectorXd& b, Eigen::VectorXd& x) const override {
    return minimumResidual(p, b, x, static_cast<int>(attrs_.integer("iterations")), attrs_.real("tolerance"));
  }
};

// SparseLDLSolver factorises every step's matrix; PrecomputedLinearSolver (SOFA's) factorises the
// first one and solves every later step with it, as if the system never changed (a copied or
// restored state factorises again at its first step).
class SparseLDLSolver : public Component, public LinearSolver {
 public:
  using Component::Component;
  bool needsMatrix() const override { return true; }
  struct Live : ComponentStateOf<Live> {
    Scratch<CholmodSolver> chol;
    void save(StateWriter&) const override {}
    void load(StateReader&) override {}
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  LinearSolveInfo solve(State& s, const LinearProblem& p, const Eigen::VectorXd& b, Eigen::VectorXd& x) const override {
    Scratch<CholmodSolver>& chol = stateIn<Live>(s).chol;
    const bool factorized = !chol.empty();
    LinearSolveInfo info;
    if (!p.matrix) {
      info.ok = false;
      info.message = typeName() + " needs an assembled matrix";
      return info;
    }
    const bool precomputed = typeName() == "PrecomputedLinearSolver";
    // LDL^T and LU take indefinite matrices as SOFA's do; Cholesky (LL^T) refuses them.
    chol->allowIndefinite(typeName() == "SparseLDLSolver");
    if ((!precomputed || !factorized) && !chol->factorize(*p.matrix, info.message)) {
      chol.reset();
      info.ok = false;
      return info;
    }
    chol->solve(b, x);
    info.iterations = 1;
    if (!x.allFinite()) {
      info.ok = false;
      info.message = "SparseLDLSolver produced non-finite values";
    }
    return info;
  }
};

// SOFA's SVDLinearSolver: the dense singular value decomposition of the step's matrix, with the
// singular values below minSingularValue (relative to the largest) taken as zero: the
// least-squares solution of minimal norm, defined for singular systems too. Dense: for small ones.
class SVDLinearSolver : public Component, public LinearSolver {
 public:
  using Component::Component;
  bool needsMatrix() const override { return true; }
  void init() override {
    threshold_ = attrs_.real("minSingularValue");
    if (!(threshold_ >= 0)) throw error("minSingularValue", "must not be negative");
  }
  LinearSolveInfo solve(State&, const LinearProblem& p, const Eigen::VectorXd& b, Eigen::VectorXd& x) const override {
    LinearSolveInfo info;
    if (!p.matrix) {
      info.ok = false;
      info.message = typeName() + " needs an assembled matrix";
      return info;
    }
    Eigen::BDCSVD<Eigen::MatrixXd> svd(p.matrix->toDense(), Eigen::ComputeThinU | Eigen::ComputeThinV);
    const Eigen::VectorXd& sigma = svd.singularValues();
    const double cut = sigma.size() ? threshold_ * sigma[0] : 0.0;
    Eigen::VectorXd c = svd.matrixU().transpose() * b;
    for (Eigen::Index i = 0; i < c.size(); ++i) c[i] = sigma[i] > cut ? c[i] / sigma[i] : 0.0;
    x = svd.matrixV() * c;
    info.iterations = 1;
    if (!x.allFinite()) {
      info.ok = false;
      info.message = "SVDLinearSolver produced non-finite values";
    }
    return info;
  }

 private:
  double threshold_ = 1e-6;
};

// A preconditioner for PCGLinearSolver, built from the assembled matrix.
class PreconditionerComponent : public Component {
 public:
  using Component::Component;
  virtual Preconditioner build(const BlockSparseMatrix& A) const = 0;
};

class JacobiPreconditioner : public PreconditionerComponent {
 public:
  using PreconditionerComponent::PreconditionerComponent;
  Preconditioner build(const BlockSparseMatrix& A) const override { return jacobiPreconditioner(A); }
};

class BlockJacobiPreconditioner : public PreconditionerComponent {
 public:
  using PreconditionerComponent::PreconditionerComponent;
  Preconditioner build(const BlockSparseMatrix& A) const override { return blockJacobiPreconditioner(A); }
};

class SSORPreconditioner : public PreconditionerComponent {
 public:
  using PreconditionerComponent::PreconditionerComponent;
  Preconditioner build(const BlockSparseMatrix& A) const override { return ssorPreconditioner(A, attrs().real("omega")); }
};

class PCGLinearSolver : public Component, public LinearSolver {
 public:
  using Component::Component;
  void init() override {
    if (attrs_.boolean("use_precond") && attrs_.isSet("preconditioner")) {
      Component* c = linkedComponent("preconditioner");
      preconditioner_ = dynamic_cast<PreconditionerComponent*>(c);
      // A direct solver as preconditioner (SOFA's AsyncSparseLDLSolver): the factorised matrix itself.
      direct_ = !preconditioner_ && dynamic_cast<LinearSolver*>(c) && dynamic_cast<LinearSolver*>(c)->needsMatrix() &&
                c->typeName() != "PCGLinearSolver";
      if (!preconditioner_ && !direct_)
        throw error("preconditioner", "does not link to a preconditioner (JacobiPreconditioner, BlockJacobiPreconditioner, "
                                      "SSORPreconditioner or a direct solver such as SparseLDLSolver)");
    }
    updateStep_ = static_cast<int>(attrs_.integer("update_step"));
  }
  bool needsMatrix() const override { return preconditioner_ != nullptr || direct_; }
  // The preconditioner in use and the solves since the start; a copied state builds its own.
  struct Live : ComponentStateOf<Live> {
    Preconditioner precondition;
    long solves = 0;
    Live() = default;
    Live(const Live& o) : solves(o.solves) {}
    Live& operator=(const Live&) = delete;
    void save(StateWriter&) const override {}
    void load(StateReader&) override {}
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  LinearSolveInfo solve(State& s, const LinearProblem& p, const Eigen::VectorXd& b, Eigen::VectorXd& x) const override {
    Live& l = stateIn<Live>(s);
    Preconditioner& precondition = l.precondition;
    if (preconditioner_ || direct_) {
      LinearSolveInfo info;
      if (!p.matrix) {
        info.ok = false;
        info.message = "PCGLinearSolver's preconditioner needs an assembled matrix";
        return info;
      }
      // SOFA rebuilds the preconditioner every update_step solves and keeps it in between.
      if (l.solves++ % updateStep_ == 0 || !precondition) {
        if (preconditioner_) {
          precondition = preconditioner_->build(*p.matrix);
        } else {
          auto chol = std::make_shared<CholmodSolver>();
          if (!chol->factorize(*p.matrix, info.message)) {
            info.ok = false;
            info.message = "PCGLinearSolver's direct preconditioner: " + info.message;
            return info;
          }
          precondition = [chol](const Eigen::VectorXd& r, Eigen::VectorXd& z) { chol->solve(r, z); };
        }
      }
    }
    return preconditionedConjugateGradient(p, b, x, static_cast<int>(attrs_.integer("iterations")), attrs_.real("tolerance"),
                                           precondition ? &precondition : nullptr);
  }

 private:
  PreconditionerComponent* preconditioner_ = nullptr;
  bool direct_ = false;  // the preconditioner is a direct solver: the factorised matrix
  int updateStep_ = 1;
};

}  // namespace

std::unique_ptr<ComponentState> LinearSolver::initialState() const { return std::make_unique<NoWorkspace>(); }

void registerLinearSolvers(Registry& r) {
  {
    ComponentSpec s;
    s.name = "PCGLinearSolver";
    s.aliases = {"ShewchukPCGLinearSolver"};
    s.category = "solver";
    s.doc = "Preconditioned conjugate gradient, as SOFA's: starts from the previous step's solution and stops after "
            "`iterations` or when r^T M^-1 r <= tolerance b^T b (without a preconditioner the squared relative "
            "residual, so tolerance 1e-5 is a residual of about 3e-3). The preconditioner M is a linked "
            "JacobiPreconditioner, BlockJacobiPreconditioner or SSORPreconditioner, or a direct solver (the factorised "
            "matrix, as SOFA's AsyncSparseLDLSolver there), rebuilt every update_step steps.";
    s.add(AttrSpec::integer("iterations").def("25").atLeast(1).help("maximum number of iterations"));
    s.add(AttrSpec::real("tolerance").def("1e-5").atLeast(0).help("stop when r^T M^-1 r <= tolerance b^T b"));
    s.add(AttrSpec::boolean("use_precond").def("true").help("apply the preconditioner (false: plain conjugate gradient)"));
    s.add(AttrSpec::link("preconditioner").help("the preconditioner component (none: plain conjugate gradient)"));
    s.add(AttrSpec::integer("update_step").def("1").atLeast(1).help("rebuild the preconditioner every this many solves"));
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.factory = [](BuildContext& c) { return std::make_unique<PCGLinearSolver>(c); };
    r.add(std::move(s));
  }
  const char* preconditioners[3][2] = {
      {"JacobiPreconditioner", "The diagonal of the assembled matrix, for PCGLinearSolver."},
      {"BlockJacobiPreconditioner", "The 3x3 diagonal blocks (one per node) of the assembled matrix, inverted, for PCGLinearSolver."},
      {"SSORPreconditioner", "Symmetric successive over-relaxation of the assembled matrix (omega 1: symmetric Gauss-Seidel), "
                             "for PCGLinearSolver, in SOFA's order (the upper sweep first)."}};
  for (auto& p : preconditioners) {
    ComponentSpec s;
    s.name = p[0];
    s.category = "solver";
    s.doc = p[1];
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    const std::string name = p[0];
    if (name == "SSORPreconditioner") {
      s.add(AttrSpec::real("omega").def("1").above(0).below(2).help("relaxation factor, in (0, 2)"));
      s.factory = [](BuildContext& c) { return std::make_unique<SSORPreconditioner>(c); };
    } else if (name == "JacobiPreconditioner") {
      s.factory = [](BuildContext& c) { return std::make_unique<JacobiPreconditioner>(c); };
    } else {
      s.factory = [](BuildContext& c) { return std::make_unique<BlockJacobiPreconditioner>(c); };
    }
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "CGLinearSolver";
    s.category = "solver";
    s.doc = "Conjugate gradient, as SOFA's: starts from zero, stops after `iterations`, when ||r||/||b|| <= "
            "tolerance, or when |p^T A p| <= threshold. Assembled (3x3 block sparse) by default, or matrix-free.";
    s.add(AttrSpec::integer("iterations").def("25").atLeast(1).help("maximum number of iterations"));
    s.add(AttrSpec::real("tolerance").def("1e-5").atLeast(0).help("relative residual ||r||/||b|| to stop at"));
    s.add(AttrSpec::real("threshold").def("1e-5").atLeast(0).help("stop when |p^T A p| falls to this"));
    s.add(AttrSpec::boolean("warmStart").def("false").help("start from the previous solution"));
    s.add(AttrSpec::choice("preconditioner", {"none", "jacobi"}).def("none").help("none | jacobi (diagonal)"));
    s.add(AttrSpec::boolean("assembled").def("true").help("assemble the matrix (false: matrix-free products)"));
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.factory = [](BuildContext& c) { return std::make_unique<CGLinearSolver>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "SparseLDLSolver";
    // SOFA's other direct solvers give the same solution of the step's symmetric positive definite
    // system (up to round-off), so they map to this one.
    s.aliases = {"EigenSimplicialLDLT", "EigenSparseLU", "EigenSparseQR", "AsyncSparseLDLSolver"};
    s.category = "solver";
    s.doc = "Direct sparse LDL^T through SuiteSparse CHOLMOD; the symbolic analysis is computed once and reused. "
            "SOFA's EigenSimplicialLDLT, EigenSparseLU/QR and AsyncSparseLDLSolver solve the same symmetric system "
            "and map to it. An indefinite system (an inverted hyperelastic body) is factorised as LDL^T with negative "
            "pivots, as SOFA's is; only a zero pivot fails.";
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.factory = [](BuildContext& c) { return std::make_unique<SparseLDLSolver>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "SparseCholeskySolver";
    s.aliases = {"CholmodSolver", "EigenSimplicialLLT"};
    s.category = "solver";
    s.doc = "Direct sparse Cholesky (LL^T) through SuiteSparse CHOLMOD, as SparseLDLSolver, but a system that is not "
            "positive definite fails the step, as SOFA's LL^T solvers do.";
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.factory = [](BuildContext& c) { return std::make_unique<SparseLDLSolver>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "SVDLinearSolver";
    s.category = "solver";
    s.doc = "Dense singular value decomposition of the step's assembled matrix (SOFA's SVDLinearSolver): singular values "
            "below minSingularValue times the largest count as zero, so a singular system gets its minimal-norm "
            "least-squares solution. Dense, so for small systems (a few thousand unknowns at most).";
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.add(AttrSpec::real("minSingularValue").def("1e-6").help("relative singular value below which a direction is dropped"));
    s.add(AttrSpec::boolean("verbose").def("false").help("accepted for SOFA scenes"));
    s.factory = [](BuildContext& c) { return std::make_unique<SVDLinearSolver>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "PrecomputedLinearSolver";
    s.category = "solver";
    s.doc = "SOFA's PrecomputedLinearSolver: the first step's matrix is factorised (CHOLMOD) and that factorisation "
            "solves every later step, as if the system never changed (fast, and exact only for a linear model).";
    s.add(AttrSpec::boolean("use_file").def("false").help("must be false: the factorisation is not stored in a file"));
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
      if (c.attrs().boolean("use_file")) throw c.attrs().error("use_file", "a stored factorisation is not supported; set it false");
      return std::make_unique<SparseLDLSolver>(c);
    };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "MinResLinearSolver";
    s.category = "solver";
    s.doc = "MINRES (minimum residual, Paige and Saunders), matrix-free, from zero: for symmetric systems, definite or "
            "not; stops after `iterations` or when ||r||/||b|| <= tolerance.";
    s.add(AttrSpec::integer("iterations").def("25").atLeast(1).help("maximum number of iterations"));
    s.add(AttrSpec::real("tolerance").def("1e-5").atLeast(0).help("relative residual ||r||/||b|| to stop at"));
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.factory = [](BuildContext& c) { return std::make_unique<MinResLinearSolver>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
