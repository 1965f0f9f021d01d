// Scene components for the linear solvers: CGLinearSolver, PCGLinearSolver with its preconditioners,
// and SparseLDLSolver.
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <memory>

#include "core/Component.h"
#include "core/Registry.h"
#include "core/Scene.h"
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
  bool takesUpperMatrix() const override { return true; }  // products and the diagonal (Jacobi)
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

// A preconditioner for PCGLinearSolver, built from the assembled matrix (and, for those that keep
// a factorisation between solves, their part of the state). An empty result is a failure, said in
// `message`.
class PreconditionerComponent : public Component {
 public:
  using Component::Component;
  virtual Preconditioner build(State& s, const BlockSparseMatrix& A, std::string& message) const = 0;
  // True for one that decides itself when to rebuild (it is asked at every solve, whatever the
  // PCG's update_step).
  virtual bool rebuildsItself() const { return false; }
};

class JacobiPreconditioner : public PreconditionerComponent {
 public:
  using PreconditionerComponent::PreconditionerComponent;
  Preconditioner build(State&, const BlockSparseMatrix& A, std::string&) const override { return jacobiPreconditioner(A); }
};

class BlockJacobiPreconditioner : public PreconditionerComponent {
 public:
  using PreconditionerComponent::PreconditionerComponent;
  Preconditioner build(State&, const BlockSparseMatrix& A, std::string&) const override {
    return blockJacobiPreconditioner(A);
  }
};

class SSORPreconditioner : public PreconditionerComponent {
 public:
  using PreconditionerComponent::PreconditionerComponent;
  Preconditioner build(State&, const BlockSparseMatrix& A, std::string&) const override {
    return ssorPreconditioner(A, attrs().real("omega"));
  }
};

// SOFA's RotationMatrixSystem: the rotations a WarpPreconditioner turns its factorised matrix with
// (from the corotational force field in its context, or the one `rotationFinder` names), and how
// often that matrix is factorised again (`assemblingRate` solves).
class RotationMatrixSystem : public Component {
 public:
  using Component::Component;
  void init() override {
    if (attrs_.isSet("rotationFinder")) {
      finder_ = dynamic_cast<const RotationFinder*>(linkedComponent("rotationFinder"));
      if (!finder_)
        throw error("rotationFinder", "does not link to a corotational force field (TetrahedronFEMForceField or "
                                      "HexahedronFEMForceField)");
    }
  }
  const RotationFinder* finder() const { return finder_; }
  int rate() const { return static_cast<int>(attrs_.integer("assemblingRate")); }

 private:
  const RotationFinder* finder_ = nullptr;
};

// SOFA's WarpPreconditioner and PrecomputedWarpPreconditioner: a factorisation of the step's matrix
// A0, kept for later solves and turned with how each node has rotated since it was made:
// M^-1 r = Q A0^-1 Q^T r, Q the block diagonal of R_i R0_i^T (node rotations now and at the
// factorisation). The corotational stiffness turns with its elements, so this stays a close inverse
// for many steps. WarpPreconditioner factorises again every update_step solves (or the
// RotationMatrixSystem's assemblingRate, the longer); PrecomputedWarpPreconditioner factorises once.
class WarpPreconditioner : public PreconditionerComponent, public Stateful {
 public:
  using PreconditionerComponent::PreconditionerComponent;
  void init() override {
    precomputed_ = typeName() == "PrecomputedWarpPreconditioner";
    // The factorisation is made here, with CHOLMOD as SparseLDLSolver makes it; the link says
    // which direct solver a SOFA scene meant, and must name one.
    if (attrs_.isSet("linearSolver") && !dynamic_cast<SparseLDLSolver*>(linkedComponent("linearSolver")))
      throw error("linearSolver", "does not link to a direct solver (SparseLDLSolver, SparseCholeskySolver, "
                                  "AsyncSparseLDLSolver, ...): the factorisation the preconditioner turns");
    RotationMatrixSystem* system = nullptr;
    if (attrs_.isSet("linearSystem")) {
      system = dynamic_cast<RotationMatrixSystem*>(linkedComponent("linearSystem"));
      if (!system && !precomputed_)
        throw error("linearSystem", "does not link to a RotationMatrixSystem");
    } else {
      system = node().findInContext<RotationMatrixSystem>();
    }
    if (system) scene().initComponent(*system);  // its rotationFinder link is resolved in its init
    period_ = precomputed_ ? 0 : static_cast<int>(attrs_.integer("update_step"));
    if (system && !precomputed_) period_ = std::max(period_, system->rate());
    finder_ = system ? system->finder() : nullptr;
    // As SOFA's: the first rotation finder in the node, else in the nearest ancestor that has one.
    for (const Node* n = &node(); n && !finder_; n = n->parent()) finder_ = n->find<RotationFinder>();
    useRotations_ = !precomputed_ || attrs_.boolean("use_rotations");
    if (!finder_ && useRotations_)
      throw error("needs a corotational force field (TetrahedronFEMForceField or HexahedronFEMForceField) in its node "
                  "or above, or a RotationMatrixSystem naming one: the rotations it turns the factorised matrix with");
  }
  bool rebuildsItself() const override { return true; }
  struct Live : ComponentStateOf<Live> {
    std::shared_ptr<CholmodSolver> chol;  // A0's factorisation
    std::vector<Eigen::Matrix3d> R0;      // node rotations when it was made
    long solves = 0;                      // since it was made
    Live() = default;
    Live(const Live&) {}  // a copied state factorises its own at its first solve
    Live& operator=(const Live&) = delete;
    void save(StateWriter&) const override {}
    void load(StateReader&) override {}
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }

  Preconditioner build(State& s, const BlockSparseMatrix& A, std::string& message) const override {
    Live& l = stateIn<Live>(s);
    std::vector<Eigen::Matrix3d> R;
    if (useRotations_) {
      finder_->nodeRotations(s, R);
      if (3 * static_cast<long>(R.size()) != A.rows()) {
        message = typeName() + " '" + name() + "': the system has " + std::to_string(A.rows()) +
                  " rows but the rotations are of " + std::to_string(R.size()) + " nodes (one body's nodes only)";
        return {};
      }
    }
    if (!l.chol || (period_ > 0 && l.solves >= period_)) {
      auto chol = std::make_shared<CholmodSolver>();
      chol->allowIndefinite(true);
      if (!chol->factorize(A, message)) {
        message = typeName() + " '" + name() + "': " + message;
        return {};
      }
      l.chol = std::move(chol);
      l.R0 = R;
      l.solves = 0;
    }
    ++l.solves;
    std::shared_ptr<CholmodSolver> chol = l.chol;
    if (!useRotations_) return [chol](const Eigen::VectorXd& r, Eigen::VectorXd& z) { chol->solve(r, z); };
    std::vector<Eigen::Matrix3d> Q(R.size());
    for (size_t i = 0; i < R.size(); ++i) Q[i] = R[i] * l.R0[i].transpose();
    return [chol, Q = std::move(Q)](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
      Eigen::VectorXd t(r.size());
      for (size_t i = 0; i < Q.size(); ++i) t.segment<3>(3 * i) = Q[i].transpose() * r.segment<3>(3 * i);
      Eigen::VectorXd u;
      chol->solve(t, u);
      z.resize(r.size());
      for (size_t i = 0; i < Q.size(); ++i) z.segment<3>(3 * i) = Q[i] * u.segment<3>(3 * i);
    };
  }

 private:
  bool precomputed_ = false;
  bool useRotations_ = true;
  int period_ = 1;  // solves between factorisations; 0: once
  const RotationFinder* finder_ = nullptr;
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
                                      "SSORPreconditioner, WarpPreconditioner, PrecomputedWarpPreconditioner or a direct "
                                      "solver such as SparseLDLSolver)");
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
      // SOFA rebuilds the preconditioner every update_step solves and keeps it in between; the
      // warp preconditioners turn theirs at every solve and refactorise on their own count.
      const bool rebuild = l.solves++ % updateStep_ == 0 || !precondition || (preconditioner_ && preconditioner_->rebuildsItself());
      if (rebuild) {
        if (preconditioner_) {
          precondition = preconditioner_->build(s, *p.matrix, info.message);
          if (!precondition) {
            info.ok = false;
            return info;
          }
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

std::vector<Eigen::Matrix3d> averageNodeRotations(int nodeCount, const int* elementNodes, int nodesPerElement,
                                                  const Eigen::Matrix3d* elementRotations, int elementCount) {
  std::vector<Eigen::Matrix3d> sum(nodeCount, Eigen::Matrix3d::Zero());
  for (int e = 0; e < elementCount; ++e)
    for (int k = 0; k < nodesPerElement; ++k) sum[elementNodes[e * nodesPerElement + k]] += elementRotations[e];
  for (Eigen::Matrix3d& m : sum) {
    if (m.isZero()) {
      m.setIdentity();
      continue;
    }
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d U = svd.matrixU();
    if ((U * svd.matrixV().transpose()).determinant() < 0) U.col(2) = -U.col(2);
    m = U * svd.matrixV().transpose();
  }
  return sum;
}

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
            "JacobiPreconditioner, BlockJacobiPreconditioner, SSORPreconditioner, WarpPreconditioner or "
            "PrecomputedWarpPreconditioner, or a direct solver (the factorised matrix, as SOFA's AsyncSparseLDLSolver "
            "there), rebuilt every update_step steps.";
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
    s.name = "RotationMatrixSystem";
    s.category = "solver";
    s.doc = "The rotations a WarpPreconditioner turns its factorised matrix with (SOFA's): each node's, averaged from "
            "the elements of the corotational force field in its context, and how often the matrix is factorised "
            "again.";
    s.add(AttrSpec::integer("assemblingRate").def("1").atLeast(1).help(
        "factorise the step's matrix again every this many solves (the WarpPreconditioner's update_step, if longer, "
        "wins)"));
    s.add(AttrSpec::link("rotationFinder").help(
        "the corotational force field whose rotations are used (default: the one in the context)"));
    s.add(AttrSpec::link("mainSystem").help("accepted for SOFA scenes: the matrix factorised is the step's"));
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.add(AttrSpec::boolean("printLog").def("false").help("accepted for SOFA scenes"));
    s.factory = [](BuildContext& c) { return std::make_unique<RotationMatrixSystem>(c); };
    r.add(std::move(s));
  }
  for (const char* name : {"WarpPreconditioner", "PrecomputedWarpPreconditioner"}) {
    const bool precomputed = std::string(name) == "PrecomputedWarpPreconditioner";
    ComponentSpec s;
    s.name = name;
    s.category = "solver";
    s.doc = precomputed
                ? "For PCGLinearSolver: the step's matrix factorised once, at the first solve, and turned at every "
                  "later one with how each node has rotated since: M^-1 = Q A0^-1 Q^T (SOFA's, which stores A0^-1 "
                  "densely; a factorisation gives the same products). A copied or restored state factorises again at "
                  "its first solve, as PrecomputedLinearSolver does."
                : "For PCGLinearSolver: the step's matrix factorised and kept for update_step solves, turned meanwhile "
                  "with how each node has rotated since: M^-1 = Q A0^-1 Q^T, Q the nodes' rotations (from the "
                  "corotational force field in the context) times their transposes at the factorisation. Turned at "
                  "every solve, whatever the PCG's update_step. A copied or restored state factorises again at its "
                  "first solve.";
    s.add(AttrSpec::link("linearSolver").help(
        "the direct solver meant (SparseLDLSolver or an alias); the factorisation is CHOLMOD's LDL^T, made here"));
    s.add(AttrSpec::link("linearSystem").help(
        precomputed ? "accepted for SOFA scenes (PrecomputedMatrixSystem)" : "its RotationMatrixSystem (default: the one in the context)"));
    if (precomputed) {
      s.add(AttrSpec::boolean("use_rotations").def("true").help("turn the factorised matrix with the nodes' rotations"));
      s.add(AttrSpec::boolean("jmjt_twostep").def("true").help("accepted for SOFA scenes (a contact compliance option)"));
      s.add(AttrSpec::boolean("use_file").def("true").help(
          "accepted for SOFA scenes, which cache the dense inverse in a file; the factorisation is made at the first solve"));
      s.add(AttrSpec::boolean("share_matrix").def("true").help("accepted for SOFA scenes"));
      s.add(AttrSpec::real("draw_rotations_scale").def("0").help("accepted for SOFA scenes (drawing)"));
    } else {
      s.add(AttrSpec::integer("update_step").def("1").atLeast(1).help("factorise the step's matrix again every this many solves"));
      s.add(AttrSpec::integer("useRotationFinder").def("0").atLeast(0).atMost(0).help(
          "which rotation finder of the context (only the first, 0, here)"));
    }
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.add(AttrSpec::boolean("printLog").def("false").help("accepted for SOFA scenes"));
    s.factory = [](BuildContext& c) { return std::make_unique<WarpPreconditioner>(c); };
    r.add(std::move(s));
  }
  {
    // Kept as a component (not skipped) so that a PrecomputedWarpPreconditioner's link to it resolves.
    ComponentSpec s;
    s.name = "PrecomputedMatrixSystem";
    s.category = "solver";
    s.doc = "The linear system of a PrecomputedWarpPreconditioner in SOFA scenes, where SOFA keeps the dense inverse; "
            "here the preconditioner keeps its factorisation itself, and this holds nothing.";
    s.add(AttrSpec::string("template").def("").help("SOFA's matrix type; accepted and ignored"));
    s.factory = [](BuildContext& c) { return std::make_unique<Component>(c); };
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
