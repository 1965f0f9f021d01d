// BDFOdeSolver: SOFA's velocity-based backward differentiation formula of order k, with Newton's
// method (the NewtonRaphsonSolver in the node gives its settings). With the last k steps' positions
// and velocities, a_0 y_new + sum_j a_j y_j = h b y'_new for y = x (y' = v) and y = v
// (y' = M^-1 f), the a_j and b from the derivative of the Lagrange polynomial through the time
// samples (the classic BDF coefficients at a fixed step). The order rises from 1 as the history
// fills. Newton on the velocity: with c = h b, x = x^ + c v and
//   r(v) = M (v - v^) - c [f(x, v) - rM M v + rK K v]   (K = df/dx),
//   [(1 + c rM) M - c (c + rK) K] dv = -r,
// where x^ and v^ are -sum a_j / a_0 of the history. Fixed nodes are projected out, and the
// directions the projective constraints hold keep the state the step starts from (drivers and
// corrections may have set it): the latest history entry is that state.
#include <algorithm>
#include <cmath>
#include <deque>
#include <memory>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/MechanicalSystem.h"
#include "engine/mechanics/MechanicalObject.h"
#include "solvers/linear/LinearSolver.h"
#include "solvers/ode/OdeCommon.h"

namespace viscera {

namespace {

// Coefficients of the BDF through time samples t_0 < ... < t_k (the last the new one): a_j such that
// sum a_j y_j = h y'(t_k) for the interpolating polynomial, scaled to a_k = 1, and b = 1 / (its a_k).
void bdfCoefficients(const std::vector<double>& t, std::vector<double>& a, double& b) {
  const size_t k = t.size() - 1;
  a.assign(k + 1, 0.0);
  for (size_t j = 0; j <= k; ++j)
    for (size_t i = 0; i <= k; ++i) {
      if (i == j) continue;
      double product = 1;
      for (size_t m = 0; m <= k; ++m)
        if (m != i && m != j) product *= (t[k] - t[m]) / (t[j] - t[m]);
      a[j] += product / (t[j] - t[i]);
    }
  const double h = t[k] - t[k - 1];
  for (double& v : a) v *= h;
  for (size_t j = 0; j < k; ++j) a[j] /= a[k];
  b = 1 / a[k];
  a[k] = 1;
}

class BDFOdeSolver : public Component, public OdeSolver, public Stateful {
 public:
  using Component::Component;
  // The history (most recent last): times, positions and velocities of the last `order` steps.
  struct Live : ComponentStateOf<Live> {
    std::deque<double> t;
    std::deque<Eigen::Matrix3Xd> x, v;
    int lastIterations = 0;
    BlockSparseMatrix A;
    void save(StateWriter& out) const override {
      out.put(std::vector<double>(t.begin(), t.end()));
      out.put(std::vector<Eigen::Matrix3Xd>(x.begin(), x.end()));
      out.put(std::vector<Eigen::Matrix3Xd>(v.begin(), v.end()));
      out.put(lastIterations);
    }
    void load(StateReader& in) override {
      std::vector<double> tt;
      std::vector<Eigen::Matrix3Xd> xx, vv;
      in.get(tt);
      in.get(xx);
      in.get(vv);
      in.get(lastIterations);
      t.assign(tt.begin(), tt.end());
      x.assign(xx.begin(), xx.end());
      v.assign(vv.begin(), vv.end());
    }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  void init() override {
    order_ = static_cast<int>(attrs_.integer("order"));
    rM_ = attrs_.real("rayleighMass");
    rK_ = attrs_.real("rayleighStiffness");
    const Component* newton = findNewtonRaphsonSolver(*this);
    if (!newton) throw error("needs a NewtonRaphsonSolver in its node (its Newton iterations solve each step)");
    for (const auto& c : node().components())
      if (c->typeName() == "NewtonRaphsonSolver" && c.get() != newton)
        throw error("finds two NewtonRaphsonSolver in its node ('" + newton->name() + "', '" + c->name() + "'); keep one");
    newton_ = newtonSettings(*newton);
    sys_ = std::make_unique<MechanicalSystem>(*this);
    linear_ = findLinearSolver(*this);
    if (linear_->needsMatrix()) sys_->prepareAssembly();
  }

  std::optional<Diverged> step(State& st, double t, double h, int stepIndex) const override {
    Live& l = stateIn<Live>(st);
    MechanicalObject::Live& s = sys_->state().live(st);
    const int n = sys_->nodes();
    if (l.t.empty()) {  // the history starts from the initial state
      l.t.push_back(t);
      l.x.push_back(s.x);
      l.v.push_back(s.v);
    } else {
      // What drivers, contact constraints and corrections did since the last solve counts.
      l.x.back() = s.x;
      l.v.back() = s.v;
    }
    // The samples: the history and the new time.
    std::vector<double> samples(l.t.begin(), l.t.end());
    samples.push_back(t + h);
    std::vector<double> a;
    double b;
    bdfCoefficients(samples, a, b);
    const double c = h * b;
    Eigen::Matrix3Xd xHat = Eigen::Matrix3Xd::Zero(3, n), vHat = Eigen::Matrix3Xd::Zero(3, n);
    for (size_t j = 0; j + 1 < samples.size(); ++j) {
      xHat -= a[j] * l.x[j];
      vHat -= a[j] * l.v[j];
    }
    // Held directions stay where the step starts (their velocity is projected to zero).
    Eigen::Matrix3Xd drift = xHat - s.x;
    sys_->project(drift);
    xHat = s.x + drift;
    const Eigen::Matrix3Xd x0 = s.x, v0 = s.v;
    Eigen::Matrix3Xd v = s.v;  // the initial guess: the last velocity
    sys_->project(v);
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
    // r(v), linearising the force fields at x(v).
    auto residual = [&](const Eigen::Matrix3Xd& vel) {
      const Eigen::Matrix3Xd x = xHat + c * vel;
      sys_->computeForce(st, x, vel, s.f);
      Eigen::Matrix3Xd damping = Eigen::Matrix3Xd::Zero(3, n);
      if (rM_ != 0) sys_->addMdx(vel, damping, rM_);
      if (rK_ != 0) sys_->addKdx(st, vel, damping, -rK_, 0.0);  // -rK K v: K = df/dx is negative
      Eigen::Matrix3Xd r = Eigen::Matrix3Xd::Zero(3, n);
      sys_->addMdx(vel - vHat, r, 1.0);
      r -= c * (s.f - damping);
      sys_->project(r);
      return r;
    };
    Eigen::Matrix3Xd r = residual(v);
    const double r0 = r.norm();
    double previous = r0;
    l.lastIterations = 0;
    for (int it = 0; it < newton_.iterations; ++it) {
      const double rn = r.norm();
      if (rn <= newton_.absResidual || (r0 > 0 && rn <= newton_.relInitial * r0) ||
          (it > 0 && newton_.relSuccessive > 0 && rn <= newton_.relSuccessive * previous))
        break;
      previous = rn;
      Eigen::VectorXd dv = Eigen::VectorXd::Zero(3 * n);
      const Eigen::VectorXd rhs = -Eigen::Map<const Eigen::VectorXd>(r.data(), 3 * n);
      if (auto bad = solveTangent(st, l, c, rhs, dv)) return fail(*bad);
      Eigen::Matrix3Xd step = Eigen::Map<const Eigen::Matrix3Xd>(dv.data(), 3, n);
      // Backtracking: the step shrinks until the residual falls; if it never does, the trial
      // with the smallest residual is taken.
      double scale = 1, bestScale = 1, bestNorm = -1;
      for (int k = 0; k < std::max(newton_.lineSearch, 1); ++k, scale *= newton_.lineSearchFactor) {
        const double tn = residual(v + scale * step).norm();
        if (bestNorm < 0 || tn < bestNorm) bestNorm = tn, bestScale = scale;
        if (tn < rn) break;
      }
      step *= bestScale;
      v += step;
      r = residual(v);
      l.lastIterations = it + 1;
      const double moved = step.norm();
      if (moved <= newton_.absCorrection || (newton_.relCorrection > 0 && moved <= newton_.relCorrection * v.norm())) break;
    }
    s.v = v;
    s.x = xHat + c * v;
    if (!s.x.allFinite() || !s.v.allFinite()) return fail("non-finite state after the Newton iterations");
    if (auto bad = sys_->check(s.x, s.v, stepIndex, t + h)) {
      s.x = x0;
      s.v = v0;
      return bad;
    }
    // The history keeps the last `order` states.
    l.t.push_back(t + h);
    l.x.push_back(s.x);
    l.v.push_back(s.v);
    while (static_cast<int>(l.t.size()) > order_) {
      l.t.pop_front();
      l.x.pop_front();
      l.v.pop_front();
    }
    return std::nullopt;
  }
  int lastLinearIterations(const State& s) const override { return stateIn<Live>(s).lastIterations; }

 private:
  // [(1 + c rM) M - c (c + rK) K] dv = rhs at the last linearisation; a message on failure.
  std::optional<std::string> solveTangent(State& st, Live& l, double c, const Eigen::VectorXd& rhs, Eigen::VectorXd& dv) const {
    const LinearSolveInfo info =
        solveStepSystem(*sys_, *linear_, st, l.A, 1 + c * rM_, -c * (c + rK_), c / (c + rK_), rhs, dv);
    if (!info.ok) return "linear solver failed: " + info.message;
    if (!dv.allFinite()) return std::string("non-finite Newton correction");
    return std::nullopt;
  }

  int order_ = 1;
  double rM_ = 0, rK_ = 0;
  NewtonSettings newton_;
  std::unique_ptr<MechanicalSystem> sys_;
  LinearSolver* linear_ = nullptr;
};

}  // namespace

void registerBDFOdeSolver(Registry& r) {
  ComponentSpec s;
  s.name = "BDFOdeSolver";
  s.category = "solver";
  s.doc = "SOFA's backward differentiation formula of order `order` (velocity-based: the same formula for positions and "
          "velocities), each step solved by Newton's method with the settings of the NewtonRaphsonSolver in its node, "
          "and Rayleigh damping. The order rises from 1 as the history of steps fills. Orders above 6 are not "
          "zero-stable.";
  s.add(AttrSpec::integer("order").def("1").atLeast(1).atMost(6).help("the number of past steps the formula uses"));
  s.add(AttrSpec::real("rayleighMass").def("0").atLeast(0).help("Rayleigh damping proportional to mass"));
  s.add(AttrSpec::real("rayleighStiffness").def("0").atLeast(0).help("Rayleigh damping proportional to stiffness"));
  s.factory = [](BuildContext& c) { return std::make_unique<BDFOdeSolver>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
