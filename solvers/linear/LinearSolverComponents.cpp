// Scene components for the linear solvers: CGLinearSolver and SparseLDLSolver.
#include "core/Component.h"
#include "core/Registry.h"
#include "solvers/linear/LinearSolver.h"

namespace viscera {

namespace {

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
  LinearSolveInfo solve(const LinearProblem& p, const Eigen::VectorXd& b, Eigen::VectorXd& x) override {
    return conjugateGradient(p, b, x, o_);
  }

 private:
  CgOptions o_;
  bool assembled_ = true;
};

class SparseLDLSolver : public Component, public LinearSolver {
 public:
  using Component::Component;
  bool needsMatrix() const override { return true; }
  LinearSolveInfo solve(const LinearProblem& p, const Eigen::VectorXd& b, Eigen::VectorXd& x) override {
    LinearSolveInfo info;
    if (!p.matrix) {
      info.ok = false;
      info.message = "SparseLDLSolver needs an assembled matrix";
      return info;
    }
    if (!chol_.factorize(*p.matrix, info.message)) {
      info.ok = false;
      return info;
    }
    chol_.solve(b, x);
    info.iterations = 1;
    if (!x.allFinite()) {
      info.ok = false;
      info.message = "SparseLDLSolver produced non-finite values";
    }
    return info;
  }

 private:
  CholmodSolver chol_;
};

}  // namespace

void registerLinearSolvers(Registry& r) {
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
    s.aliases = {"SparseCholeskySolver", "CholmodSolver", "EigenSimplicialLDLT", "EigenSimplicialLLT", "EigenSparseLU",
                 "EigenSparseQR", "AsyncSparseLDLSolver"};
    s.category = "solver";
    s.doc = "Direct sparse LDL^T through SuiteSparse CHOLMOD; the symbolic analysis is computed once and reused. "
            "SOFA's EigenSimplicialLDLT/LLT, EigenSparseLU/QR and AsyncSparseLDLSolver solve the same symmetric "
            "positive definite system and map to it.";
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.factory = [](BuildContext& c) { return std::make_unique<SparseLDLSolver>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
