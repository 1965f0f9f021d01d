// The explicit solvers, as SOFA's. Both evaluate accelerations a = M^-1 f(x, v) with fixed nodes
// projected out; a lumped (diagonal) mass is inverted node by node, a consistent mass matrix is
// solved with the node's linear solver, as SOFA does. No stiffness system is solved, so a step is
// stable only below the fastest mode's period.
// - EulerExplicitSolver: symplectic (semi-implicit) Euler, v <- v + h a, x <- x + h v (new v), or
//   the forward Euler of both, x <- x + h v (old v), v <- v + h a (h < 2 / omega_max, symplectic).
// - RungeKutta4Solver: the classical fourth-order Runge-Kutta step of (x, v)' = (v, a(x, v)),
//   four force evaluations per step (h < 2.8 / omega_max).
#include <memory>

#include "core/Registry.h"
#include "engine/MechanicalSystem.h"
#include "engine/mechanics/MechanicalObject.h"
#include "solvers/ode/OdeCommon.h"

namespace viscera {

namespace {

// What the explicit solvers share: the mechanical system and a = M^-1 f(x, v), projected.
class ExplicitSolver : public Component, public OdeSolver, public Stateful {
 public:
  using Component::Component;
  void init() override {
    if ((rigid_ = RigidBodyIntegrator::forSolver(*this))) return;
    sys_ = std::make_unique<MechanicalSystem>(*this);
    // A consistent mass is not inverted node by node: M a = f is solved.
    if (sys_->consistentMass()) linear_ = findLinearSolver(*this);
    if (linear_ && linear_->needsMatrix()) {
      sys_->prepareAssembly();  // M's pattern is within the stiffness pattern
      M_ = sys_->pattern();
      sys_->addMass(M_, 1.0);
      sys_->constrain(M_);
    }
  }
  // The last accelerations of a consistent mass's solve (the next one starts from them).
  struct Live : ComponentStateOf<Live> {
    Eigen::VectorXd acc;
    void save(StateWriter& out) const override { out.put(acc); }
    void load(StateReader& in) override { in.get(acc); }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }

 protected:
  // The accelerations at (x, v); f receives the forces.
  std::optional<Diverged> acceleration(State& st, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v,
                                       Eigen::Matrix3Xd& f, Eigen::Matrix3Xd& a, double t, double h,
                                       int stepIndex) const {
    sys_->computeForce(st, x, v, f);
    if (linear_) {
      if (auto failed = solveMass(st, f, a, t, h, stepIndex)) return failed;
    } else {
      a = f * sys_->nodeMass().cwiseInverse().asDiagonal();
    }
    sys_->project(a);
    return std::nullopt;
  }

  std::unique_ptr<RigidBodyIntegrator> rigid_;  // set in a rigid body's node
  std::unique_ptr<MechanicalSystem> sys_;

 private:
  // a = M^-1 f with the node's linear solver (fixed nodes projected out).
  std::optional<Diverged> solveMass(State& st, const Eigen::Matrix3Xd& f, Eigen::Matrix3Xd& a, double t, double h,
                                    int stepIndex) const {
    const int n = sys_->nodes();
    LinearProblem problem;
    if (linear_->needsMatrix()) {
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
    Eigen::VectorXd& acc = stateIn<Live>(st).acc;
    if (acc.size() != 3 * n) acc = Eigen::VectorXd::Zero(3 * n);
    const LinearSolveInfo info = linear_->solve(st, problem, Eigen::Map<const Eigen::VectorXd>(b.data(), 3 * n), acc);
    if (!info.ok) {
      Diverged d;
      d.step = stepIndex;
      d.time = t + h;
      d.reason = "linear solver failed on the mass matrix: " + info.message;
      d.object = sys_->state().name();
      return d;
    }
    a = Eigen::Map<const Eigen::Matrix3Xd>(acc.data(), 3, n);
    return std::nullopt;
  }

  LinearSolver* linear_ = nullptr;
  BlockSparseMatrix M_;  // the constrained mass matrix, when the linear solver takes one
};

class EulerExplicitSolver : public ExplicitSolver {
 public:
  using ExplicitSolver::ExplicitSolver;
  void init() override {
    symplectic_ = attrs_.boolean("symplectic");
    ExplicitSolver::init();
    if (rigid_ && !rigid_->idle() && !symplectic_)
      throw error("symplectic", "a rigid body is integrated with the symplectic step only (v first, then the pose)");
  }

  std::optional<Diverged> step(State& st, double t, double h, int stepIndex) const override {
    if (rigid_) return rigid_->step(st, t, h, stepIndex, 0.0);
    MechanicalObject::Live& s = sys_->state().live(st);
    const Eigen::Matrix3Xd x0 = s.x, v0 = s.v;
    Eigen::Matrix3Xd a;
    if (auto failed = acceleration(st, s.x, s.v, s.f, a, t, h, stepIndex)) return failed;
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
  // A force F added over the step (a constraint's correction) changes the velocities by h M^-1 F
  // and, as the symplectic step moves with the new velocity, the positions by h^2 M^-1 F. The
  // forward step moves the positions with the old velocity: nothing corrects them within it.
  std::optional<StepResponse> stepResponse(double h) const override {
    if (!symplectic_) return std::nullopt;
    return StepResponse{1.0, 0.0, h * h, h};
  }

 private:
  bool symplectic_ = true;
};

class RungeKutta4Solver : public ExplicitSolver {
 public:
  using ExplicitSolver::ExplicitSolver;
  void init() override {
    ExplicitSolver::init();
    if (rigid_ && !rigid_->idle())
      throw error("does not integrate rigid bodies; use EulerImplicitSolver or EulerExplicitSolver in the node of '" +
                  rigid_->bodies().front()->name() + "'");
  }

  std::optional<Diverged> step(State& st, double t, double h, int stepIndex) const override {
    if (rigid_) return std::nullopt;  // a held or driven body
    MechanicalObject::Live& s = sys_->state().live(st);
    const Eigen::Matrix3Xd x0 = s.x, v0 = s.v;
    // Stage k: velocity v_k (the slope of x) and acceleration a_k (the slope of v) at the point
    // reached from the start with the previous stage's slopes.
    Eigen::Matrix3Xd v1 = v0, a1, a2, a3, a4, f;
    if (auto failed = acceleration(st, x0, v1, s.f, a1, t, h, stepIndex)) return failed;
    const Eigen::Matrix3Xd v2 = v0 + 0.5 * h * a1;
    if (auto failed = acceleration(st, x0 + 0.5 * h * v1, v2, f, a2, t, h, stepIndex)) return failed;
    const Eigen::Matrix3Xd v3 = v0 + 0.5 * h * a2;
    if (auto failed = acceleration(st, x0 + 0.5 * h * v2, v3, f, a3, t, h, stepIndex)) return failed;
    const Eigen::Matrix3Xd v4 = v0 + h * a3;
    if (auto failed = acceleration(st, x0 + h * v3, v4, f, a4, t, h, stepIndex)) return failed;
    s.x = x0 + (h / 6) * (v1 + 2 * v2 + 2 * v3 + v4);
    s.v = v0 + (h / 6) * (a1 + 2 * a2 + 2 * a3 + a4);
    if (auto bad = sys_->check(s.x, s.v, stepIndex, t + h)) {
      s.x = x0;
      s.v = v0;
      return bad;
    }
    return std::nullopt;
  }
};

}  // namespace

void registerExplicitSolvers(Registry& r) {
  {
    ComponentSpec s;
    s.name = "RungeKutta4Solver";
    s.category = "solver";
    s.doc = "Classical fourth-order Runge-Kutta on positions and velocities, as SOFA's: four force evaluations a step, "
            "error O(h^4) per unit time. Masses as EulerExplicitSolver (a consistent mass is solved with the node's "
            "linear solver). Stable only for a step below about 2.8 / omega_max.";
    s.factory = [](BuildContext& c) { return std::make_unique<RungeKutta4Solver>(c); };
    r.add(std::move(s));
  }
  ComponentSpec s;
  s.name = "EulerExplicitSolver";
  s.aliases = {"ExplicitEuler", "EulerSolver"};
  s.category = "solver";
  s.doc = "Explicit Euler as SOFA's: symplectic (velocity first, then positions with the new velocity) by default, "
          "else forward Euler. A lumped mass is inverted node by node; a consistent mass (MeshMatrixMass) is solved "
          "with the linear solver of the node. Stable only for a step below the period of the stiffest mode. The "
          "symplectic step takes constraint corrections (FreeMotionAnimationLoop): a force F over the step moves "
          "the body by dt^2 M^-1 F.";
  s.add(AttrSpec::boolean("symplectic").def("true").help("update velocities first and move with the new velocity"));
  s.factory = [](BuildContext& c) { return std::make_unique<EulerExplicitSolver>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
