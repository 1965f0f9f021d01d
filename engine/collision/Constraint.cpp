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
// relative motion of the two sides, and are solved together (solvePairs), with the bilateral
// constraints (BilateralLagrangianConstraint: three equality rows per pair of held points).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <mutex>
#include <random>
#include <unordered_map>

#include "engine/MechanicalSystem.h"
#include "engine/rigid/RigidDynamics.h"
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
    regularization_ = attrs_.real("regularizationTerm");
    mode_ = t == "UncoupledConstraintCorrection" ? Mode::Uncoupled
            : t == "LinearSolverConstraintCorrection" || t == "GenericConstraintCorrection" ? Mode::LinearSolver
                                                                                            : Mode::Precomputed;
    sys_ = std::make_unique<MechanicalSystem>(*this);
    auto* ode = node().find<OdeSolver>();
    if (!ode && integratingNode(sys_->state()))
      throw error("its body is integrated by the solver in " + integratingNode(sys_->state())->path() +
                  " above it, with other bodies; a constraint correction needs the body's own solver in its node");
    if (!ode) throw error("needs the body's ODE solver (EulerImplicitSolver, symplectic EulerExplicitSolver or StaticSolver) in its node");
    scene().initComponent(dynamic_cast<Component&>(*ode));
    ode_ = ode;
    // Springs to another object enter the body's step, not its compliance here: refuse rather
    // than correct contacts with a softer body than the one that moved.
    for (InteractionForceField* ff : scene().all<InteractionForceField>()) {
      scene().initComponent(dynamic_cast<Component&>(*ff));
      if (&ff->object(0) == &ff->object(1) || !ff->solverNode()) continue;
      if (&ff->object(0) == &sys_->state() || &ff->object(1) == &sys_->state())
        throw error("its body '" + sys_->state().name() + "' is tied to another object by " +
                    dynamic_cast<Component&>(*ff).typeName() + " '" + dynamic_cast<Component&>(*ff).name() +
                    "', which the contact compliance does not include");
    }
    auto r = ode->stepResponse(scene().dt());
    if (!r)
      throw error("the ODE solver in its node gives no step response to correct (EulerImplicitSolver, symplectic "
                  "EulerExplicitSolver and StaticSolver do)");
    if (mode_ == Mode::Uncoupled && !(r->mFactor > 0))
      throw error("the uncoupled (mass-only) compliance needs a dynamic solver (EulerImplicitSolver or symplectic EulerExplicitSolver)");
    if (mode_ != Mode::Uncoupled) sys_->prepareAssembly();
    // The compliance at rest for the scene's step, factorised once and shared by every simulation.
    if (mode_ == Mode::Precomputed) {
      restDt_ = scene().dt();
      rest_ = std::make_shared<CholmodSolver>();
      factorizeAt(sys_->state().x0, *r, *rest_);
    }
  }

  MechanicalObject& mstate() const { return sys_->state(); }
  // Added to the compliance of every constraint row on this body (SOFA's regularizationTerm).
  double regularization() const { return regularization_; }

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
      // The system of the free motion: linearised where its step started (the positions now are
      // the free motion's end), so that the correction completes that step's constrained solve.
      const Eigen::Matrix3Xd* at = ode_->linearisedAt(st);
      const Eigen::Matrix3Xd& x = sys_->state().x(st);
      // In a copy of the force fields' blocks: the step's own are left as they are (a plastic
      // strain must not creep a second time in the step).
      State scratch = scratchState(&st);
      factorizeAt(scratch, at && at->cols() == x.cols() ? *at : x, l.resp, l.A, l.chol.get());
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

  // Whether linearising the body reads this component's block: the body's force fields and the
  // springs with both ends on it.
  bool linearisedBy(const Stateful* c) const {
    const auto& forces = sys_->forceFields();
    if (auto* f = dynamic_cast<const ForceField*>(c); f && std::find(forces.begin(), forces.end(), f) != forces.end()) return true;
    const auto& internal = sys_->internalForces();
    auto* i = dynamic_cast<const InteractionForceField*>(c);
    return i && std::find(internal.begin(), internal.end(), i) != internal.end();
  }
  // A scratch state for linearising the body: the blocks linearisedBy reads, copied from `from`
  // or, with none, at their initial values; no other block is read.
  State scratchState(const State* from) const {
    State out;
    std::vector<Stateful*> stateful = scene().all<Stateful>();
    for (size_t i = 0; i < stateful.size(); ++i) {
      if (stateful[i]->stateSlot() < 0) stateful[i]->setStateSlot(static_cast<int>(i));
      std::unique_ptr<ComponentState> block;
      if (linearisedBy(stateful[i]))
        block = from ? from->of<ComponentState>(stateful[i]->stateSlot()).clone() : stateful[i]->initialState();
      out.add("", std::move(block));
    }
    return out;
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
    State rest = scratchState(nullptr);
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
  double regularization_ = 0;
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
    regularization_ = attrs_.real("regularizationTerm");
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
  // Added to the compliance of every constraint row on this body (SOFA's regularizationTerm).
  double regularization() const { return regularization_; }

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
    const auto r = ode_->rigidStepResponse(h);
    if (!r || !(r->xFactor > 0))
      throw error("the solver moving rigid body '" + body_->name() +
                  "' gives no step response (use EulerImplicitSolver, or EulerExplicitSolver with symplectic=\"true\")");
    return *r;
  }

  RigidObject* body_ = nullptr;
  OdeSolver* ode_ = nullptr;
  double regularization_ = 0;
  bool given_ = false;
  double linear_ = 0;
  Eigen::Matrix3d rotational_ = Eigen::Matrix3d::Identity();
  std::vector<const RigidMapping*> mappings_;
};

// SOFA's BilateralLagrangianConstraint (Vec3): pairs of points, one on each of two states, held
// at a fixed offset at the end of every step: p2 - p1 = rest (zero unless rest_vector is given).
// A point is a node of a body solved in its node, a point mapped from a body (RigidMapping from a
// rigid body, a barycentric mapping from a deformable one), or a point of a state that nothing
// moves (it stays where it is). The constraint's force lambda acts on point 2 and -lambda on
// point 1; the constraint solver finds it together with the contacts between bodies.
class BilateralConstraint : public Component {
 public:
  using Component::Component;
  // One point of a pair: where it is and what moves it.
  struct Point {
    const MechanicalObject* at = nullptr;     // the state whose nodes place the point (where.nodes index it)
    const MechanicalObject* body = nullptr;   // the deformable body it moves with (== at), if any
    const RigidObject* rigid = nullptr;       // the rigid body it is fixed to (at: the mapped state), if any
    Contact where;                            // the point as a weighted sum of at's nodes
  };
  void init() override {
    if (scene().all<ConstraintSolver>().empty())
      throw error("needs a constraint solver (GenericConstraintSolver) and FreeMotionAnimationLoop in the root node: "
                  "without them nothing holds the points");
    MechanicalObject* obj[2];
    const char* attr[2] = {"object1", "object2"};
    for (int k = 0; k < 2; ++k) {
      if (!attrs_.isSet(attr[k])) throw error(attr[k], "is needed: the MechanicalObject (Vec3d) whose points are held");
      // SOFA's link to a state may name its node.
      Component* c = nullptr;
      try {
        c = linkedComponent(attr[k]);
      } catch (const Error&) {
        const Node* n = linkedNode(node(), attrs_.get(attr[k]).text);
        if (!n || !n->find<MechanicalObject>()) throw;
        c = n->find<MechanicalObject>();
        scene().initComponent(*c);
      }
      obj[k] = dynamic_cast<MechanicalObject*>(c);
      if (!obj[k])
        throw error(attr[k], "links to '" + c->name() + "', a " + c->typeName() +
                                 "; it must be a Vec3d MechanicalObject (for a rigid body, a point mapped from it by RigidMapping)");
      scene().initComponent(*obj[k]);
      for (const auto& m : obj[k]->node().components())
        if (dynamic_cast<Mapping*>(m.get())) scene().initComponent(*m);
    }
    auto points = [](size_t n) { return std::to_string(n) + (n == 1 ? " point" : " points"); };
    std::vector<int> first = linkedInts("first_point"), second = linkedInts("second_point");
    if (!attrs_.isSet("first_point") && !attrs_.isSet("second_point")) {
      if (obj[0]->size() != obj[1]->size())
        throw error("first_point", "is needed: '" + obj[0]->name() + "' has " + points(obj[0]->size()) + " and '" +
                                       obj[1]->name() + "' " + points(obj[1]->size()) + ", so they do not pair one to one");
      for (int i = 0; i < obj[0]->size(); ++i) first.push_back(i);
      second = first;
    }
    if (first.size() != second.size())
      throw error("second_point", "has " + points(second.size()) + " and first_point " + points(first.size()) +
                                      "; they pair one to one");
    const std::vector<double> rest = attrs_.reals("rest_vector");
    if (!rest.empty() && rest.size() != 3 * first.size())
      throw error("rest_vector", "has " + std::to_string(rest.size()) + " numbers; it needs 3 per pair (" +
                                     std::to_string(3 * first.size()) + ")");
    for (size_t i = 0; i < first.size(); ++i) {
      pairs_.push_back({attach(*obj[0], first[i], "first_point"), attach(*obj[1], second[i], "second_point")});
      rest_.push_back(rest.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(rest[3 * i], rest[3 * i + 1], rest[3 * i + 2]));
    }
    active_ = attrs_.boolean("activate");
    endTime_ = attrs_.real("endTime");
  }
  // Whether the constraint acts over a step that ends at `time`.
  bool acts(double time) const { return active_ && (endTime_ < 0 || time <= endTime_); }
  const std::vector<std::array<Point, 2>>& pairs() const { return pairs_; }
  const Eigen::Vector3d& rest(int i) const { return rest_[i]; }

 private:
  Point attach(MechanicalObject& s, int i, const char* attr) const {
    if (i < 0 || i >= s.size())
      throw error(attr, "point " + std::to_string(i) + " is not a point of '" + s.name() + "' (" + std::to_string(s.size()) + " points)");
    Point p;
    p.at = &s;
    p.where.count = 1;
    p.where.nodes[0] = i;
    p.where.w[0] = 1;
    if (const auto* rm = dynamic_cast<const RigidMapping*>(s.mappedBy())) {
      p.rigid = &rm->body();
    } else if (const Component* by = s.mappedBy()) {
      const auto* m = dynamic_cast<const Mapping*>(by);
      std::vector<std::pair<int, double>> weights;
      if (!m || !m->inputState() || !m->pointWeights(i, weights))
        throw error(attr, "'" + s.name() + "' is mapped by " + by->typeName() + ", which does not give point " +
                              std::to_string(i) + " as a weighted sum of a body's nodes");
      if (weights.size() > static_cast<size_t>(kMaxContactNodes))
        throw error(attr, "point " + std::to_string(i) + " of '" + s.name() + "' depends on more than " +
                              std::to_string(kMaxContactNodes) + " nodes of its body");
      p.at = m->inputState();
      // A body nothing integrates holds the point where it is.
      if (integratingNode(*p.at)) p.body = p.at;
      p.where.count = static_cast<int>(weights.size());
      for (size_t k = 0; k < weights.size(); ++k) {
        p.where.nodes[k] = weights[k].first;
        p.where.w[k] = weights[k].second;
      }
    } else if (integratingNode(s)) {
      p.body = &s;
    }
    return p;
  }

  std::vector<std::array<Point, 2>> pairs_;
  std::vector<Eigen::Vector3d> rest_;
  bool active_ = true;
  double endTime_ = -1;
};

class GenericConstraintSolver : public Component, public ConstraintSolver, public Stateful {
 public:
  using Component::Component;
  // Each step starts from zero impulses: only the last step's statistics carry over.
  struct Live : ComponentStateOf<Live> {
    int iterations = 0;
    double residual = 0;
    std::uint64_t orderSeed = 0;  // shuffleOrder's seed; 0: the constraints in the order built
    void save(StateWriter& out) const override {
      out.put(iterations);
      out.put(residual);
      out.put(orderSeed);
    }
    void load(StateReader& in) override {
      in.get(iterations);
      in.get(residual);
      in.get(orderSeed);
    }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  void init() override {
    maxIt_ = static_cast<int>(attrs_.integer("maxIterations"));
    tol_ = attrs_.real("tolerance");
    regularization_ = attrs_.real("regularizationTerm");
    svdRegularization_ = attrs_.boolean("useSVDForRegularization");
    // SOFA's LCPConstraintSolver applies its own mu (0.6 unless given) to every contact that has
    // friction at all (a response mu above 0); GenericConstraintSolver's given mu replaces the response's.
    lcp_ = attrs_.component() == "LCPConstraintSolver";  // an alias: the tag as written
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
    for (BilateralConstraint* b : scene().all<BilateralConstraint>()) {
      scene().initComponent(*b);
      bilaterals_.push_back(b);
    }
  }

  std::optional<Diverged> solve(State& st, const CollisionPipeline* pipe, double h, int stepIndex,
                                double time) const override {
    Live& l = stateIn<Live>(st);
    l.iterations = 0;
    l.residual = 0;
    // Contacts take constraints under a constraint response; bilateral constraints always do.
    if (pipe && pipe->settings().response != ContactSettings::Response::Constraint) pipe = nullptr;
    double mu = 0;
    if (pipe) {
      mu = muOverride_ < 0 ? pipe->settings().mu : lcp_ && !(pipe->settings().mu > 0) ? 0.0 : muOverride_;
      for (const SurfaceCollisionModel* surf : pipe->surfaces()) {
        if (!surf->active() || surf->rigidBody() || surf->isStatic()) continue;
        const auto& cs = surf->contacts(st);
        if (std::none_of(cs.begin(), cs.end(), [](const Contact& c) { return c.sphere; })) continue;
        if (auto bad = solveBody(st, *surf, deformableCorrection(surf->mstate(), *surf), mu, h, stepIndex, time)) return bad;
      }
    }
    return solvePairs(st, pipe, mu, h, stepIndex, time);
  }
  int lastIterations(const State& s) const override { return stateIn<Live>(s).iterations; }
  double lastResidual(const State& s) const override { return stateIn<Live>(s).residual; }
  void shuffleOrder(State& s, std::uint64_t seed) const override { stateIn<Live>(s).orderSeed = seed; }

 private:
  bool hasAnimationLoop() const {
    for (const auto& c : scene().root().components())
      if (c->typeName() == "FreeMotionAnimationLoop") return true;
    return false;
  }
  // The correction of deformable body `body`; `who` (a surface or a bilateral constraint) names the error.
  const ConstraintCorrection& deformableCorrection(const MechanicalObject& body, const Component& who) const {
    for (ConstraintCorrection* c : corrections_)
      if (&c->mstate() == &body) return *c;
    throw who.error("constraints on '" + body.name() + "' need a constraint correction in its node "
                    "(PrecomputedConstraintCorrection, LinearSolverConstraintCorrection or UncoupledConstraintCorrection)");
  }
  // The correction of rigid body b, or null when nothing moves the body.
  const RigidConstraintCorrection* rigidCorrection(const RigidObject& b, const Component& who) const {
    for (RigidConstraintCorrection* c : rigidCorrections_)
      if (&c->body() == &b) return c->moves() ? c : nullptr;
    if (b.driven || !(b.mass > 0) || b.prescribedVelocity) return nullptr;
    throw who.error("constraints on rigid body '" + b.name() + "' need UncoupledConstraintCorrection in its node");
  }

  // One side of a constraint between two bodies (a contact, or a pair of held points): the body
  // that moves under it (none for a fixed surface, a driven body or a state nothing moves), how the
  // point follows it, and the sign of the force on it.
  struct Side {
    const SurfaceCollisionModel* surf = nullptr;  // contacts: the surface
    const MechanicalObject* at = nullptr;         // the state whose nodes place the point
    Contact* c = nullptr;  // this side's record: the contact's (the pair's, or its mirror), or the held point
    const ConstraintCorrection* deformable = nullptr;
    const RigidConstraintCorrection* rigid = nullptr;
    Eigen::Vector3d arm = Eigen::Vector3d::Zero();  // rigid: point - body origin
    double sign = 1;
    const void* key() const { return deformable ? static_cast<const void*>(deformable) : static_cast<const void*>(rigid); }
    Eigen::Vector3d point(const State& st) const { return c->point(at->x(st)); }
    double regularization() const { return deformable ? deformable->regularization() : rigid ? rigid->regularization() : 0.0; }
  };
  // A contact's two sides (normal and friction rows), or a held pair's (three equality rows).
  struct Pair {
    std::array<Side, 2> side;
    const BilateralConstraint* bilateral = nullptr;
    int index = 0;  // the bilateral constraint's pair
  };

  // Contacts between the surfaces of two bodies (a vertex of one against a feature of the other)
  // and bilateral constraints, solved together: a body touching several others couples their
  // rows. A contact's force lambda pushes the first side along -n and the second along +n; a held
  // pair's pulls point 2 by +lambda and point 1 by -lambda. The Delassus operator sums each moving
  // body's compliance between the points (a rigid body's C(p, q) = J_p C J_q^T with
  // J_p = [I, -[p - origin]x]).
  std::optional<Diverged> solvePairs(State& st, const CollisionPipeline* pipe, double mu, double h, int stepIndex,
                                     double time) const {
    std::vector<Pair> pairs;
    // A rigid side is linearised about the body's pose at the step start, as SOFA maps its free
    // motion to the points: the arm r is the point's then (a contact's point at detection from the
    // centre, which the free motion moved by h v; a held point's arm turned back by the step's
    // rotation), and the point's free motion is h (v + w x r), not the turned point's (freeMove,
    // freePoint below).
    auto attach = [&](Side& sd, const MechanicalObject* body, const RigidObject* rigid, const Component& who) {
      if (rigid) {
        sd.rigid = rigidCorrection(*rigid, who);
        if (!sd.rigid) return;
        const RigidObject::Live& b = sd.rigid->body().live(st);
        if (sd.surf) sd.arm = sd.c->p0 - (b.p - h * b.v);
        else {
          const double angle = h * b.w.norm();
          sd.arm = sd.point(st) - b.p;
          if (angle > 0) sd.arm = Eigen::AngleAxisd(-angle, b.w.normalized()) * sd.arm;
        }
      } else if (body) {
        sd.deformable = &deformableCorrection(*body, who);
      }
    };
    if (pipe) {
      const auto& surfaces = pipe->surfaces();
      auto indexOf = [&](const SurfaceCollisionModel* m) {
        return static_cast<int>(std::find(surfaces.begin(), surfaces.end(), m) - surfaces.begin());
      };
      for (int si = 0; si < static_cast<int>(surfaces.size()); ++si) {
        const SurfaceCollisionModel* a = surfaces[si];
        if (!a->active()) continue;
        auto& cs = a->contacts(st);
        for (int ci = 0; ci < static_cast<int>(cs.size()); ++ci) {
          Contact& c = cs[ci];
          if (!c.partner) continue;
          const int pi = indexOf(c.partner);
          if (std::make_pair(pi, c.mirror) < std::make_pair(si, ci)) continue;  // the pair is taken from its other side
          if (c.mirror >= static_cast<int>(c.partner->contacts(st).size()))
            throw Error("contact state of '" + a->name() + "' names contact " + std::to_string(c.mirror) + " of '" +
                        c.partner->name() + "', which has " + std::to_string(c.partner->contacts(st).size()) +
                        ": the state belongs to another run");
          Pair p;
          p.side[0].surf = a;
          p.side[0].c = &c;
          p.side[1].surf = c.partner;
          p.side[1].c = &c.partner->contacts(st)[c.mirror];
          p.side[1].sign = -1;
          for (Side& sd : p.side) {
            sd.at = &sd.surf->mstate();
            if (!sd.surf->isStatic()) attach(sd, &sd.surf->mstate(), sd.surf->rigidBody(), *sd.surf);
          }
          if (p.side[0].key() || p.side[1].key()) pairs.push_back(p);
        }
      }
    }
    // Held points: their records live for this solve only.
    size_t held = 0;
    for (const BilateralConstraint* b : bilaterals_)
      if (b->acts(time)) held += 2 * b->pairs().size();
    std::vector<Contact> points;
    points.reserve(held);
    for (const BilateralConstraint* b : bilaterals_) {
      if (!b->acts(time)) continue;
      for (int i = 0; i < static_cast<int>(b->pairs().size()); ++i) {
        Pair p;
        p.bilateral = b;
        p.index = i;
        p.side[1].sign = -1;
        for (int k = 0; k < 2; ++k) {
          const BilateralConstraint::Point& pt = b->pairs()[i][k];
          points.push_back(pt.where);
          p.side[k].c = &points.back();
          p.side[k].at = pt.at;
          attach(p.side[k], pt.body, pt.rigid, *b);
        }
        if (p.side[0].key() || p.side[1].key()) pairs.push_back(p);
      }
    }
    if (pairs.empty()) return std::nullopt;
    Live& l = stateIn<Live>(st);
    reorder(l, stepIndex, pairs);
    const int m = static_cast<int>(pairs.size());
    std::unordered_map<const void*, ConstraintCorrection::Live*> deformableLive;
    std::unordered_map<const void*, Eigen::Matrix<double, 6, 6>> rigidC;
    for (const auto& p : pairs)
      for (const Side& sd : p.side) {
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
    // Contacts: rows [-n; t1; t2] of the first side's normal, free gap and slip. Held pairs: rows
    // -I (force -lambda on point 1), free value p2 - p1 - rest.
    std::vector<Eigen::Matrix3d> R(m);
    std::vector<Eigen::Vector3d> dfree(m), lambda(m, Eigen::Vector3d::Zero());
    std::vector<char> equality(m, 0);
    for (int i = 0; i < m; ++i) {
      const Side &A = pairs[i].side[0], &B = pairs[i].side[1];
      if (const BilateralConstraint* b = pairs[i].bilateral) {
        equality[i] = 1;
        R[i] = -Eigen::Matrix3d::Identity();
        const auto freePoint = [&](const Side& sd) -> Eigen::Vector3d {
          if (!sd.rigid) return sd.point(st);
          const RigidObject::Live& rb = sd.rigid->body().live(st);
          return rb.p + sd.arm + h * rb.w.cross(sd.arm);
        };
        dfree[i] = freePoint(B) - freePoint(A) - b->rest(pairs[i].index);
        continue;
      }
      const Eigen::Vector3d& n = A.c->n;
      const Eigen::Vector3d t1 = n.unitOrthogonal(), t2 = n.cross(t1);
      R[i].row(0) = -n.transpose();
      R[i].row(1) = t1.transpose();
      R[i].row(2) = t2.transpose();
      // The free motion of each side's point since detection, and the gap it leaves along n.
      const auto freeMove = [&](const Side& sd) -> Eigen::Vector3d {
        if (!sd.rigid) return sd.point(st) - sd.c->p0;
        const RigidObject::Live& b = sd.rigid->body().live(st);
        return h * (b.v + b.w.cross(sd.arm));
      };
      const Eigen::Vector3d moveA = freeMove(A), moveB = freeMove(B);
      const double gap = A.c->gap0 - n.dot(moveA) + n.dot(moveB);
      const double slip = slipShare(A.c->gap0, gap, moveA.norm() + moveB.norm());
      dfree[i] = Eigen::Vector3d(gap, slip * t1.dot(moveA - moveB), slip * t2.dot(moveA - moveB));
    }
    Eigen::MatrixXd W = Eigen::MatrixXd::Zero(3 * m, 3 * m);
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < m; ++j) {
        Eigen::Matrix3d Cij = Eigen::Matrix3d::Zero();
        for (const Side& u : pairs[i].side)
          for (const Side& v : pairs[j].side)
            if (u.key() && u.key() == v.key()) Cij += u.sign * v.sign * C(u, v);
        W.block<3, 3>(3 * i, 3 * j) = R[i] * Cij * R[j].transpose();
      }
    for (int i = 0; i < m; ++i) {  // R is orthonormal: a body's eps I stays eps I in the rows
      const Side &u = pairs[i].side[0], &v = pairs[i].side[1];
      double eps = u.regularization();
      if (v.key() != u.key()) eps += v.regularization();  // once per body, as solveBody
      W.block<3, 3>(3 * i, 3 * i).diagonal().array() += eps;
    }
    regularize(W);
    gaussSeidel(l, W, dfree, mu, lambda, equality);
    // Forces on each side, then every moving body corrected once.
    std::unordered_map<const void*, Eigen::Matrix3Xd> nodeForces;
    std::unordered_map<const void*, Eigen::Matrix<double, 6, 1>> wrenches;
    for (int i = 0; i < m; ++i) {
      const Eigen::Vector3d f = R[i].transpose() * lambda[i];
      for (const Side& sd : pairs[i].side) {
        Contact& rec = *sd.c;
        rec.force = sd.sign * f;
        rec.active = lambda[i][0] > 0;
        if (sd.rigid) {
          auto [it, fresh] = wrenches.try_emplace(sd.key(), Eigen::Matrix<double, 6, 1>::Zero());
          it->second.head<3>() += rec.force;
          it->second.tail<3>() += sd.arm.cross(rec.force);
        } else if (sd.deformable) {
          auto [it, fresh] = nodeForces.try_emplace(sd.key(), Eigen::Matrix3Xd::Zero(3, sd.at->size()));
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
      for (const Side& sd : p.side) {
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
          MechanicalObject::Live& s = sd.at->live(st);
          keptDeformable.push_back({&s, {s.x, s.v}});
          Eigen::Matrix3Xd dx;
          sd.deformable->apply(cl, nodeForces.at(sd.key()), dx);
          s.x += dx;
          if (cl.resp.vFactor != 0) s.v += dx * (cl.resp.vFactor / cl.resp.xFactor);
          nodeForces.erase(sd.key());
          if (!s.x.allFinite() || !s.v.allFinite()) {
            finite = false;
            failed = sd.at->name();
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
  // The solver's regularisation: eps I added to W, or (useSVDForRegularization) W's eigenvalues
  // below eps raised to eps, which leaves a well-posed problem alone. Either makes redundant rows
  // (more held points than the bodies' freedoms) solvable, at the price of holding them a little
  // less exactly.
  void regularize(Eigen::MatrixXd& W) const {
    if (!(regularization_ > 0)) return;
    if (!svdRegularization_) {
      W.diagonal().array() += regularization_;
      return;
    }
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(W);
    const Eigen::VectorXd lifted = eig.eigenvalues().cwiseMax(regularization_);
    W = eig.eigenvectors() * lifted.asDiagonal() * eig.eigenvectors().transpose();
  }

  // Rows flagged in `equality` (held points) take the force that zeroes their three values.
  void gaussSeidel(Live& l, const Eigen::MatrixXd& W, const std::vector<Eigen::Vector3d>& dfree, double mu,
                   std::vector<Eigen::Vector3d>& lambda, const std::vector<char>& equality = {}) const {
    const int m = static_cast<int>(dfree.size());
    double last = 0;
    for (int it = 0; it < maxIt_; ++it) {
      double change = 0, scale = 1e-300;
      double moved = 0;  // LCPConstraintSolver's measure: how far the sweep moved the contacts' points
      for (int i = 0; i < m; ++i) {
        Eigen::Vector3d d = dfree[i];
        for (int j = 0; j < m; ++j) d += W.block<3, 3>(3 * i, 3 * j) * lambda[j];
        const Eigen::Matrix3d Wii = W.block<3, 3>(3 * i, 3 * i);
        if (!equality.empty() && equality[i]) {
          if (!(Wii.trace() > 0)) continue;  // neither point can move
          // Least squares: a point held along some direction only (a partly fixed body) takes
          // the force it can act with.
          const Eigen::Vector3d li = lambda[i] - Wii.completeOrthogonalDecomposition().solve(d);
          change = std::max(change, (li - lambda[i]).norm());
          scale = std::max(scale, li.norm());
          lambda[i] = li;
          continue;
        }
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
        moved += (Wii * (li - lambda[i])).norm();
        lambda[i] = li;
      }
      l.iterations = std::max(l.iterations, it + 1);
      last = change / scale;
      // SOFA's LCPConstraintSolver stops on the summed displacement, below tolerance x (contacts + 1);
      // its other solvers (as here otherwise) on the change of the forces.
      if (lcp_ ? moved < tol_ * (m + 1) : last <= tol_) break;
    }
    l.residual = std::max(l.residual, last);  // the worst of the step's problems
  }

  // The constraints in the order the state asks for: as built, or shuffled by its seed and the
  // step (so that a state restored mid-run continues the same way).
  template <class T>
  static void reorder(const Live& l, int stepIndex, std::vector<T>& items) {
    if (l.orderSeed == 0) return;
    std::mt19937_64 rng(l.orderSeed * 0x9E3779B97F4A7C15ull + static_cast<std::uint64_t>(stepIndex));
    std::shuffle(items.begin(), items.end(), rng);
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
    reorder(l, stepIndex, cs);
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
    W.diagonal().array() += cc.regularization();
    regularize(W);
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
  double regularization_ = 0;
  bool svdRegularization_ = false;
  double tol_ = 1e-8;
  double muOverride_ = -1;
  bool lcp_ = false;
  std::vector<ConstraintCorrection*> corrections_;
  std::vector<RigidConstraintCorrection*> rigidCorrections_;
  std::vector<BilateralConstraint*> bilaterals_;
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
    s.aliases = {"LCPConstraintSolver", "BlockGaussSeidelConstraintSolver", "ProjectedGaussSeidelConstraintSolver",
                 "UnbuiltGaussSeidelConstraintSolver", "NNCGConstraintSolver"};
    s.category = "collision";
    s.doc = "Projected Gauss-Seidel on the Delassus operator of the contacts and bilateral constraints (3x3 block "
            "per contact pair or held pair of points): normal force >= 0 with zero gap when pushing, friction in the "
            "Coulomb cone, held points together. Stops when no force changes by more than tolerance x the largest "
            "force (LCPConstraintSolver, as SOFA's: when a sweep moves the contacts' points by less than tolerance x "
            "(contacts + 1) in all), or after maxIterations. SOFA's other solvers of the same problem (UnbuiltGaussSeidel, NNCG) take "
            "this one: they differ in how they iterate, not in the forces they converge to.";
    s.add(AttrSpec::integer("maxIterations").alias("maxIt").def("1000").atLeast(1).help("Gauss-Seidel sweeps at most"));
    s.add(AttrSpec::real("tolerance").alias("tol").def("1e-8").above(0).help(
        "relative change of the contact forces to stop at (LCPConstraintSolver: the sweep's summed displacement of "
        "the contacts' points, below tolerance x (contacts + 1))"));
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
    s.add(AttrSpec::real("regularizationTerm").def("0").atLeast(0).help(
        "added to the diagonal of the constraint compliance W (for redundant bilateral constraints)"));
    s.add(AttrSpec::boolean("useSVDForRegularization").def("false").help(
        "with regularizationTerm: raise W's eigenvalues below it to it, instead of adding it to every one"));
    s.factory = [](BuildContext& c) { return std::make_unique<GenericConstraintSolver>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "BilateralLagrangianConstraint";
    s.aliases = {"BilateralInteractionConstraint"};
    s.category = "collision";
    s.doc = "Holds pairs of points of two states together (SOFA's attachment by Lagrange multipliers): at the end "
            "of every step point 2 - point 1 = rest_vector (zero unless given), solved by the constraint solver with "
            "the contacts (needs FreeMotionAnimationLoop, a constraint solver, and a constraint correction in the node "
            "of every body that moves). A point is a node of a body, a point mapped from one (RigidMapping, "
            "BarycentricMapping), or a point of a state nothing moves, which stays where it is.";
    s.add(AttrSpec::choice("template", {"Vec3d", "Vec3", "Vec3f"}).def("Vec3d").help(
        "the points' type (Rigid3d is not handled: hold points mapped from the rigid bodies)"));
    s.add(AttrSpec::link("object1").help("the MechanicalObject of the first points"));
    s.add(AttrSpec::link("object2").help("the MechanicalObject of the second points"));
    s.add(AttrSpec::ints("first_point").atLeast(0).linked().help(
        "the points of object1 (with second_point empty too: every point, paired with the same index)"));
    s.add(AttrSpec::ints("second_point").atLeast(0).linked().help("the points of object2, one per first point"));
    s.add(AttrSpec::reals("rest_vector").unit(Dimension::length()).help(
        "point 2 - point 1 to hold, three numbers per pair (default: the points coincide)"));
    s.add(AttrSpec::boolean("activate").def("true").help("false: the constraint does nothing"));
    s.add(AttrSpec::real("endTime").def("-1").help("the constraint stops acting after this time (negative: never)"));
    s.add(AttrSpec::boolean("keepOrientationDifference").def("false").help("accepted for SOFA scenes (rigid templates only)"));
    s.add(AttrSpec::real("numericalTolerance").def("0.0001").help("accepted for SOFA scenes"));
    s.add(AttrSpec::integer("group").def("0").help("accepted for SOFA scenes; one solver takes every constraint"));
    s.add(AttrSpec::integer("constraintIndex").def("0").help("accepted for SOFA scenes"));
    s.factory = [](BuildContext& c) { return std::make_unique<BilateralConstraint>(c); };
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
    s.add(AttrSpec::real("regularizationTerm").def("0").atLeast(0).help(
        "added to the compliance of every constraint row on this body"));
    s.factory = [](BuildContext& ctx) -> std::unique_ptr<Component> {
      if (ctx.node().find<RigidObject>() && !ctx.node().find<MechanicalObject>()) return std::make_unique<RigidConstraintCorrection>(ctx);
      return std::make_unique<ConstraintCorrection>(ctx);
    };
    r.add(std::move(s));
  }
}

}  // namespace viscera
