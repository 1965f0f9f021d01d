// StaticSolver: Newton's method on f(x) = 0 at each step (quasi-static loading). With the exact
// tangent (default) the corotational stiffness is not symmetric, so the Newton system is solved
// with a sparse LU; otherwise the scene's linear solver solves with SOFA's symmetric stiffness.
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <memory>

#include "engine/MechanicalSystem.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "solvers/ode/OdeCommon.h"

namespace viscera {

namespace {

Eigen::SparseMatrix<double> toSparse(const BlockSparseMatrix& A) {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(9 * A.nonZeroBlocks());
  for (int i = 0; i < A.blockRows(); ++i)
    for (int s = A.rowStart()[i]; s < A.rowStart()[i + 1]; ++s) {
      const auto B = A.block(s);
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          if (B(a, b) != 0.0) t.emplace_back(3 * i + a, 3 * A.cols()[s] + b, B(a, b));
    }
  Eigen::SparseMatrix<double> M(A.rows(), A.rows());
  M.setFromTriplets(t.begin(), t.end());
  return M;
}

class StaticSolver : public Component, public OdeSolver, public Stateful {
 public:
  using Component::Component;
  // Newton starts from the current positions each step: only the statistics carry over; the
  // tangent and its factorisation are workspace.
  struct Lu {
    Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
    bool analysed = false;
  };
  struct Live : ComponentStateOf<Live> {
    int iterationsDone = 0;
    BlockSparseMatrix K;
    Scratch<Lu> lu;
    void save(StateWriter& out) const override { out.put(iterationsDone); }
    void load(StateReader& in) override { in.get(iterationsDone); }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  void init() override {
    iterations_ = static_cast<int>(attrs_.integer("newton_iterations"));
    absRes_ = attrs_.real("absolute_residual_tolerance_threshold");
    relRes_ = attrs_.real("relative_residual_tolerance_threshold");
    absCorr_ = attrs_.real("absolute_correction_tolerance_threshold");
    relCorr_ = attrs_.real("relative_correction_tolerance_threshold");
    if (attrs_.isSet("newtonSolver")) {
      // SOFA's newer form: the iteration settings live in a NewtonRaphsonSolver it links to.
      Component* newton = linkedComponent("newtonSolver");
      if (!newton || newton->typeName() != "NewtonRaphsonSolver")
        throw error("newtonSolver", "does not link to a NewtonRaphsonSolver");
      for (const char* own : {"newton_iterations", "absolute_residual_tolerance_threshold",
                              "relative_residual_tolerance_threshold", "absolute_correction_tolerance_threshold",
                              "relative_correction_tolerance_threshold"})
        if (attrs_.isSet(own))
          throw error(own, "is set on the linked NewtonRaphsonSolver '" + newton->name() + "'; set it there");
      const NewtonSettings n = newtonSettings(*newton);
      iterations_ = n.iterations;
      absRes_ = n.absResidual;
      relRes_ = n.relInitial;
      relSuccessive_ = n.relSuccessive;
      absCorr_ = n.absCorrection;
      relCorr_ = n.relCorrection;
      lineSearch_ = n.lineSearch;
      lineSearchFactor_ = n.lineSearchFactor;
    }
    // SOFA's newer form solves with the node's linear solver and SOFA's stiffness, as SOFA does.
    exact_ = attrs_.isSet("exactTangent") ? attrs_.boolean("exactTangent") : !attrs_.isSet("newtonSolver");
    if ((rigid_ = RigidBodyIntegrator::forSolver(*this))) {
      if (!rigid_->idle())
        throw error("does not solve rigid bodies; use EulerImplicitSolver or EulerExplicitSolver in the node of '" +
                    rigid_->bodies().front()->name() + "'");
      return;
    }
    sys_ = std::make_unique<MechanicalSystem>(*this);
    if (exact_) {
      for (ForceField* f : sys_->forceFields()) f->setExactTangent(true);
    } else {
      linear_ = findLinearSolver(*this);
    }
    sys_->prepareAssembly();
  }

  std::optional<Diverged> step(State& st, double t, double, int stepIndex) const override {
    if (rigid_) return std::nullopt;
    Live& l = stateIn<Live>(st);
    MechanicalObject::Live& s = sys_->state().live(st);
    BlockSparseMatrix& K = l.K;
    const int n = sys_->nodes();
    const Eigen::Matrix3Xd xStart = s.x;
    const Eigen::Matrix3Xd zero = Eigen::Matrix3Xd::Zero(3, n);
    double r0 = -1;
    l.iterationsDone = 0;
    auto fail = [&](const std::string& why) {
      s.x = xStart;
      Diverged d;
      d.step = stepIndex;
      d.time = t;
      d.reason = why;
      d.object = sys_->state().name();
      return d;
    };
    // The projected force at x (the residual), linearising the force fields there.
    auto residual = [&](const Eigen::Matrix3Xd& x) {
      sys_->computeForce(st, x, zero, s.f);
      Eigen::Matrix3Xd r = s.f;
      sys_->project(r);
      return r;
    };
    double previous = -1;
    for (int it = 0; it < iterations_; ++it) {
      const Eigen::Matrix3Xd r = residual(s.x);
      const double rn = r.norm();
      if (r0 < 0) r0 = rn;
      if (rn <= absRes_ || (r0 > 0 && rn <= relRes_ * r0)) break;
      if (relSuccessive_ > 0 && previous > 0 && rn <= relSuccessive_ * previous) break;
      previous = rn;
      // Solve (-K) dx = f.
      sys_->assembleStiffness(st, K);
      K.scale(-1.0);
      sys_->constrain(K);
      Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(r.data(), 3 * n), dx;
      if (exact_) {
        Eigen::SparseMatrix<double> A = toSparse(K);
        A.makeCompressed();
        Lu& lu = l.lu.get();
        if (!lu.analysed) {
          lu.lu.analyzePattern(A);
          lu.analysed = true;
        }
        lu.lu.factorize(A);
        if (lu.lu.info() != Eigen::Success) return fail("singular tangent stiffness in Newton iteration " + std::to_string(it));
        dx = lu.lu.solve(b);
      } else {
        LinearProblem p;
        p.matrix = &K;
        p.apply = [&K](const Eigen::VectorXd& a, Eigen::VectorXd& q) {
          q.resize(a.size());
          K.multiply(a, q);
        };
        dx = Eigen::VectorXd::Zero(3 * n);
        LinearSolveInfo info = linear_->solve(st, p, b, dx);
        if (!info.ok) return fail("linear solver failed: " + info.message);
      }
      if (!dx.allFinite()) return fail("non-finite Newton correction");
      Eigen::Matrix3Xd step = Eigen::Map<const Eigen::Matrix3Xd>(dx.data(), 3, n);
      // Backtracking (SOFA's line search): the step shrinks by lineSearchFactor_ until the
      // residual falls; if it never does, the step with the smallest residual is taken.
      if (lineSearch_ > 1) {
        double best = -1, scale = 1, bestScale = 1;
        for (int k = 0; k < lineSearch_; ++k, scale *= lineSearchFactor_) {
          const double trial = residual(s.x + scale * step).norm();
          if (best < 0 || trial < best) best = trial, bestScale = scale;
          if (trial < rn) break;
        }
        step *= bestScale;
      }
      const double moved = step.norm(), size = s.x.norm();
      s.x += step;
      ++l.iterationsDone;
      if (moved <= absCorr_ || (relCorr_ > 0 && size > 0 && moved <= relCorr_ * size)) break;
    }
    s.v.setZero();
    if (auto bad = sys_->check(s.x, s.v, stepIndex, t)) {
      s.x = xStart;
      return bad;
    }
    return std::nullopt;
  }
  // Equilibrium -K dx = F: positions move by (-K)^-1 F.
  std::optional<StepResponse> stepResponse(double) const override {
    if (rigid_) return std::nullopt;
    return StepResponse{0.0, -1.0, 1.0, 0.0};
  }
  int lastLinearIterations(const State& s) const override { return stateIn<Live>(s).iterationsDone; }

 private:
  int iterations_ = 10;
  double absRes_ = 1e-10, relRes_ = 1e-10, absCorr_ = 1e-12;
  double relCorr_ = 1e-12;
  double relSuccessive_ = 0;                       // off unless a NewtonRaphsonSolver sets it
  int lineSearch_ = 1;                             // trial steps per iteration (1: none)
  double lineSearchFactor_ = 0.5;
  bool exact_ = true;
  std::unique_ptr<RigidBodyIntegrator> rigid_;  // a held or driven body's node
  std::unique_ptr<MechanicalSystem> sys_;
  LinearSolver* linear_ = nullptr;
};

// SOFA's NewtonRaphsonSolver as a StaticSolver's settings (StaticSolver newtonSolver="@newton"):
// the component holds them; the StaticSolver that links to it runs the iterations.
class NewtonRaphsonSettings : public Component {
 public:
  using Component::Component;
  void init() override {
    for (const auto& c : node().components())
      if (c->typeName() == "BDFOdeSolver") return;
    for (Component* c : scene().all<Component>())
      if (c->typeName() == "StaticSolver" && c->attrs().isSet("newtonSolver")) {
        const AttrValue& v = c->attrs().get("newtonSolver");
        if (&scene().resolve(*c, v.text, v.loc, "StaticSolver.newtonSolver") == this) return;
      }
    throw error("is used by a StaticSolver that links to it (StaticSolver newtonSolver=\"@" + name() +
                "\") or by a BDFOdeSolver in its node; there is neither");
  }
};

}  // namespace

NewtonSettings newtonSettings(const Component& newton) {
  const Attributes& n = newton.attrs();
  NewtonSettings s;
  s.iterations = static_cast<int>(n.integer("maxNbIterationsNewton"));
  s.absResidual = n.real("absoluteResidualStoppingThreshold");
  s.relInitial = n.real("relativeInitialStoppingThreshold");
  s.relSuccessive = n.real("relativeSuccessiveStoppingThreshold");
  s.absCorrection = n.real("absoluteEstimateDifferenceThreshold");
  s.relCorrection = n.real("relativeEstimateDifferenceThreshold");
  s.lineSearch = static_cast<int>(n.integer("maxNbIterationsLineSearch"));
  s.lineSearchFactor = n.real("lineSearchCoefficient");
  return s;
}

const Component* findNewtonRaphsonSolver(const Component& c) {
  for (const auto& other : c.node().components())
    if (other->typeName() == "NewtonRaphsonSolver") return other.get();
  return nullptr;
}

void registerStaticSolver(Registry& r) {
  {
    ComponentSpec s;
    s.name = "NewtonRaphsonSolver";
    s.category = "solver";
    s.doc = "SOFA's Newton-Raphson settings for a StaticSolver in its node that links to it (newtonSolver=\"@name\"), "
            "or for the BDFOdeSolver in its node. "
            "Each iteration solves the tangent system; it stops at the first criterion met: the residual's norm under "
            "absoluteResidualStoppingThreshold, under relativeInitialStoppingThreshold times the first one or under "
            "relativeSuccessiveStoppingThreshold times the previous one, or a correction under "
            "absoluteEstimateDifferenceThreshold (relativeEstimateDifferenceThreshold times the unknown's norm: the positions "
            "for a StaticSolver, the velocities for a BDFOdeSolver). With "
            "maxNbIterationsLineSearch > 1 a step is halved (lineSearchCoefficient) until the residual falls.";
    s.add(AttrSpec::integer("maxNbIterationsNewton").def("1").atLeast(1).help("Newton iterations per step at most"));
    s.add(AttrSpec::real("absoluteResidualStoppingThreshold").alias("absoluteResidualToleranceThreshold").def("1e-5").atLeast(0)
              .unit(Dimension::force()).help("stop when the residual's norm falls to this"));
    s.add(AttrSpec::real("relativeInitialStoppingThreshold").def("1e-5").atLeast(0).help("stop when the residual falls to this times the first"));
    s.add(AttrSpec::real("relativeSuccessiveStoppingThreshold").def("1e-5").atLeast(0).help("stop when the residual falls to this times the previous one"));
    s.add(AttrSpec::real("absoluteEstimateDifferenceThreshold").def("0").atLeast(0).unit(Dimension::length()).help("stop when a correction's norm falls to this"));
    s.add(AttrSpec::real("relativeEstimateDifferenceThreshold").def("0").atLeast(0).help("stop when a correction's norm falls to this times the positions' norm"));
    s.add(AttrSpec::integer("maxNbIterationsLineSearch").def("5").atLeast(1).help("trial steps per iteration (1: the full step)"));
    s.add(AttrSpec::real("lineSearchCoefficient").def("0.5").above(0).below(1).help("factor a trial step shrinks by"));
    s.add(AttrSpec::boolean("warnWhenLineSearchFails").def("true").help("SOFA's message switch; accepted, no message is printed"));
    s.add(AttrSpec::choice("updateStateWhenDiverged", {"true", "1"}).def("true").help("keep the last iterate when the iterations do not converge (only true)"));
    s.factory = [](BuildContext& c) { return std::make_unique<NewtonRaphsonSettings>(c); };
    r.add(std::move(s));
  }
  ComponentSpec s;
  s.name = "StaticSolver";
  s.category = "solver";
  s.doc = "Static equilibrium by Newton's method each step (loads applied at once; inertia ignored).";
  s.add(AttrSpec::integer("newton_iterations").alias("maxNbIterationsNewton").def("20").atLeast(1).help("maximum Newton iterations per step"));
  s.add(AttrSpec::real("absolute_residual_tolerance_threshold").def("1e-10").atLeast(0).help("stop when ||f|| falls to this"));
  s.add(AttrSpec::real("relative_residual_tolerance_threshold").def("1e-10").atLeast(0).help("stop when ||f|| / ||f0|| falls to this"));
  s.add(AttrSpec::real("absolute_correction_tolerance_threshold").def("1e-12").atLeast(0).help("stop when ||dx|| falls to this"));
  s.add(AttrSpec::real("relative_correction_tolerance_threshold").def("1e-12").atLeast(0).help("stop when ||dx|| falls to this times ||x||"));
  s.add(AttrSpec::link("newtonSolver").help("a NewtonRaphsonSolver whose settings replace the four above (SOFA's newer form)"));
  s.add(AttrSpec::boolean("exactTangent").def("true").help("exact corotational tangent with sparse LU (false: the node's linear solver with SOFA's stiffness; the default with `newtonSolver`, as SOFA)"));
  s.factory = [](BuildContext& c) { return std::make_unique<StaticSolver>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
