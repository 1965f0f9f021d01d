// EulerImplicitSolver in SOFA's formulation (one linear solve per step), with a = h (or h / 2 with
// trapezoidalScheme):
//   [(1 + a rM) M - a (a + rK) K] dv = h [f(x, v) + (a + rK) K v - rM M v],
//   where contact stiffness (not Rayleigh damped) enters with a in place of a + rK;
//   v <- v + dv, x <- x + h v; fixed nodes are projected out of the system.
// firstOrder (SOFA's first-order system x' = v = M^-1 f, no Rayleigh damping):
//   (M - a K) v_new = f(x, v),  x <- x + h v_new.
// In the node of a rigid body it integrates the body (RigidDynamics.h). In a node with no body
// (SOFA's solver over several bodies) it integrates the rigid bodies below it and the deformable
// ones (collectBodies), the latter as one linear system over all their unknowns, which the
// interaction force fields between them (springs between two objects) couple.
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "engine/MechanicalSystem.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidDynamics.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/LinearSolver.h"
#include "solvers/ode/OdeCommon.h"

namespace viscera {

namespace {

class EulerImplicitSolver : public Component, public OdeSolver, public Stateful {
 public:
  using Component::Component;
  // The last velocity change (the next linear solve starts from it; the bodies' one after the
  // other) and its iteration count; the step's matrices are workspace.
  struct Live : ComponentStateOf<Live> {
    Eigen::VectorXd dv;
    int lastIterations = 0;
    std::vector<BlockSparseMatrix> A;  // one per body
    BlockSparseMatrix joint;           // all bodies and their couplings, when a matrix is needed
    Eigen::Matrix3Xd start;  // positions at the start of the last step (one body: its linearisation)
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
    // The body of its node; or, with none there (SOFA's solver over several bodies), the rigid
    // bodies below it and the deformable ones, integrated together.
    rigid_ = RigidBodyIntegrator::forSolver(*this, true);
    if (node().find<MechanicalObject>()) {
      systems_.push_back(std::make_unique<MechanicalSystem>(*this));
    } else if (node().find<RigidObject>()) {
      return;  // a rigid body's own solver: that body alone
    } else {
      std::vector<RigidObject*> rigid;
      std::vector<MechanicalObject*> deformable;
      collectBodies(node(), rigid, deformable);
      for (MechanicalObject* m : deformable) systems_.push_back(std::make_unique<MechanicalSystem>(*this, *m));
      if (systems_.empty() && !rigid_) throw error("needs a MechanicalObject in its node");
    }
    if (systems_.empty()) return;
    linear_ = findLinearSolver(*this);
    collectCouplings();
    joint_ = systems_.size() > 1 || !couplings_.empty();
    if (joint_) {
      const std::string& l = dynamic_cast<Component&>(*linear_).typeName();
      static const char* general[] = {"CGLinearSolver", "MinResLinearSolver", "SparseLDLSolver", "SparseCholeskySolver", "SVDLinearSolver"};
      if (std::find(std::begin(general), std::end(general), l) == std::end(general))
        throw error("integrates " + std::to_string(systems_.size()) + " deformable bodies below its node" +
                    (couplings_.empty() ? "" : ", coupled by " + std::to_string(couplings_.size()) + " interaction force field(s),") +
                    " as one system; its " + l + " works on one body's matrix: use CGLinearSolver, MinResLinearSolver, "
                    "SparseLDLSolver, SparseCholeskySolver or SVDLinearSolver, or give each body its own solver");
      if (systems_.size() > 1)
        scene().addNote(loc().str() + ": note: " + typeName() + " '" + name() + "' integrates " +
                        std::to_string(systems_.size()) + " deformable bodies below its node as one system");
    }
    if (linear_->needsMatrix()) {
      for (auto& sys : systems_) sys->prepareAssembly();
      if (joint_) prepareJoint();
      else upper_ = linear_->takesUpperMatrix() && systems_.front()->prepareUpperAssembly();
    }
  }

  std::optional<Diverged> step(State& st, double t, double h, int stepIndex) const override {
    if (rigid_)
      if (auto failed = rigid_->step(st, t, h, stepIndex, rM_)) return failed;
    if (systems_.empty()) return std::nullopt;
    Live& l = stateIn<Live>(st);
    const double a = tr_ * h;
    const double mFact = firstOrder_ ? 1.0 : 1.0 + a * rM_;
    const double kFact = firstOrder_ ? -a : -a * (a + rK_);
    // Contact stiffness is not Rayleigh damped: its K enters as -a^2 K (and a K v), not
    // -a (a + rK) K, hence the scale a / (a + rK) on the undamped fields.
    const double uScale = a / (a + rK_);
    const int bodies = static_cast<int>(systems_.size());
    const auto K = [](int k) { return static_cast<size_t>(k); };
    l.A.resize(K(bodies));
    // Each body's part of the one system: its right-hand side, its operator (A_k, or matrix-free).
    std::vector<Eigen::Index> offset(K(bodies) + 1, 0);
    std::vector<Eigen::Matrix3Xd> x0(K(bodies)), v0(K(bodies)), rhs(K(bodies)), Kv(K(bodies));
    // Forces: each body's own, then the couplings' on their ends.
    for (int k = 0; k < bodies; ++k) {
      const MechanicalSystem& sys = *systems_[K(k)];
      MechanicalObject::Live& s = sys.state().live(st);
      offset[K(k) + 1] = offset[K(k)] + 3 * sys.nodes();
      x0[K(k)] = s.x;
      v0[K(k)] = s.v;
      sys.computeForce(st, s.x, s.v, s.f);
    }
    for (const Coupling& c : couplings_)
      c.ff->addForce(st, sides(st, c, &MechanicalObject::Live::x), sides(st, c, &MechanicalObject::Live::v), bodyVectors(st, c));
    for (int k = 0; k < bodies; ++k) {
      const MechanicalSystem& sys = *systems_[K(k)];
      MechanicalObject::Live& s = sys.state().live(st);
      const int n = sys.nodes();
      Kv[K(k)] = Eigen::Matrix3Xd::Zero(3, n);
      if (linear_->needsMatrix()) {
        // A = kFact K + mFact M, constrained; K v read from kFact K before the mass joins it.
        BlockSparseMatrix& A = l.A[K(k)];
        if (upper_ && !A.upper()) A = sys.upperPattern();
        sys.assembleStiffness(st, A, uScale, kFact != 0 ? kFact : 1.0);
        A.multiply(Eigen::Map<const Eigen::VectorXd>(s.v.data(), 3 * n), Eigen::Map<Eigen::VectorXd>(Kv[K(k)].data(), 3 * n));
        if (kFact != 0) Kv[K(k)] *= 1.0 / kFact;
        else A.setZero();
        sys.addMass(A, mFact);
        sys.constrain(A);
      } else {
        sys.addKdx(st, s.v, Kv[K(k)], 1.0, uScale);
      }
    }
    // The couplings' K v (Rayleigh damped, as the bodies' own fields).
    for (const Coupling& c : couplings_) {
      InteractionForceField::SideForces out{};
      for (int side = 0; side < 2; ++side)
        if (c.body[side] >= 0) out[side] = &Kv[K(c.body[side])];
      c.ff->addDForce(st, sides(st, c, &MechanicalObject::Live::v, false), out, 1.0);
    }
    for (int k = 0; k < bodies; ++k) {
      const MechanicalSystem& sys = *systems_[K(k)];
      const MechanicalObject::Live& s = sys.state().live(st);
      Eigen::Matrix3Xd Mv = Eigen::Matrix3Xd::Zero(3, sys.nodes());
      if (rM_ != 0) sys.addMdx(s.v, Mv, 1.0);
      // First order: the unknown is the new velocity itself.
      rhs[K(k)] = firstOrder_ ? Eigen::Matrix3Xd(s.f) : Eigen::Matrix3Xd(h * (s.f + (a + rK_) * Kv[K(k)] - rM_ * Mv));
      sys.project(rhs[K(k)]);
    }
    if (bodies == 1) l.start = x0.front();
    LinearProblem problem;
    if (!joint_ && linear_->needsMatrix()) {
      useAssembled(problem, l.A.front());
    } else if (linear_->needsMatrix()) {
      assembleJoint(st, l, kFact);
      useAssembled(problem, l.joint);
    } else {
      problem.apply = [this, &st, &offset, bodies, mFact, kFact, uScale, K](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
        q.resize(p.size());
        std::vector<Eigen::Map<const Eigen::Matrix3Xd>> P;
        std::vector<Eigen::Matrix3Xd> Q(K(bodies));
        for (int k = 0; k < bodies; ++k) {
          const MechanicalSystem& sys = *systems_[K(k)];
          P.emplace_back(p.data() + offset[K(k)], 3, sys.nodes());
          Q[K(k)] = Eigen::Matrix3Xd::Zero(3, sys.nodes());
          sys.addMdx(P.back(), Q[K(k)], mFact);
          sys.addKdx(st, P.back(), Q[K(k)], kFact, uScale);
        }
        for (const Coupling& c : couplings_) {
          InteractionForceField::Sides in{};
          InteractionForceField::SideForces out{};
          Eigen::Matrix3Xd pk[2];
          for (int side = 0; side < 2; ++side)
            if (c.body[side] >= 0) {
              pk[side] = P[K(c.body[side])];
              in[side] = &pk[side];
              out[side] = &Q[K(c.body[side])];
            }
          c.ff->addDForce(st, in, out, kFact);
        }
        for (int k = 0; k < bodies; ++k) {
          systems_[K(k)]->project(Q[K(k)]);
          q.segment(offset[K(k)], offset[K(k) + 1] - offset[K(k)]) = Eigen::Map<const Eigen::VectorXd>(Q[K(k)].data(), Q[K(k)].size());
        }
      };
    }
    Eigen::VectorXd bv(offset.back());
    for (int k = 0; k < bodies; ++k)
      bv.segment(offset[static_cast<size_t>(k)], offset[static_cast<size_t>(k) + 1] - offset[static_cast<size_t>(k)]) =
          Eigen::Map<const Eigen::VectorXd>(rhs[static_cast<size_t>(k)].data(), rhs[static_cast<size_t>(k)].size());
    Eigen::VectorXd& dv = l.dv;
    if (dv.size() != offset.back()) dv = Eigen::VectorXd::Zero(offset.back());
    LinearSolveInfo info = linear_->solve(st, problem, bv, dv);
    l.lastIterations = info.iterations;
    if (!info.ok) {
      Diverged d;
      d.step = stepIndex;
      d.time = t + h;
      d.reason = "linear solver failed: " + info.message;
      d.object = systems_.front()->state().name();
      return d;
    }
    for (int k = 0; k < bodies; ++k) {
      const MechanicalSystem& sys = *systems_[static_cast<size_t>(k)];
      MechanicalObject::Live& s = sys.state().live(st);
      const Eigen::Map<const Eigen::Matrix3Xd> d(dv.data() + offset[static_cast<size_t>(k)], 3, sys.nodes());
      if (firstOrder_) s.v = d;
      else s.v += d;
      if (vdamping_ > 0) s.v *= std::exp(-h * vdamping_);
      s.x += h * s.v;
    }
    for (int k = 0; k < bodies; ++k) {
      const MechanicalSystem& sys = *systems_[static_cast<size_t>(k)];
      MechanicalObject::Live& s = sys.state().live(st);
      if (auto bad = sys.check(s.x, s.v, stepIndex, t + h)) {
        // Keep the last good state: nothing bad reaches the outputs.
        for (int j = 0; j < bodies; ++j) {
          MechanicalObject::Live& sj = systems_[static_cast<size_t>(j)]->state().live(st);
          sj.x = x0[static_cast<size_t>(j)];
          sj.v = v0[static_cast<size_t>(j)];
        }
        return bad;
      }
    }
    return std::nullopt;
  }
  // Rigid bodies: (1 + h rM) M dV = h F, p += h v (no stiffness of their own; their step is the
  // same whatever the scheme of the deformable ones).
  std::optional<StepResponse> rigidStepResponse(double h) const override { return StepResponse{1.0 + h * rM_, 0.0, h * h, h}; }
  int lastLinearIterations(const State& s) const override { return stateIn<Live>(s).lastIterations; }
  const Eigen::Matrix3Xd* linearisedAt(const State& s) const override {
    const Live& l = stateIn<Live>(s);
    return systems_.size() != 1 || l.start.cols() == 0 ? nullptr : &l.start;
  }
  // A dv = h F, x += h v: positions move by h^2 A^-1 F, velocities by h A^-1 F (first order:
  // A v = F, so h A^-1 F and A^-1 F).
  std::optional<StepResponse> stepResponse(double h) const override {
    if (systems_.empty()) return rigidStepResponse(h);
    const double a = tr_ * h;
    if (firstOrder_) return StepResponse{1.0, -a, h, 1.0};
    return StepResponse{1.0 + a * rM_, -a * (a + rK_), h * h, h};
  }

 private:
  double rM_ = 0, rK_ = 0, vdamping_ = 0;
  double tr_ = 1.0;  // 1/2 with the trapezoidal scheme
  bool firstOrder_ = false;
  std::unique_ptr<RigidBodyIntegrator> rigid_;  // the rigid bodies it moves, if any
  std::vector<std::unique_ptr<MechanicalSystem>> systems_;  // the deformable bodies it moves
  LinearSolver* linear_ = nullptr;
  // Interaction force fields between its bodies (or a body and an object held still): each
  // side's index in systems_, or -1 for a side held still.
  struct Coupling {
    const InteractionForceField* ff = nullptr;
    std::array<int, 2> body{-1, -1};
  };
  std::vector<Coupling> couplings_;
  // One system over several bodies or with couplings; with an assembled linear solver, its matrix
  // is the bodies' matrices side by side and the couplings' blocks (jointPattern_, bodySlots_).
  bool joint_ = false;
  bool upper_ = false;  // one body whose matrix assembles in upper storage (MechanicalSystem::prepareUpperAssembly)
  BlockSparseMatrix jointPattern_;
  std::vector<int> firstNode_;               // each body's first node in the joint matrix
  std::vector<std::vector<int>> bodySlots_;  // body k's block slot -> joint slot

  void collectCouplings() {
    for (InteractionForceField* ff : scene().all<InteractionForceField>()) {
      scene().initComponent(dynamic_cast<Component&>(*ff));
      if (ff->solverNode() != &node()) continue;
      Coupling c{ff, {-1, -1}};
      for (int side = 0; side < 2; ++side)
        for (size_t k = 0; k < systems_.size(); ++k)
          if (&systems_[k]->state() == &ff->object(side)) c.body[side] = static_cast<int>(k);
      if (c.body[0] < 0 && c.body[1] < 0) continue;
      couplings_.push_back(c);
    }
  }
  // A coupling's sides' vectors (positions or velocities): the bodies', and an object held still's
  // own, or null for it without `anchors`.
  InteractionForceField::Sides sides(const State& st, const Coupling& c, Eigen::Matrix3Xd MechanicalObject::Live::*v,
                                     bool anchors = true) const {
    InteractionForceField::Sides out{};
    for (int side = 0; side < 2; ++side)
      if (anchors || c.body[side] >= 0) out[side] = &(c.ff->object(side).live(st).*v);
    return out;
  }
  InteractionForceField::SideForces bodyVectors(State& st, const Coupling& c) const {
    InteractionForceField::SideForces out{};
    for (int side = 0; side < 2; ++side)
      if (c.body[side] >= 0) out[side] = &c.ff->object(side).live(st).f;
    return out;
  }
  // The joint matrix's pattern: each body's pattern at its first node, and the couplings' blocks.
  void prepareJoint() {
    firstNode_.assign(systems_.size() + 1, 0);
    for (size_t k = 0; k < systems_.size(); ++k) firstNode_[k + 1] = firstNode_[k] + systems_[k]->nodes();
    std::vector<std::pair<int, int>> pairs;
    for (size_t k = 0; k < systems_.size(); ++k) {
      const BlockSparseMatrix& P = systems_[k]->pattern();
      for (int i = 0; i < P.blockRows(); ++i)
        for (int s = P.rowStart()[i]; s < P.rowStart()[i + 1]; ++s) pairs.push_back({firstNode_[k] + i, firstNode_[k] + P.cols()[s]});
    }
    for (const Coupling& c : couplings_) {
      std::vector<std::array<int, 4>> blocks;
      c.ff->stiffnessPattern(blocks);
      for (const auto& b : blocks)
        if (c.body[b[0]] >= 0 && c.body[b[2]] >= 0)
          pairs.push_back({firstNode_[c.body[b[0]]] + b[1], firstNode_[c.body[b[2]]] + b[3]});
    }
    jointPattern_.setPattern(firstNode_.back(), pairs);
    bodySlots_.assign(systems_.size(), {});
    for (size_t k = 0; k < systems_.size(); ++k) {
      const BlockSparseMatrix& P = systems_[k]->pattern();
      for (int i = 0; i < P.blockRows(); ++i)
        for (int s = P.rowStart()[i]; s < P.rowStart()[i + 1]; ++s)
          bodySlots_[k].push_back(jointPattern_.slot(firstNode_[k] + i, firstNode_[k] + P.cols()[s]));
    }
  }
  // The joint matrix: the bodies' A_k (constrained already) and the couplings' kFact P_i K_ij P_j.
  void assembleJoint(const State& st, Live& l, double kFact) const {
    if (l.joint.blockRows() != jointPattern_.blockRows()) l.joint = jointPattern_;
    l.joint.setZero();
    for (size_t k = 0; k < systems_.size(); ++k) {
      const BlockSparseMatrix& A = l.A[k];
      for (size_t s = 0; s < bodySlots_[k].size(); ++s) l.joint.block(bodySlots_[k][s]) = A.block(static_cast<int>(s));
    }
    if (kFact == 0) return;
    for (const Coupling& c : couplings_)
      c.ff->forEachStiffnessBlock(st, [&](int si, int i, int sj, int j, const Eigen::Matrix3d& Kij) {
        const int bi = c.body[si], bj = c.body[sj];
        if (bi < 0 || bj < 0) return;
        const Eigen::Matrix3d Pi = systems_[static_cast<size_t>(bi)]->projector(i), Pj = systems_[static_cast<size_t>(bj)]->projector(j);
        l.joint.block(l.joint.slot(firstNode_[bi] + i, firstNode_[bj] + j)) += kFact * (Pi * Kij * Pj);
      });
  }
};

}  // namespace

void useAssembled(LinearProblem& problem, const BlockSparseMatrix& A) {
  problem.matrix = &A;
  problem.apply = [&A](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
    q.resize(p.size());
    A.multiply(p, q);
  };
  problem.applyDot = [&A](const Eigen::VectorXd& p, Eigen::VectorXd& q) {
    q.resize(p.size());
    double pq = 0;
    A.multiply(p, q, &pq);
    return pq;
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
          "formulation). The linear solver is the one in the same node. In a node without a MechanicalObject it "
          "integrates the bodies below it that no other solver moves: rigid bodies, and deformable ones (a mass in "
          "their node) as one system (an iterative solver, or a direct one on the joint matrix). Springs between two "
          "objects it integrates (SpringForceField with object1 and object2) couple them in that system.";
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
