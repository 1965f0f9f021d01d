// NewmarkImplicitSolver: the Newmark-beta scheme (SOFA's name and parameters; beta = 1/4, gamma =
// 1/2 by default: the average acceleration, which keeps a linear undamped system's energy), with
// Rayleigh damping, linearised as SOFA's implicit solvers are: one linear solve per step for the
// new acceleration a,
//   x = x~ + beta h^2 a,  x~ = x + h v + (1/2 - beta) h^2 a_old,
//   v = v~ + gamma h a,   v~ = v + (1 - gamma) h a_old,
//   [(1 + gamma h rM) M - (beta h^2 + gamma h rK) K] a = f + K (x~ - x) - rM M v~ + rK K v~,
// with f and K = df/dx at the step start. The first acceleration solves M a = f - rM M v + rK K v
// at the start.
#include <memory>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/MechanicalSystem.h"
#include "engine/mechanics/MechanicalObject.h"
#include "solvers/linear/LinearSolver.h"
#include "solvers/ode/OdeCommon.h"

namespace viscera {

namespace {

class NewmarkImplicitSolver : public Component, public OdeSolver, public Stateful {
 public:
  using Component::Component;
  // The last acceleration (the scheme carries it), whether it is known yet, and workspace.
  struct Live : ComponentStateOf<Live> {
    Eigen::Matrix3Xd a;
    bool started = false;
    int lastIterations = 0;
    BlockSparseMatrix A;
    void save(StateWriter& out) const override {
      out.put(a);
      out.put(started);
      out.put(lastIterations);
    }
    void load(StateReader& in) override {
      in.get(a);
      in.get(started);
      in.get(lastIterations);
    }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  void init() override {
    rM_ = attrs_.real("rayleighMass");
    rK_ = attrs_.real("rayleighStiffness");
    beta_ = attrs_.real("beta");
    gamma_ = attrs_.real("gamma");
    sys_ = std::make_unique<MechanicalSystem>(*this);
    linear_ = findLinearSolver(*this);
    if (linear_->needsMatrix()) sys_->prepareAssembly();
  }

  std::optional<Diverged> step(State& st, double t, double h, int stepIndex) const override {
    Live& l = stateIn<Live>(st);
    MechanicalObject::Live& s = sys_->state().live(st);
    const int n = sys_->nodes();
    const Eigen::Matrix3Xd x0 = s.x, v0 = s.v;
    auto fail = [&](const std::string& why) {
      s.x = x0;
      s.v = v0;
      Diverged d;
      d.step = stepIndex;
      d.time = t + h;
      d.reason = why;
      d.object = sys_->state().name();
      return d;
    };
    sys_->computeForce(st, s.x, s.v, s.f);
    // Rayleigh damping at v: -rM M v + rK K v (K = df/dx).
    auto damping = [&](const Eigen::Matrix3Xd& v) {
      Eigen::Matrix3Xd d = Eigen::Matrix3Xd::Zero(3, n);
      if (rM_ != 0) sys_->addMdx(v, d, -rM_);
      if (rK_ != 0) sys_->addKdx(st, v, d, rK_, 0.0);
      return d;
    };
    if (!l.started) {
      // The starting acceleration: M a = f - rM M v + rK K v.
      Eigen::Matrix3Xd rhs = s.f + damping(s.v);
      sys_->project(rhs);
      Eigen::VectorXd a = Eigen::VectorXd::Zero(3 * n);
      if (auto bad = solve(st, l, 1.0, 0.0, 1.0, Eigen::Map<const Eigen::VectorXd>(rhs.data(), 3 * n), a)) return fail(*bad);
      l.a = Eigen::Map<const Eigen::Matrix3Xd>(a.data(), 3, n);
      l.started = true;
    }
    const Eigen::Matrix3Xd xPred = s.x + h * s.v + ((0.5 - beta_) * h * h) * l.a;
    const Eigen::Matrix3Xd vPred = s.v + ((1 - gamma_) * h) * l.a;
    Eigen::Matrix3Xd rhs = s.f + damping(vPred);
    sys_->addKdx(st, xPred - s.x, rhs, 1.0);
    sys_->project(rhs);
    const double mFact = 1 + gamma_ * h * rM_, kFact = -(beta_ * h * h + gamma_ * h * rK_);
    const double uScale = beta_ * h * h / (beta_ * h * h + gamma_ * h * rK_);  // contact: no Rayleigh damping
    Eigen::VectorXd a = Eigen::Map<const Eigen::VectorXd>(l.a.data(), 3 * n);
    if (auto bad = solve(st, l, mFact, kFact, uScale, Eigen::Map<const Eigen::VectorXd>(rhs.data(), 3 * n), a)) return fail(*bad);
    const Eigen::Map<const Eigen::Matrix3Xd> acc(a.data(), 3, n);
    s.x = xPred + (beta_ * h * h) * acc;
    s.v = vPred + (gamma_ * h) * acc;
    if (auto bad = sys_->check(s.x, s.v, stepIndex, t + h)) {
      s.x = x0;
      s.v = v0;
      return bad;
    }
    l.a = acc;  // only a good step's acceleration is carried on
    return std::nullopt;
  }
  int lastLinearIterations(const State& s) const override { return stateIn<Live>(s).lastIterations; }

 private:
  // (mFact M + kFact (K_damped + uScale K_undamped)) a = rhs at the last linearisation.
  std::optional<std::string> solve(State& st, Live& l, double mFact, double kFact, double uScale, const Eigen::VectorXd& rhs,
                                   Eigen::VectorXd& a) const {
    const LinearSolveInfo info = solveStepSystem(*sys_, *linear_, st, l.A, mFact, kFact, uScale, rhs, a);
    l.lastIterations = info.iterations;
    if (!info.ok) return "linear solver failed: " + info.message;
    if (!a.allFinite()) return std::string("non-finite acceleration");
    return std::nullopt;
  }

  double rM_ = 0, rK_ = 0, beta_ = 0.25, gamma_ = 0.5;
  std::unique_ptr<MechanicalSystem> sys_;
  LinearSolver* linear_ = nullptr;
};

}  // namespace

void registerNewmarkImplicitSolver(Registry& r) {
  ComponentSpec s;
  s.name = "NewmarkImplicitSolver";
  s.category = "solver";
  s.doc = "The Newmark-beta scheme (SOFA's NewmarkImplicitSolver), linearised: one linear solve per step for the new "
          "acceleration with the node's linear solver, and Rayleigh damping. beta 1/4 and gamma 1/2 (the default, the "
          "average acceleration) keep the energy of a linear undamped system; gamma above 1/2 damps.";
  s.add(AttrSpec::real("rayleighStiffness").def("0").atLeast(0).help("Rayleigh damping proportional to stiffness"));
  s.add(AttrSpec::real("rayleighMass").def("0").atLeast(0).help("Rayleigh damping proportional to mass"));
  s.add(AttrSpec::real("beta").def("0.25").above(0).atMost(0.5).help("Newmark's beta"));
  s.add(AttrSpec::real("gamma").def("0.5").atLeast(0.5).atMost(1).help("Newmark's gamma"));
  s.factory = [](BuildContext& c) { return std::make_unique<NewmarkImplicitSolver>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
