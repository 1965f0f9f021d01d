// Constraint contact (SOFA's FreeMotionAnimationLoop + GenericConstraintSolver): after the free
// motion, each contact gets a normal force (non-penetration) and a friction force inside the
// Coulomb cone, found by projected Gauss-Seidel on the Delassus operator W = H C H^T, where C
// maps forces on the tissue nodes to end-of-step displacements (the constraint correction).
//
// Rows of a contact (tissue point p = sum w_i x_i, n towards the sphere, t1 t2 tangents):
//   gap   g = g_free - n . dp           (>= 0; normal force lambda_n >= 0 pushes the tissue along -n)
//   slip  s = t . (p - p_start) - t . (sphere point displacement over the step)
// with |lambda_t| <= mu lambda_n, lambda_t opposing the slip while sliding. Contacts between the
// surfaces of two bodies (rigid bodies, deformable ones, fixed obstacles) have the same rows on the
// relative motion of the two sides, and are solved together (solvePairs).
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
#include "engine/rigid/RigidMapping.h"
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

// The compliance of an integrated rigid body (UncoupledConstraintCorrection in its node): a wrench
// W over the step moves it by xFactor / mFactor M^-1 W (translation, then rotation vector), with
// M = diag(m I, R I_body R^T) as the body's solver integrates it, or SOFA's `compliance` (1/m and
// the six upper entries of the inverse inertia) or `defaultCompliance` in place of M^-1; the
// velocities change by vFactor / xFactor of that (SOFA: dx = dt dv).
class RigidConstraintCorrection : public Component {
 public:
  using Component::Component;
  void init() override {
    body_ = &contextRigid(*this, "mstate");
    scene().initComponent(*body_);
    // The solver initialises the body's node, this component included: its step response is read
    // when the constraint solver runs (none is needed for a body nothing moves).
    for (const Node* n = &body_->node(); n && !ode_; n = n->parent()) ode_ = n->find<OdeSolver>();
    const std::vector<double> c = attrs_.reals("compliance");
    if (!c.empty()) {
      if (c.size() != 7) throw error("compliance", "a rigid body's compliance is 7 numbers: 1/m and the upper inverse inertia (xx xy xz yy yz zz)");
      given_ = true;
      linear_ = c[0];
      rotational_ << c[1], c[2], c[3], c[2], c[4], c[5], c[3], c[5], c[6];
    } else if (attrs_.isSet("defaultCompliance")) {
      given_ = true;
      linear_ = attrs_.real("defaultCompliance");
      rotational_.setIdentity();
    }
    for (RigidMapping* m : scene().all<RigidMapping>()) {
      scene().initComponent(*m);
      if (&m->body() == body_) mappings_.push_back(m);
    }
  }
  RigidObject& body() const { return *body_; }

  // Whether anything moves the body: it is integrated (a mass, not driven, no prescribed velocity).
  bool moves() const { return !body_->driven && body_->mass > 0 && !body_->prescribedVelocity; }

  // The 6x6 compliance over a step of size h at state s; held components take nothing.
  Eigen::Matrix<double, 6, 6> compliance(const State& s, double h) const {
    Eigen::Matrix<double, 6, 6> C = Eigen::Matrix<double, 6, 6>::Zero();
    if (!moves()) return C;
    const StepResponse r = response(h);
    const double f = r.xFactor / r.mFactor;
    if (given_) {
      C.topLeftCorner<3, 3>() = f * linear_ * Eigen::Matrix3d::Identity();
      C.bottomRightCorner<3, 3>() = f * rotational_;
    } else {
      C.topLeftCorner<3, 3>() = f / body_->mass * Eigen::Matrix3d::Identity();
      const Eigen::Matrix3d R = body_->live(s).q.toRotationMatrix();
      C.bottomRightCorner<3, 3>() = f * R * body_->inertia.inverse() * R.transpose();
    }
    for (int k = 0; k < 6; ++k)
      if (body_->held[k]) {
        C.row(k).setZero();
        C.col(k).setZero();
      }
    return C;
  }
  // Moves the body by C W (C: its compliance for this step, from compliance(); W: force and torque
  // about its origin) and its velocity to match; the mapped points follow.
  void apply(State& s, const Eigen::Matrix<double, 6, 6>& C, const Eigen::Matrix<double, 6, 1>& wrench, double h) const {
    if (!moves()) return;
    const StepResponse r = response(h);
    const Eigen::Matrix<double, 6, 1> d = C * wrench;
    RigidObject::Live& b = body_->live(s);
    for (int k = 0; k < 3; ++k) {
      if (!body_->held[k]) {
        b.p[k] += d[k];
        b.v[k] += d[k] * r.vFactor / r.xFactor;
      }
    }
    Eigen::Vector3d turn = d.tail<3>();
    for (int k = 0; k < 3; ++k)
      if (body_->held[3 + k]) turn[k] = 0;
    b.w += turn * (r.vFactor / r.xFactor);
    if (turn.norm() > 0) b.q = (Eigen::Quaterniond(Eigen::AngleAxisd(turn.norm(), turn.normalized())) * b.q).normalized();
    remap(s);
  }
  // The points mapped from the body follow its pose in s.
  void remap(State& s) const {
    for (const RigidMapping* m : mappings_) m->apply(s);
  }

 private:
  StepResponse response(double h) const {
    if (!ode_) throw error("rigid body '" + body_->name() + "' has no ODE solver in its node or above it");
    const auto r = ode_->stepResponse(h);
    if (!r || !(r->xFactor > 0))
      throw error("the solver moving rigid body '" + body_->name() + "' gives no step response (use EulerImplicitSolver)");
    return *r;
  }

  RigidObject* body_ = nullptr;
  OdeSolver* ode_ = nullptr;
  bool given_ = false;
  double linear_ = 0;
  Eigen::Matrix3d rotational_ = Eigen::Matrix3d::Identity();
  std::vector<const RigidMapping*> mappings_;
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
    // SOFA's LCPConstraintSolver applies its own mu (0.6 unless given) to every contact that has
    // friction at all (a response mu above 0); GenericConstraintSolver's given mu replaces the response's.
    lcp_ = typeName() == "LCPConstraintSolver";
    if (attrs_.isSet("mu")) muOverride_ = attrs_.real("mu");
    else if (lcp_) muOverride_ = 0.6;
    if (!hasAnimationLoop())
      throw error("needs FreeMotionAnimationLoop in the root node (constraint contact runs after the free motion)");
    for (ConstraintCorrection* c : scene().all<ConstraintCorrection>()) {
      scene().initComponent(*c);
      corrections_.push_back(c);
    }
    for (RigidConstraintCorrection* c : scene().all<RigidConstraintCorrection>()) {
      scene().initComponent(*c);
      rigidCorrections_.push_back(c);
    }
  }

  std::optional<Diverged> solve(State& st, const CollisionPipeline& pipe, double h, int stepIndex,
                                double time) const override {
    Live& l = stateIn<Live>(st);
    l.iterations = 0;
    l.residual = 0;
    if (pipe.settings().response != ContactSettings::Response::Constraint) return std::nullopt;
    const double mu = muOverride_ < 0 ? pipe.settings().mu : lcp_ && !(pipe.settings().mu > 0) ? 0.0 : muOverride_;
    for (const SurfaceCollisionModel* surf : pipe.surfaces()) {
      if (!surf->active() || surf->rigidBody() || surf->isStatic()) continue;
      const auto& cs = surf->contacts(st);
      if (std::none_of(cs.begin(), cs.end(), [](const Contact& c) { return c.sphere; })) continue;
      if (auto bad = solveBody(st, *surf, deformableCorrection(*surf), mu, h, stepIndex, time)) return bad;
    }
    return solvePairs(st, pipe, mu, h, stepIndex, time);
  }
  int lastIterations(const State& s) const override { return stateIn<Live>(s).iterations; }
  double lastResidual(const State& s) const override { return stateIn<Live>(s).residual; }

 private:
  bool hasAnimationLoop() const {
    for (const auto& c : scene().root().components())
      if (c->typeName() == "FreeMotionAnimationLoop") return true;
    return false;
  }
  const ConstraintCorrection& deformableCorrection(const SurfaceCollisionModel& surf) const {
    for (ConstraintCorrection* c : corrections_)
      if (&c->mstate() == &surf.mstate()) return *c;
    throw surf.error("constraint contact needs a constraint correction in the node of '" + surf.mstate().name() +
                     "' (PrecomputedConstraintCorrection, LinearSolverConstraintCorrection or UncoupledConstraintCorrection)");
  }
  // The correction of the rigid body a surface is on, or null when nothing moves the body.
  const RigidConstraintCorrection* rigidCorrection(const SurfaceCollisionModel& surf) const {
    const RigidObject& b = *surf.rigidBody();
    for (RigidConstraintCorrection* c : rigidCorrections_)
      if (&c->body() == &b) return c->moves() ? c : nullptr;
    if (b.driven || !(b.mass > 0) || b.prescribedVelocity) return nullptr;
    throw surf.error("constraint contact with rigid body '" + b.name() + "' needs UncoupledConstraintCorrection in its node");
  }

  // One side of a contact between two bodies: the body that moves under it (none for a fixed
  // surface or a driven body), how the contact point follows it, and the sign of the force on it.
  struct Side {
    const SurfaceCollisionModel* surf = nullptr;
    Contact* c = nullptr;  // this side's own record of the contact (the pair's, or its mirror)
    const ConstraintCorrection* deformable = nullptr;
    const RigidConstraintCorrection* rigid = nullptr;
    Eigen::Vector3d arm = Eigen::Vector3d::Zero();  // rigid: contact point - body origin
    double sign = 1;
    const void* key() const { return deformable ? static_cast<const void*>(deformable) : static_cast<const void*>(rigid); }
  };

  // Contacts between the surfaces of two bodies (a vertex of one against a feature of the other),
  // solved together: a body touching several others couples their contacts. The pair's force
  // lambda pushes the first side along -n and the second along +n; the Delassus operator sums each
  // moving body's compliance between the contact points (a rigid body's C(p, q) = J_p C J_q^T with
  // J_p = [I, -[p - origin]x]).
  std::optional<Diverged> solvePairs(State& st, const CollisionPipeline& pipe, double mu, double h, int stepIndex,
                                     double time) const {
    const auto& surfaces = pipe.surfaces();
    auto indexOf = [&](const SurfaceCollisionModel* m) {
      return static_cast<int>(std::find(surfaces.begin(), surfaces.end(), m) - surfaces.begin());
    };
    std::vector<std::array<Side, 2>> pairs;
    for (int si = 0; si < static_cast<int>(surfaces.size()); ++si) {
      const SurfaceCollisionModel* a = surfaces[si];
      if (!a->active()) continue;
      auto& cs = a->contacts(st);
      for (int ci = 0; ci < static_cast<int>(cs.size()); ++ci) {
        Contact& c = cs[ci];
        if (!c.partner) continue;
        const int pi = indexOf(c.partner);
        if (std::make_pair(pi, c.mirror) < std::make_pair(si, ci)) continue;  // the pair is taken from its other side
        std::array<Side, 2> p;
        p[0].surf = a;
        p[0].c = &c;
        p[1].surf = c.partner;
        p[1].c = &c.partner->contacts(st)[c.mirror];
        p[1].sign = -1;
        for (Side& sd : p) {
          if (sd.surf->isStatic()) continue;
          if (sd.surf->rigidBody()) {
            sd.rigid = rigidCorrection(*sd.surf);
            if (sd.rigid)
              sd.arm = sd.c->point(sd.surf->mstate().x(st)) - sd.rigid->body().live(st).p;
          } else {
            sd.deformable = &deformableCorrection(*sd.surf);
          }
        }
        if (p[0].key() || p[1].key()) pairs.push_back(p);
      }
    }
    if (pairs.empty()) return std::nullopt;
    Live& l = stateIn<Live>(st);
    const int m = static_cast<int>(pairs.size());
    std::unordered_map<const void*, ConstraintCorrection::Live*> deformableLive;
    std::unordered_map<const void*, Eigen::Matrix<double, 6, 6>> rigidC;
    for (const auto& p : pairs)
      for (const Side& sd : p) {
        if (sd.deformable && !deformableLive.count(sd.key())) deformableLive[sd.key()] = &sd.deformable->prepare(st, h);
        if (sd.rigid && !rigidC.count(sd.key())) rigidC[sd.key()] = sd.rigid->compliance(st, h);
      }
    // The compliance of one body between the points of sides u and v (both on it).
    auto C = [&](const Side& u, const Side& v) -> Eigen::Matrix3d {
      if (u.rigid) {
        const Eigen::Matrix<double, 6, 6>& Cr = rigidC.at(u.key());
        Eigen::Matrix<double, 3, 6> Ju, Jv;
        Ju << Eigen::Matrix3d::Identity(), -skew(u.arm);
        Jv << Eigen::Matrix3d::Identity(), -skew(v.arm);
        return Ju * Cr * Jv.transpose();
      }
      ConstraintCorrection::Live& cl = *deformableLive.at(u.key());
      Eigen::Matrix3d r = Eigen::Matrix3d::Zero();
      for (int a = 0; a < u.c->count; ++a)
        for (int b = 0; b < v.c->count; ++b) r += u.c->w[a] * v.c->w[b] * u.deformable->block(cl, u.c->nodes[a], v.c->nodes[b]);
      return r;
    };
    // Rows [-n; t1; t2] of the first side's normal; free gap and slip.
    std::vector<Eigen::Matrix3d> R(m);
    std::vector<Eigen::Vector3d> dfree(m), lambda(m, Eigen::Vector3d::Zero());
    for (int i = 0; i < m; ++i) {
      const Side &A = pairs[i][0], &B = pairs[i][1];
      const Eigen::Vector3d& n = A.c->n;
      const Eigen::Vector3d t1 = n.unitOrthogonal(), t2 = n.cross(t1);
      R[i].row(0) = -n.transpose();
      R[i].row(1) = t1.transpose();
      R[i].row(2) = t2.transpose();
      const Eigen::Vector3d moveA = A.c->point(A.surf->mstate().x(st)) - A.c->p0;
      const Eigen::Vector3d moveB = B.c->point(B.surf->mstate().x(st)) - B.c->p0;
      const double gap = A.surf->gapAt(st, *A.c, A.surf->mstate().x(st));
      const double slip = slipShare(A.c->gap0, gap, moveA.norm() + moveB.norm());
      dfree[i] = Eigen::Vector3d(gap, slip * t1.dot(moveA - moveB), slip * t2.dot(moveA - moveB));
    }
    Eigen::MatrixXd W = Eigen::MatrixXd::Zero(3 * m, 3 * m);
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < m; ++j) {
        Eigen::Matrix3d Cij = Eigen::Matrix3d::Zero();
        for (const Side& u : pairs[i])
          for (const Side& v : pairs[j])
            if (u.key() && u.key() == v.key()) Cij += u.sign * v.sign * C(u, v);
        W.block<3, 3>(3 * i, 3 * j) = R[i] * Cij * R[j].transpose();
      }
    gaussSeidel(l, W, dfree, mu, lambda);
    // Forces on each side, then every moving body corrected once.
    std::unordered_map<const void*, Eigen::Matrix3Xd> nodeForces;
    std::unordered_map<const void*, Eigen::Matrix<double, 6, 1>> wrenches;
    for (int i = 0; i < m; ++i) {
      const Eigen::Vector3d f = R[i].transpose() * lambda[i];
      for (const Side& sd : pairs[i]) {
        Contact& rec = *sd.c;
        rec.force = sd.sign * f;
        rec.active = lambda[i][0] > 0;
        if (sd.rigid) {
          auto [it, fresh] = wrenches.try_emplace(sd.key(), Eigen::Matrix<double, 6, 1>::Zero());
          it->second.head<3>() += rec.force;
          it->second.tail<3>() += sd.arm.cross(rec.force);
        } else if (sd.deformable) {
          auto [it, fresh] = nodeForces.try_emplace(sd.key(), Eigen::Matrix3Xd::Zero(3, sd.surf->mstate().size()));
          for (int a = 0; a < sd.c->count; ++a) it->second.col(sd.c->nodes[a]) += sd.c->w[a] * rec.force;
        }
      }
    }
    // Every moving body once; all are put back if any comes out non-finite.
    std::vector<std::pair<MechanicalObject::Live*, std::array<Eigen::Matrix3Xd, 2>>> keptDeformable;
    std::vector<std::pair<const RigidConstraintCorrection*, RigidObject::Live>> keptRigid;
    bool finite = true;
    std::string failed;
    for (const auto& p : pairs)
      for (const Side& sd : p) {
        if (sd.rigid && wrenches.count(sd.key())) {
          RigidObject::Live& b = sd.rigid->body().live(st);
          keptRigid.emplace_back(sd.rigid, b);
          sd.rigid->apply(st, rigidC.at(sd.key()), wrenches.at(sd.key()), h);
          wrenches.erase(sd.key());
          if (!b.p.allFinite() || !b.v.allFinite() || !b.w.allFinite() || !b.q.coeffs().allFinite()) {
            finite = false;
            failed = sd.rigid->body().name();
          }
        } else if (sd.deformable && nodeForces.count(sd.key())) {
          ConstraintCorrection::Live& cl = *deformableLive.at(sd.key());
          MechanicalObject::Live& s = sd.surf->mstate().live(st);
          keptDeformable.push_back({&s, {s.x, s.v}});
          Eigen::Matrix3Xd dx;
          sd.deformable->apply(cl, nodeForces.at(sd.key()), dx);
          s.x += dx;
          if (cl.resp.vFactor != 0) s.v += dx * (cl.resp.vFactor / cl.resp.xFactor);
          nodeForces.erase(sd.key());
          if (!s.x.allFinite() || !s.v.allFinite()) {
            finite = false;
            failed = sd.surf->mstate().name();
          }
        }
      }
    if (finite) return std::nullopt;
    for (auto& [s, xv] : keptDeformable) {
      s->x = xv[0];
      s->v = xv[1];
    }
    for (auto& [c, b] : keptRigid) {
      c->body().live(st) = b;
      c->remap(st);
    }
    Diverged d;
    d.step = stepIndex;
    d.time = time;
    d.reason = "constraint solver produced non-finite forces";
    d.object = failed;
    return d;
  }

  // The share of a step's relative tangential motion that friction acts on, from the gap at
  // detection g0 and after the free motion g (SOFA's rule): a contact whose gap changes sign within
  // the step slips only after that, from the fraction tau = g0 / (g0 - g) of the step; one that
  // stays open resists none, one that stays closed all of it.
  static double slipShare(double g0, double g, double travel) {
    if (std::abs(g0) < 1e-5 * travel && std::abs(g) < 1e-5 * travel) return 1;
    if (std::abs(g0 - g) > 1e-3 * g0) {
      const double tau = g0 / (g0 - g);
      if (tau > 0 && tau < 1) return 1 - tau;
      return g < 0 ? 1 : 0;
    }
    return 1;
  }

  static Eigen::Matrix3d skew(const Eigen::Vector3d& r) {
    Eigen::Matrix3d S;
    S << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
    return S;
  }

  // Coulomb's sliding force for one contact whose slip is s(l) = W l + b: the force of norm lim that
  // opposes its own slip, s = -a l / lim with a >= 0, i.e. l = -(W + beta I)^-1 b with |l| = lim
  // (beta = a / lim). |l(beta)| falls from the sticking force's norm (> lim) as beta grows; Newton
  // on 1 / |l| - 1 / lim, nearly linear in beta, finds it in a few steps. (Projecting the
  // sticking force onto the cone instead would oppose the force to W^-1 s, which is not Coulomb's
  // law where W is anisotropic, as at a contact off a rigid body's centre.)
  static Eigen::Vector2d slidingForce(const Eigen::Matrix2d& W, const Eigen::Vector2d& b, double lim) {
    if (!(lim > 0)) return Eigen::Vector2d::Zero();
    // A singular W (a node held along one tangent) starts just off zero, where W + beta I inverts.
    const double tr = W.trace();
    double beta = W.determinant() > 1e-12 * tr * tr ? 0.0 : 1e-9 * tr + 1e-300;
    Eigen::Vector2d l = Eigen::Vector2d::Zero();
    for (int k = 0; k < 50; ++k) {
      const Eigen::Matrix2d Ab = W + beta * Eigen::Matrix2d::Identity();
      l = -Ab.inverse() * b;
      const double n = l.norm();
      if (std::abs(n - lim) <= 1e-12 * lim) break;
      const Eigen::Vector2d q = Ab.inverse() * l;  // d l / d beta = -q
      beta = std::max(beta, beta + (n - lim) / lim * n * n / std::max(l.dot(q), 1e-300));
    }
    return l * (lim / std::max(l.norm(), 1e-300));
  }

  // Projected Gauss-Seidel: each contact's local problem in turn, until no force changes by more
  // than tolerance x the largest force.
  void gaussSeidel(Live& l, const Eigen::MatrixXd& W, const std::vector<Eigen::Vector3d>& dfree, double mu,
                   std::vector<Eigen::Vector3d>& lambda) const {
    const int m = static_cast<int>(dfree.size());
    double last = 0;
    for (int it = 0; it < maxIt_; ++it) {
      double change = 0, scale = 1e-300;
      for (int i = 0; i < m; ++i) {
        Eigen::Vector3d d = dfree[i];
        for (int j = 0; j < m; ++j) d += W.block<3, 3>(3 * i, 3 * j) * lambda[j];
        const Eigen::Matrix3d Wii = W.block<3, 3>(3 * i, 3 * i);
        if (!(Wii(0, 0) > 0)) continue;  // nothing the contact could move (fixed nodes, a held body)
        Eigen::Vector3d li = lambda[i];
        // Normal: make the gap zero if that pushes, else release.
        li[0] = std::max(0.0, li[0] - d[0] / Wii(0, 0));
        d += Wii.col(0) * (li[0] - lambda[i][0]);
        // Tangential: stick (zero slip) when that force is inside the cone |l_t| <= mu l_n, else
        // slide with the force on the cone opposing the slip (slidingForce).
        const Eigen::Matrix2d Wtt = Wii.block<2, 2>(1, 1);
        const Eigen::Vector2d b = d.tail<2>() - Wtt * li.tail<2>();  // slip = Wtt l_t + b
        Eigen::Vector2d lt = -Wtt.ldlt().solve(b);
        const double lim = mu * li[0];
        if (lt.norm() > lim) lt = slidingForce(Wtt, b, lim);
        li.tail<2>() = lt;
        change = std::max(change, (li - lambda[i]).norm());
        scale = std::max(scale, li.norm());
        lambda[i] = li;
      }
      l.iterations = std::max(l.iterations, it + 1);
      last = change / scale;
      if (last <= tol_) break;
    }
    l.residual = std::max(l.residual, last);  // the worst of the step's problems
  }

  std::optional<Diverged> solveBody(State& st, const SurfaceCollisionModel& surf, const ConstraintCorrection& cc,
                                    double mu, double h, int stepIndex, double time) const {
    Live& l = stateIn<Live>(st);
    const MechanicalObject& body = surf.mstate();
    MechanicalObject::Live& s = body.live(st);
    // The contacts with instruments' spheres (those with other bodies are solved in solvePairs).
    std::vector<Contact*> cs;
    for (Contact& c : surf.contacts(st))
      if (c.sphere) cs.push_back(&c);
    const int m = static_cast<int>(cs.size());
    ConstraintCorrection::Live& ccl = cc.prepare(st, h);
    // Rows R_i = [-n^T; t1^T; t2^T] acting on the contact point.
    std::vector<Eigen::Matrix3d> R(m);
    std::vector<Eigen::Vector3d> dfree(m), lambda(m, Eigen::Vector3d::Zero());
    for (int i = 0; i < m; ++i) {
      const Contact& c = *cs[i];
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
        for (int a = 0; a < cs[i]->count; ++a)
          for (int b = 0; b < cs[j]->count; ++b) Cij += cs[i]->w[a] * cs[j]->w[b] * cc.block(ccl, cs[i]->nodes[a], cs[j]->nodes[b]);
        W.block<3, 3>(3 * i, 3 * j) = R[i] * Cij * R[j].transpose();
      }
    gaussSeidel(l, W, dfree, mu, lambda);
    // Correct the free motion: forces on the nodes, displacement C F, velocity to match.
    Eigen::Matrix3Xd F = Eigen::Matrix3Xd::Zero(3, body.size()), dx;
    for (int i = 0; i < m; ++i) {
      Contact& c = *cs[i];
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
  bool lcp_ = false;
  std::vector<ConstraintCorrection*> corrections_;
  std::vector<RigidConstraintCorrection*> rigidCorrections_;
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
    s.add(AttrSpec::real("mu").atLeast(0).help(
        "friction coefficient: GenericConstraintSolver, when given, in place of the CollisionResponse's; "
        "LCPConstraintSolver (as SOFA's), for every contact whose response has friction (0.6 unless given)"));
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
       "model of soft tissue; for comparison with SOFA scenes. In a rigid body's node: the body's mass and inertia "
       "over its solver's step (any of the three corrections)."}};
  for (auto& c : corr) {
    ComponentSpec s;
    s.name = c[0];
    if (std::string(c[0]) == "LinearSolverConstraintCorrection") s.aliases = {"GenericConstraintCorrection"};
    s.category = "collision";
    s.doc = c[1];
    s.add(AttrSpec::string("solverName").def("").help("accepted for SOFA scenes; the node's solver is used"));
    s.add(AttrSpec::reals("compliance").help(
        "rigid body: 1/m and the upper inverse inertia (xx xy xz yy yz zz) in place of the mass's; deformable body: "
        "accepted for SOFA scenes, the compliance comes from the mass and the step matrix"));
    s.add(AttrSpec::boolean("wire_optimization").def("false").help("accepted for SOFA scenes"));
    s.add(AttrSpec::link("linearSolver").help("accepted for SOFA scenes; the node's solver is used"));
    s.add(AttrSpec::real("defaultCompliance").atLeast(0).help(
        "rigid bodies only: 1/m in place of the mass's, with unit rotational compliance (as SOFA)"));
    s.add(AttrSpec::boolean("useOdeSolverIntegrationFactors").def("true").help(
        "rigid bodies only, accepted for SOFA scenes: the compliance always follows the solver's step (a force over "
        "the step moves the body by h^2 / (1 + h rayleighMass) M^-1 F)"));
    s.add(AttrSpec::link("mstate").help("the body (default: the one in the node)"));
    s.factory = [](BuildContext& ctx) -> std::unique_ptr<Component> {
      if (ctx.node().find<RigidObject>() && !ctx.node().find<MechanicalObject>()) return std::make_unique<RigidConstraintCorrection>(ctx);
      return std::make_unique<ConstraintCorrection>(ctx);
    };
    r.add(std::move(s));
  }
}

}  // namespace viscera
