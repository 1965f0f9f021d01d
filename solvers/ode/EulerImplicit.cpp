// EulerImplicitSolver in SOFA's formulation (one linear solve per step), with a = h (or h / 2 with
// trapezoidalScheme):
//   [(1 + a rM) M - a (a + rK) K] dv = h [f(x, v) + (a + rK) K v - rM M v],
//   where contact stiffness (not Rayleigh damped) enters with a in place of a + rK;
//   v <- v + dv, x <- x + h v; fixed nodes are projected out of the system.
// firstOrder (SOFA's first-order system x' = v = M^-1 f, no Rayleigh damping):
//   (M - a K) v_new = f(x, v),  x <- x + h v_new.
// In the node of a rigid body it integrates the body (RigidDynamics.h).
#include <cmath>
#include <memory>

#include "engine/MechanicalSystem.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidDynamics.h"
#include "solvers/linear/LinearSolver.h"
#include "solvers/ode/OdeCommon.h"

namespace viscera {

namespace {

class EulerImplicitSolver : public Component, public OdeSolver, public Stateful {
 public:
  using Component::Component;
  // The last velocity change (the next linear solve starts from it) and its iteration count; the
  // step's matrix is workspace.
  struct Live : ComponentStateOf<Live> {
    Eigen::VectorXd dv;
    int lastIterations = 0;
    BlockSparseMatrix A;
    Eigen::Matrix3Xd start;  // positions at the start of the last step (the system's linearisation)
    void save(StateWriter& out) const override {
      out.put(dv);
      out.put(lastIterations);
    }
    void load(StateReader& in) override {
      in.get(dv);
      in.get(lastIterations);
    }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  void init() override {
    rM_ = attrs_.real("rayleighMass");
    rK_ = attrs_.real("rayleighStiffness");
    firstOrder_ = attrs_.boolean("firstOrder");
    tr_ = attrs_.boolean("trapezoidalScheme") ? 0.5 : 1.0;
    if (firstOrder_ && (rM_ != 0 || rK_ != 0)) {
      scene().addNote(loc().str() + ": note: " + typeName() + " '" + name() + "': the first-order scheme has no Rayleigh "
                      "damping; rayleighMass and rayleighStiffness are not used (as in SOFA)");
      rM_ = rK_ = 0;
    }
    vdamping_ = attrs_.real("vdamping");
    if ((rigid_ = RigidBodyIntegrator::forSolver(*this))) return;
    sys_ = std::make_unique<MechanicalSystem>(*this);
    linear_ = findLinearSolver(*this);
    if (linear_->needsMatrix()) sys_->prepareAssembly();
  }

  std::optional<Diverged> step(State& st, double t, double h, int stepIndex) const override {
    if (rigid_) return rigid_->step(st, t, h, stepIndex, rM_);
    Live& l = stateIn<Live>(st);
    MechanicalObject::Live& s = sys_->state().live(st);
    const int n = sys_->nodes();
    l.start = s.x;
    const Eigen::Matrix3Xd& x0 = l.start;
    const Eigen::Matrix3Xd v0 = s.v;
    Eigen::Matrix3Xd& f = s.f;
    sys_->computeForce(st, s.x, s.v, f);

    const double a = tr_ * h;
    const double mFact = firstOrder_ ? 1.0 : 1.0 + a * rM_;
    const double kFact = firstOrder_ ? -a : -a * (a + rK_);
    // Contact stiffness is not Rayleigh damped: its K enters as -a^2 K (and a K v), not
    // -a (a + rK) K, hence the scale a / (a + rK) on the undamped fields.
    const double uScale = a / (a + rK_);
    Eigen::Matrix3Xd Kv = Eigen::Matrix3Xd::Zero(3, n);
    LinearProblem problem;
    BlockSparseMatrix& A = l.A;
    if (linear_->needsMatrix()) {
      // A = kFact K + mFact M, constrained; K v read from kFact K before the mass joins it.
      sys_->assembleStiffness(st, A, uScale, kFact != 0 ? kFact : 1.0);
      A.multiply(Eigen::Map<const Eigen::VectorXd>(s.v.data(), 3 * n), Eigen::Map<Eigen::VectorXd>(Kv.data(), 3 * n));
      if (kFact != 0) Kv *= 1.0 / kFact;
      else A.setZero();
      sys_->addMass(A, mFact);
      sys_->constrain(A);
      useAssembled(problem, A);
    } else {
      sys_->addKdx(st, s.v, Kv, 1.0, uScale);
      problem.apply = [this, &st, n, mFact, kFact, uScale](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
        const Eigen::Map<const Eigen::Matrix3Xd> P(p.data(), 3, n);
        Eigen::Matrix3Xd Q = Eigen::Matrix3Xd::Zero(3, n);
        sys_->addMdx(P, Q, mFact);
        sys_->addKdx(st, P, Q, kFact, uScale);
        sys_->project(Q);
        q = Eigen::Map<const Eigen::VectorXd>(Q.data(), 3 * n);
      };
    }
    Eigen::Matrix3Xd Mv = Eigen::Matrix3Xd::Zero(3, n);
    if (rM_ != 0) sys_->addMdx(s.v, Mv, 1.0);
    // First order: the unknown is the new velocity itself.
    Eigen::Matrix3Xd b = firstOrder_ ? Eigen::Matrix3Xd(f) : Eigen::Matrix3Xd(h * (f + (a + rK_) * Kv - rM_ * Mv));
    sys_->project(b);
    Eigen::VectorXd bv = Eigen::Map<const Eigen::VectorXd>(b.data(), 3 * n);
    Eigen::VectorXd& dv = l.dv;
    if (dv.size() != 3 * n) dv = Eigen::VectorXd::Zero(3 * n);
    LinearSolveInfo info = linear_->solve(st, problem, bv, dv);
    l.lastIterations = info.iterations;
    if (!info.ok) {
      Diverged d;
      d.step = stepIndex;
      d.time = t + h;
      d.reason = "linear solver failed: " + info.message;
      d.object = sys_->state().name();
      return d;
    }
    if (firstOrder_) s.v = Eigen::Map<const Eigen::Matrix3Xd>(dv.data(), 3, n);
    else s.v += Eigen::Map<const Eigen::Matrix3Xd>(dv.data(), 3, n);
    if (vdamping_ > 0) s.v *= std::exp(-h * vdamping_);
    s.x += h * s.v;
    if (auto bad = sys_->check(s.x, s.v, stepIndex, t + h)) {
      // Keep the last good state: nothing bad reaches the outputs.
      s.x = x0;
      s.v = v0;
      return bad;
    }
    return std::nullopt;
  }
  int lastLinearIterations(const State& s) const override { return stateIn<Live>(s).lastIterations; }
  const Eigen::Matrix3Xd* linearisedAt(const State& s) const override {
    const Live& l = stateIn<Live>(s);
    return rigid_ || l.start.cols() == 0 ? nullptr : &l.start;
  }
  // A dv = h F, x += h v: positions move by h^2 A^-1 F, velocities by h A^-1 F (first order:
  // A v = F, so h A^-1 F and A^-1 F).
  std::optional<StepResponse> stepResponse(double h) const override {
    // Rigid bodies: (1 + h rM) M dV = h F, p += h v (no stiffness of their own).
    if (rigid_) return StepResponse{1.0 + h * rM_, 0.0, h * h, h};
    const double a = tr_ * h;
    if (firstOrder_) return StepResponse{1.0, -a, h, 1.0};
    return StepResponse{1.0 + a * rM_, -a * (a + rK_), h * h, h};
  }

 private:
  double rM_ = 0, rK_ = 0, vdamping_ = 0;
  double tr_ = 1.0;  // 1/2 with the trapezoidal scheme
  bool firstOrder_ = false;
  std::unique_ptr<RigidBodyIntegrator> rigid_;  // set in a rigid body's node
  std::unique_ptr<MechanicalSystem> sys_;
  LinearSolver* linear_ = nullptr;
};

}  // namespace

void useAssembled(LinearProblem& problem, const BlockSparseMatrix& A) {
  problem.matrix = &A;
  problem.apply = [&A](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
    q.resize(p.size());
    A.multiply(p, q);
  };
  const int n = A.blockRows();
  problem.diagonal.resize(3 * n);
  for (int i = 0; i < n; ++i) problem.diagonal.segment<3>(3 * i) = A.block(A.diagonalSlot(i)).diagonal();
}

LinearSolveInfo solveStepSystem(const MechanicalSystem& sys, LinearSolver& linear, State& st, BlockSparseMatrix& A,
                                double mFact, double kFact, double uScale, const Eigen::VectorXd& rhs, Eigen::VectorXd& x) {
  const int n = sys.nodes();
  LinearProblem problem;
  if (linear.needsMatrix()) {
    sys.assembleStiffness(st, A, uScale, kFact != 0 ? kFact : 1.0);
    if (kFact == 0) A.setZero();
    sys.addMass(A, mFact);
    sys.constrain(A);
    useAssembled(problem, A);
  } else {
    problem.apply = [&sys, &st, n, mFact, kFact, uScale](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
      const Eigen::Map<const Eigen::Matrix3Xd> P(p.data(), 3, n);
      Eigen::Matrix3Xd Q = Eigen::Matrix3Xd::Zero(3, n);
      sys.addMdx(P, Q, mFact);
      if (kFact != 0) sys.addKdx(st, P, Q, kFact, uScale);
      sys.project(Q);
      q = Eigen::Map<const Eigen::VectorXd>(Q.data(), 3 * n);
    };
  }
  return linear.solve(st, problem, rhs, x);
}

LinearSolver* findLinearSolver(Component& c) {
  LinearSolver* l = c.node().find<LinearSolver>();
  if (!l) throw c.error("needs a linear solver in its node (CGLinearSolver or SparseLDLSolver)");
  c.scene().initComponent(dynamic_cast<Component&>(*l));
  return l;
}

void registerEulerImplicit(Registry& r) {
  ComponentSpec s;
  s.name = "EulerImplicitSolver";
  s.aliases = {"EulerImplicit"};
  s.category = "solver";
  s.doc = "Implicit (backward) Euler with Rayleigh damping, linearised: one linear solve per step (SOFA's "
          "formulation). The linear solver is the one in the same node.";
  s.add(AttrSpec::real("rayleighStiffness").def("0").atLeast(0).help("Rayleigh damping proportional to stiffness"));
  s.add(AttrSpec::real("rayleighMass").def("0").atLeast(0).help("Rayleigh damping proportional to mass"));
  s.add(AttrSpec::boolean("firstOrder").def("false").help(
      "SOFA's first-order scheme: (M - dt K) v = f, then x += dt v (velocities carry nothing over; no Rayleigh damping)"));
  s.add(AttrSpec::boolean("trapezoidalScheme").def("false").help(
      "SOFA's trapezoidal variant: the matrix and the K v term with dt / 2 in place of dt"));
  s.add(AttrSpec::real("vdamping").def("0").atLeast(0).unit(Dimension::frequency()).help("velocity damping: v *= exp(-dt vdamping)"));
  s.factory = [](BuildContext& c) { return std::make_unique<EulerImplicitSolver>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
