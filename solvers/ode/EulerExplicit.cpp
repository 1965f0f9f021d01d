// EulerExplicitSolver as SOFA's, for a lumped (diagonal) mass: a = M^-1 f(x, v) with fixed nodes
// projected out, then either symplectic (semi-implicit) Euler, v <- v + h a, x <- x + h v (new v),
// or the forward Euler of both, x <- x + h v (old v), v <- v + h a. No linear system is solved:
// the step is stable only below the fastest mode's period (h < 2 / omega_max for symplectic).
// With a consistent mass matrix, M a = f is solved by the node's linear solver, as SOFA does.
#include <memory>

#include "core/Registry.h"
#include "engine/MechanicalSystem.h"
#include "engine/mechanics/MechanicalObject.h"
#include "solvers/ode/OdeCommon.h"

namespace viscera {

namespace {

class EulerExplicitSolver : public Component, public OdeSolver {
 public:
  using Component::Component;
  void init() override {
    symplectic_ = attrs_.boolean("symplectic");
    if ((idle_ = idleInRigidNode(*this))) return;
    sys_ = std::make_unique<MechanicalSystem>(*this);
    // A consistent mass is not inverted node by node: M a = f is solved.
    if (sys_->consistentMass()) linear_ = findLinearSolver(*this);
  }

  std::optional<Diverged> step(double t, double h, int stepIndex) override {
    if (idle_) return std::nullopt;
    MechanicalObject& s = sys_->state();
    const Eigen::Matrix3Xd x0 = s.x, v0 = s.v;
    sys_->computeForce(s.x, s.v, s.f);
    Eigen::Matrix3Xd a;
    if (linear_) {
      if (auto failed = solveMass(s.f, a, t, h, stepIndex)) return failed;
    } else {
      a = s.f * sys_->nodeMass().cwiseInverse().asDiagonal();
    }
    sys_->project(a);
    if (symplectic_) {
      s.v += h * a;
      s.x += h * s.v;
    } else {
      s.x += h * s.v;
      s.v += h * a;
    }
    if (auto bad = sys_->check(s.x, s.v, stepIndex, t + h)) {
      s.x = x0;
      s.v = v0;
      return bad;
    }
    return std::nullopt;
  }

 private:
  // a = M^-1 f with the node's linear solver (fixed nodes projected out).
  std::optional<Diverged> solveMass(const Eigen::Matrix3Xd& f, Eigen::Matrix3Xd& a, double t, double h, int stepIndex) {
    const int n = sys_->nodes();
    LinearProblem problem;
    if (linear_->needsMatrix()) {
      sys_->assembleStiffness(M_);  // for the pattern; the values are replaced by M's
      M_.setZero();
      sys_->addMass(M_, 1.0);
      M_.constrainNodes(sys_->fixedNodes());
      problem.matrix = &M_;
      problem.apply = [this](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
        q.resize(p.size());
        M_.multiply(p, q);
      };
    } else {
      problem.apply = [this, n](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
        const Eigen::Map<const Eigen::Matrix3Xd> P(p.data(), 3, n);
        Eigen::Matrix3Xd Q = Eigen::Matrix3Xd::Zero(3, n);
        sys_->addMdx(P, Q, 1.0);
        sys_->project(Q);
        q = Eigen::Map<const Eigen::VectorXd>(Q.data(), 3 * n);
      };
    }
    Eigen::Matrix3Xd b = f;
    sys_->project(b);
    if (acc_.size() != 3 * n) acc_ = Eigen::VectorXd::Zero(3 * n);
    const LinearSolveInfo info = linear_->solve(problem, Eigen::Map<const Eigen::VectorXd>(b.data(), 3 * n), acc_);
    if (!info.ok) {
      Diverged d;
      d.step = stepIndex;
      d.time = t + h;
      d.reason = "linear solver failed on the mass matrix: " + info.message;
      d.object = sys_->state().name();
      return d;
    }
    a = Eigen::Map<const Eigen::Matrix3Xd>(acc_.data(), 3, n);
    return std::nullopt;
  }

  bool symplectic_ = true, idle_ = false;
  std::unique_ptr<MechanicalSystem> sys_;
  LinearSolver* linear_ = nullptr;
  BlockSparseMatrix M_;
  Eigen::VectorXd acc_;
};

}  // namespace

void registerEulerExplicit(Registry& r) {
  ComponentSpec s;
  s.name = "EulerExplicitSolver";
  s.aliases = {"ExplicitEuler", "EulerSolver"};
  s.category = "solver";
  s.doc = "Explicit Euler as SOFA's: symplectic (velocity first, then positions with the new velocity) by default, "
          "else forward Euler. A lumped mass is inverted node by node; a consistent mass (MeshMatrixMass) is solved "
          "with the linear solver of the node. Stable only for a step below the period of the stiffest mode.";
  s.add(AttrSpec::boolean("symplectic").def("true").help("update velocities first and move with the new velocity"));
  s.factory = [](BuildContext& c) { return std::make_unique<EulerExplicitSolver>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
