// Constraint contact (SOFA's FreeMotionAnimationLoop + GenericConstraintSolver): after the free
// motion, each contact gets a normal force (non-penetration) and a friction force inside the
// Coulomb cone, found by projected Gauss-Seidel on the Delassus operator W = H C H^T, where C
// maps forces on the tissue nodes to end-of-step displacements (the constraint correction).
//
// Rows of a contact (tissue point p = sum w_i x_i, n towards the sphere, t1 t2 tangents):
//   gap   g = g_free - n . dp           (>= 0; normal force lambda_n >= 0 pushes the tissue along -n)
//   slip  s = t . (p - p_start) - t . (sphere point displacement over the step)
// with |lambda_t| <= mu lambda_n, lambda_t opposing the slip while sliding.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <mutex>
#include <unordered_map>

#include "engine/MechanicalSystem.h"
#include "engine/collision/Collision.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/LinearSolver.h"

namespace viscera {

namespace {

// The compliance of one deformable body over a step: C = xFactor A^-1 (or the uncoupled mass-only
// approximation), with its block columns cached per node.
class ConstraintCorrection : public Component, public Stateful {
 public:
  enum class Mode { Precomputed, LinearSolver, Uncoupled };
  using Component::Component;

  void init() override {
    const std::string& t = typeName();
    for (const char* rigidOnly : {"defaultCompliance", "useOdeSolverIntegrationFactors"})
      if (attrs_.isSet(rigidOnly))
        throw error(rigidOnly, "is not used for a deformable body: its compliance comes from the step's matrix and the "
                               "ODE solver's factors");
    mode_ = t == "UncoupledConstraintCorrection" ? Mode::Uncoupled
            : t == "LinearSolverConstraintCorrection" || t == "GenericConstraintCorrection" ? Mode::LinearSolver
                                                                                            : Mode::Precomputed;
    sys_ = std::make_unique<MechanicalSystem>(*this);
    auto* ode = node().find<OdeSolver>();
    if (!ode) throw error("needs the body's ODE solver (EulerImplicitSolver or StaticSolver) in its node");
    scene().initComponent(dynamic_cast<Component&>(*ode));
    ode_ = ode;
    auto r = ode->stepResponse(scene().dt());
    if (!r) throw error("the ODE solver in its node has no linear system to correct");
    if (mode_ == Mode::Uncoupled && !(r->mFactor > 0))
      throw error("the uncoupled (mass-only) compliance needs a dynamic solver (EulerImplicitSolver)");
    if (mode_ != Mode::Uncoupled) sys_->prepareAssembly();
    // The compliance at rest for the scene's step, factorised once and shared by every simulation.
    if (mode_ == Mode::Precomputed) {
      restDt_ = scene().dt();
      rest_ = std::make_shared<CholmodSolver>();
      factorizeAt(sys_->state().x0, *r, *rest_);
    }
  }

  MechanicalObject& mstate() const { return sys_->state(); }

  // Per simulation: the step response, the step matrix and its factorisation when the compliance
  // follows the state (or another step size than the shared one), and cached columns of C. All of
  // it is rebuilt as the simulation steps, so none of it is saved.
  struct Live : ComponentStateOf<Live> {
    StepResponse resp;
    double respDt = 0;
    bool own = false;  // the factorisation is this state's (else the shared one at rest)
    BlockSparseMatrix A;
    Scratch<CholmodSolver> chol;
    std::unordered_map<int, Eigen::MatrixX3d> columns;
    void save(StateWriter&) const override {}
    void load(StateReader&) override {}
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }

  // Called once per step of size h before the solve: refactors when the compliance follows the
  // state, or when the step size differs from the precomputed one.
  Live& prepare(State& st, double h) const {
    Live& l = stateIn<Live>(st);
    if (h != l.respDt) {
      auto r = ode_->stepResponse(h);
      if (!r) throw error("the ODE solver in its node has no linear system to correct");
      l.resp = *r;
      l.respDt = h;
      l.columns.clear();
      l.own = false;
      if (mode_ == Mode::Precomputed && h != restDt_) {
        factorizeAt(sys_->state().x0, l.resp, l.chol.get());
        l.own = true;
      }
    }
    if (mode_ == Mode::LinearSolver) {
      factorizeAt(st, sys_->state().x(st), l.resp, l.A, l.chol.get());
      l.own = true;
      l.columns.clear();
    }
    return l;
  }

  // The 3x3 block C(u, v).
  Eigen::Matrix3d block(Live& l, int u, int v) const {
    if (mode_ == Mode::Uncoupled) return u == v ? uncoupled(l, u) : Eigen::Matrix3d::Zero();
    const Eigen::MatrixX3d& col = column(l, v);
    return col.middleRows<3>(3 * u);
  }

  // dx = C F for forces F on the nodes (non-zero on the few contact nodes: a sum of their cached
  // columns, cheaper than a solve).
  void apply(Live& l, const Eigen::Matrix3Xd& F, Eigen::Matrix3Xd& dx) const {
    const int n = F.cols();
    dx.setZero(3, n);
    Eigen::Map<Eigen::VectorXd> d(dx.data(), 3 * n);
    for (int i = 0; i < n; ++i) {
      if (F.col(i).isZero()) continue;
      if (mode_ == Mode::Uncoupled) dx.col(i) = uncoupled(l, i) * F.col(i);
      else d.noalias() += column(l, i) * F.col(i);
    }
  }

 private:
  Eigen::Matrix3d uncoupled(const Live& l, int u) const {
    const double m = sys_->nodeMass()[u];
    return sys_->projector(u) * (l.resp.xFactor / (l.resp.mFactor * m));
  }

  // Factorises the step matrix A = mFactor M + kFactor K with the force fields linearised at x
  // (in state `st`, whose force-field blocks it overwrites).
  void factorizeAt(State& st, const Eigen::Matrix3Xd& x, const StepResponse& r, BlockSparseMatrix& A,
                   CholmodSolver& chol) const {
    const int n = sys_->nodes();
    Eigen::Matrix3Xd f;
    sys_->computeForce(st, x, Eigen::Matrix3Xd::Zero(3, n), f);  // linearise the force fields at x
    sys_->assembleStiffness(st, A);
    A.scale(r.kFactor);
    if (r.mFactor != 0) sys_->addMass(A, r.mFactor);
    sys_->constrain(A);
    std::string msg;
    if (!chol.factorize(A, msg)) throw error("cannot factorize the body's step matrix for the contact compliance: " + msg);
  }
  // The same at rest, in a scratch state of the model's initial values.
  void factorizeAt(const Eigen::Matrix3Xd& x, const StepResponse& r, CholmodSolver& chol) const {
    // Only the body's force fields (initialised by now) get a block: the rest are not read.
    State rest;
    const auto& forces = sys_->forceFields();
    std::vector<Stateful*> stateful = scene().all<Stateful>();
    for (size_t i = 0; i < stateful.size(); ++i) {
      if (stateful[i]->stateSlot() < 0) stateful[i]->setStateSlot(static_cast<int>(i));
      auto* f = dynamic_cast<ForceField*>(stateful[i]);
      const bool used = f && std::find(forces.begin(), forces.end(), f) != forces.end();
      rest.add("", used ? stateful[i]->initialState() : nullptr);
    }
    BlockSparseMatrix A;
    factorizeAt(rest, x, r, A, chol);
  }

  const Eigen::MatrixX3d& column(Live& l, int v) const {
    auto it = l.columns.find(v);
    if (it != l.columns.end()) return it->second;
    // Bound the cache (each column is 3 x 3n doubles).
    if (l.columns.size() * 9.0 * sys_->nodes() * 8 > 256e6) l.columns.clear();
    const int n3 = 3 * sys_->nodes();
    Eigen::MatrixX3d col(n3, 3);
    Eigen::VectorXd e = Eigen::VectorXd::Zero(n3), x;
    // A unit force on node v, projected as the constraints allow (none on a fixed node).
    const Eigen::Matrix3d Pv = sys_->projector(v);
    for (int k = 0; k < 3; ++k) {
      e.setZero();
      e.segment<3>(3 * v) = Pv.col(k);
      if (l.own) {
        l.chol->solve(e, x);
      } else {
        // The shared factorisation's solves take turns (CHOLMOD's workspace is the solver's).
        std::lock_guard<std::mutex> lock(restMutex_);
        rest_->solve(e, x);
      }
      col.col(k) = x * l.resp.xFactor;
    }
    for (int f : sys_->fixedNodes()) col.middleRows<3>(3 * f).setZero();
    for (const auto& [i, P] : sys_->partialNodes()) col.middleRows<3>(3 * i) = P * col.middleRows<3>(3 * i);
    return l.columns.emplace(v, std::move(col)).first->second;
  }

  Mode mode_ = Mode::Precomputed;
  std::unique_ptr<MechanicalSystem> sys_;
  OdeSolver* ode_ = nullptr;
  double restDt_ = 0;
  std::shared_ptr<CholmodSolver> rest_;  // the step matrix at rest for restDt_, factorised
  mutable std::mutex restMutex_;
};

class GenericConstraintSolver : public Component, public ConstraintSolver, public Stateful {
 public:
  using Component::Component;
  // Each step starts from zero impulses: only the last step's statistics carry over.
  struct Live : ComponentStateOf<Live> {
    int iterations = 0;
    double residual = 0;
    void save(StateWriter& out) const override {
      out.put(iterations);
      out.put(residual);
    }
    void load(StateReader& in) override {
      in.get(iterations);
      in.get(residual);
    }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  void init() override {
    maxIt_ = static_cast<int>(attrs_.integer("maxIterations"));
    tol_ = attrs_.real("tolerance");
    if (attrs_.isSet("mu")) muOverride_ = attrs_.real("mu");
    if (!hasAnimationLoop())
      throw error("needs FreeMotionAnimationLoop in the root node (constraint contact runs after the free motion)");
    for (ConstraintCorrection* c : scene().all<ConstraintCorrection>()) {
      scene().initComponent(*c);
      corrections_.push_back(c);
    }
  }

  std::optional<Diverged> solve(State& st, const CollisionPipeline& pipe, double h, int stepIndex,
                                double time) const override {
    Live& l = stateIn<Live>(st);
    l.iterations = 0;
    l.residual = 0;
    if (pipe.settings().response != ContactSettings::Response::Constraint) return std::nullopt;
    const double mu = muOverride_ >= 0 ? muOverride_ : pipe.settings().mu;
    for (const SurfaceCollisionModel* surf : pipe.surfaces()) {
      if (!surf->active() || surf->contacts(st).empty()) continue;
      const ConstraintCorrection* cc = correctionFor(surf->mstate());
      if (!cc) throw surf->error("constraint contact needs a constraint correction in the node of '" + surf->mstate().name() +
                                 "' (PrecomputedConstraintCorrection, LinearSolverConstraintCorrection or "
                                 "UncoupledConstraintCorrection)");
      if (auto bad = solveBody(st, *surf, *cc, mu, h, stepIndex, time)) return bad;
    }
    return std::nullopt;
  }
  int lastIterations(const State& s) const override { return stateIn<Live>(s).iterations; }
  double lastResidual(const State& s) const override { return stateIn<Live>(s).residual; }

 private:
  bool hasAnimationLoop() const {
    for (const auto& c : scene().root().components())
      if (c->typeName() == "FreeMotionAnimationLoop") return true;
    return false;
  }
  ConstraintCorrection* correctionFor(const MechanicalObject& m) const {
    for (ConstraintCorrection* c : corrections_)
      if (&c->mstate() == &m) return c;
    return nullptr;
  }

  std::optional<Diverged> solveBody(State& st, const SurfaceCollisionModel& surf, const ConstraintCorrection& cc,
                                    double mu, double h, int stepIndex, double time) const {
    Live& l = stateIn<Live>(st);
    const MechanicalObject& body = surf.mstate();
    MechanicalObject::Live& s = body.live(st);
    std::vector<Contact>& cs = surf.contacts(st);
    const int m = static_cast<int>(cs.size());
    ConstraintCorrection::Live& ccl = cc.prepare(st, h);
    // Rows R_i = [-n^T; t1^T; t2^T] acting on the contact point.
    std::vector<Eigen::Matrix3d> R(m);
    std::vector<Eigen::Vector3d> dfree(m), lambda(m, Eigen::Vector3d::Zero());
    for (int i = 0; i < m; ++i) {
      const Contact& c = cs[i];
      Eigen::Vector3d t1 = c.n.unitOrthogonal(), t2 = c.n.cross(t1);
      R[i].row(0) = -c.n.transpose();
      R[i].row(1) = t1.transpose();
      R[i].row(2) = t2.transpose();
      const Eigen::Vector3d p = c.point(s.x);
      const Eigen::Vector3d at = c.sphere->centre(st) - c.sphere->radius() * c.n;
      const Eigen::Vector3d slip = (p - c.p0) - h * c.sphere->body().live(st).pointVelocity(at);
      dfree[i] = Eigen::Vector3d(c.gap(s.x), t1.dot(slip), t2.dot(slip));
    }
    // Delassus blocks W_ij = R_i (sum_a sum_b w_a w_b C(a, b)) R_j^T. C(a, b) comes from node b's
    // column, so j is the outer loop: contact j's (at most three) columns are fetched once for all
    // i; with i outside, once the contact nodes outnumbered the bounded column cache, every column
    // was recomputed for every i (O(m^2) solves).
    Eigen::MatrixXd W(3 * m, 3 * m);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        Eigen::Matrix3d Cij = Eigen::Matrix3d::Zero();
        for (int a = 0; a < cs[i].count; ++a)
          for (int b = 0; b < cs[j].count; ++b) Cij += cs[i].w[a] * cs[j].w[b] * cc.block(ccl, cs[i].nodes[a], cs[j].nodes[b]);
        W.block<3, 3>(3 * i, 3 * j) = R[i] * Cij * R[j].transpose();
      }
    // Projected Gauss-Seidel: each contact's local problem in turn, until no force changes by
    // more than tolerance x the largest force.
    for (int it = 0; it < maxIt_; ++it) {
      double change = 0, scale = 1e-300;
      for (int i = 0; i < m; ++i) {
        Eigen::Vector3d d = dfree[i];
        for (int j = 0; j < m; ++j) d += W.block<3, 3>(3 * i, 3 * j) * lambda[j];
        const Eigen::Matrix3d& Wii = W.block<3, 3>(3 * i, 3 * i);
        Eigen::Vector3d l = lambda[i];
        // Normal: make the gap zero if that pushes, else release.
        l[0] = std::max(0.0, l[0] - d[0] / Wii(0, 0));
        d += Wii.col(0) * (l[0] - lambda[i][0]);
        // Tangential: stick (zero slip), then project onto the cone |l_t| <= mu l_n.
        Eigen::Vector2d lt = l.tail<2>() - Wii.block<2, 2>(1, 1).ldlt().solve(d.tail<2>());
        const double lim = mu * l[0];
        if (lt.norm() > lim) lt *= lim / std::max(lt.norm(), 1e-300);
        l.tail<2>() = lt;
        change = std::max(change, (l - lambda[i]).norm());
        scale = std::max(scale, l.norm());
        lambda[i] = l;
      }
      l.iterations = it + 1;
      l.residual = change / scale;
      if (l.residual <= tol_) break;
    }
    // Correct the free motion: forces on the nodes, displacement C F, velocity to match.
    Eigen::Matrix3Xd F = Eigen::Matrix3Xd::Zero(3, body.size()), dx;
    for (int i = 0; i < m; ++i) {
      Contact& c = cs[i];
      c.force = R[i].transpose() * lambda[i];
      c.active = lambda[i][0] > 0;
      for (int a = 0; a < c.count; ++a) F.col(c.nodes[a]) += c.w[a] * c.force;
    }
    cc.apply(ccl, F, dx);
    const Eigen::Matrix3Xd x0 = s.x, v0 = s.v;
    s.x += dx;
    const StepResponse& r = ccl.resp;
    if (r.vFactor != 0) s.v += dx * (r.vFactor / r.xFactor);
    if (!s.x.allFinite() || !s.v.allFinite()) {
      s.x = x0;
      s.v = v0;
      Diverged d;
      d.step = stepIndex;
      d.time = time;
      d.reason = "constraint solver produced non-finite forces";
      d.object = body.name();
      return d;
    }
    return std::nullopt;
  }

  int maxIt_ = 1000;
  double tol_ = 1e-8;
  double muOverride_ = -1;
  std::vector<ConstraintCorrection*> corrections_;
};

class FreeMotionAnimationLoop : public Component {
 public:
  using Component::Component;
  void init() override {
    if (node().parent()) throw error("belongs in the root node");
    if (scene().all<ConstraintSolver>().empty())
      throw error("needs a constraint solver in the root node (GenericConstraintSolver or LCPConstraintSolver)");
  }
};

// A constraint correction in a rigid body's node (SOFA scenes give every body one). Contact on a
// rigid body is not handled (the step fails when something touches its surfaces), so its
// compliance is never needed: the component only says so.
class RigidBodyCorrection : public Component {
 public:
  using Component::Component;
  void init() override {
    RigidObject& body = contextRigid(*this, "mstate");
    scene().addNote(loc().str() + ": note: " + typeName() + " '" + name() + "' is on rigid body '" + body.name() +
                    "': contact on rigid bodies is not handled (a step in which something touches its surfaces "
                    "fails), so no compliance is used");
  }
};

}  // namespace

void registerConstraintContact(Registry& r) {
  {
    ComponentSpec s;
    s.name = "FreeMotionAnimationLoop";
    s.category = "collision";
    s.doc = "Step loop for constraint contact: drivers, collision detection, the free motion of every body, then "
            "the constraint solver corrects positions and velocities so that contacts do not penetrate and "
            "friction stays in the Coulomb cone. Root node only.";
    s.add(AttrSpec::boolean("solveVelocityConstraintFirst").def("false").help("accepted for SOFA scenes; positions are corrected"));
    s.add(AttrSpec::boolean("parallelCollisionDetectionAndFreeMotion").def("false").help("accepted for SOFA scenes"));
    s.add(AttrSpec::boolean("parallelODESolving").def("false").help("accepted for SOFA scenes"));
    s.factory = [](BuildContext& c) { return std::make_unique<FreeMotionAnimationLoop>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "GenericConstraintSolver";
    s.aliases = {"LCPConstraintSolver", "BlockGaussSeidelConstraintSolver", "ProjectedGaussSeidelConstraintSolver"};
    s.category = "collision";
    s.doc = "Projected Gauss-Seidel on the contacts' Delassus operator (3x3 block per contact pair): normal force "
            ">= 0 with zero gap when pushing, friction in the Coulomb cone. Stops when no contact force changes by "
            "more than tolerance x the largest force, or after maxIterations.";
    s.add(AttrSpec::integer("maxIterations").alias("maxIt").def("1000").atLeast(1).help("Gauss-Seidel sweeps at most"));
    s.add(AttrSpec::real("tolerance").alias("tol").def("1e-8").above(0).help("relative change of the contact forces to stop at"));
    s.add(AttrSpec::real("mu").atLeast(0).help("friction coefficient (overrides the CollisionResponse's)"));
    s.add(AttrSpec::boolean("build_lcp").def("true").help("accepted for SOFA scenes"));
    s.add(AttrSpec::boolean("initial_guess").def("true").help(
        "accepted for SOFA scenes (a warm start from the last step's forces): the iteration starts from zero forces, "
        "and converges to the same forces within the tolerance"));
    s.add(AttrSpec::boolean("scaleTolerance").def("true").help(
        "accepted for SOFA scenes (SOFA's tolerance times the number of rows); the tolerance here is relative to the "
        "largest contact force"));
    s.add(AttrSpec::boolean("multi_grid").def("false").help(
        "accepted for SOFA scenes (a coarse-level start for large problems): the result is the same within the tolerance"));
    s.add(AttrSpec::boolean("computeConstraintForces").def("true").help("accepted for SOFA scenes; forces are always computed"));
    s.add(AttrSpec::string("resolutionMethod").def("ProjectedGaussSeidel").help("accepted for SOFA scenes; projected Gauss-Seidel is used"));
    s.add(AttrSpec::boolean("printLog").def("false").help("accepted for SOFA scenes"));
    s.factory = [](BuildContext& c) { return std::make_unique<GenericConstraintSolver>(c); };
    r.add(std::move(s));
  }
  const char* corr[3][2] = {
      {"PrecomputedConstraintCorrection",
       "Contact compliance of a body from its step matrix A = mFactor M + kFactor K at rest, factorised once "
       "(CHOLMOD); columns are cached per node. Exact for small rotations, cheap per step."},
      {"LinearSolverConstraintCorrection",
       "Contact compliance of a body from its step matrix at the current state, refactorised every step: exact "
       "for the corotational stiffness, about one factorisation per step."},
      {"UncoupledConstraintCorrection",
       "Contact compliance from the lumped mass only (no coupling through the stiffness): cheapest, and a poor "
       "model of soft tissue; for comparison with SOFA scenes."}};
  for (auto& c : corr) {
    ComponentSpec s;
    s.name = c[0];
    if (std::string(c[0]) == "LinearSolverConstraintCorrection") s.aliases = {"GenericConstraintCorrection"};
    s.category = "collision";
    s.doc = c[1];
    s.add(AttrSpec::string("solverName").def("").help("accepted for SOFA scenes; the node's solver is used"));
    s.add(AttrSpec::string("compliance").def("").help("accepted for SOFA scenes; the compliance comes from the mass"));
    s.add(AttrSpec::boolean("wire_optimization").def("false").help("accepted for SOFA scenes"));
    s.add(AttrSpec::link("linearSolver").help("accepted for SOFA scenes; the node's solver is used"));
    s.add(AttrSpec::real("defaultCompliance").atLeast(0).help("rigid bodies only (whose contact is not handled): accepted for SOFA scenes"));
    s.add(AttrSpec::boolean("useOdeSolverIntegrationFactors").def("true").help("rigid bodies only (whose contact is not handled): accepted for SOFA scenes"));
    s.add(AttrSpec::link("mstate").help("the body (default: the one in the node)"));
    s.factory = [](BuildContext& ctx) -> std::unique_ptr<Component> {
      if (ctx.node().find<RigidObject>() && !ctx.node().find<MechanicalObject>()) return std::make_unique<RigidBodyCorrection>(ctx);
      return std::make_unique<ConstraintCorrection>(ctx);
    };
    r.add(std::move(s));
  }
}

}  // namespace viscera
