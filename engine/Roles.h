// The small interfaces a component implements to take part in the step loop. A component is a
// Component (attributes, links, init) and one or more of these roles.
#pragma once

#include <Eigen/Core>
#include <array>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace viscera {

class BlockSparseMatrix;
class MechanicalObject;
class Node;
class State;

using TetList = Eigen::Matrix<int, 4, Eigen::Dynamic>;  // 4 x #tets
using HexList = std::vector<std::array<int, 8>>;

// Supplies rest geometry: points and/or elements (loaders, grids, containers).
class Topology {
 public:
  virtual ~Topology() = default;
  virtual const Eigen::Matrix3Xd& points() const = 0;  // 3 x #points, may be empty
  virtual const TetList& tetrahedra() const = 0;       // may be empty
  virtual const HexList& hexahedra() const { static const HexList none; return none; }
  // Cells per axis for structured grids (SOFA's swapping pattern needs it); zero otherwise.
  virtual std::array<int, 3> gridCells() const { return {0, 0, 0}; }
  // Where a cell holds several hexahedra over separate parts of a shape (SOFA's ramified grid):
  // the hexahedron of the part at point p (in the topology's geometry); -1 elsewhere.
  virtual int partAt(const Eigen::Vector3d& p) const { return -1; }
};

// Forces on the nodes of one MechanicalObject. `addForce` also linearises at x, keeping the
// linearisation in the state; `addDForce` and `addStiffness` use it (K = df/dx as the solver uses
// it). Like every role below, it changes nothing in the component while stepping: what changes is
// in the State it is given.
class ForceField {
 public:
  virtual ~ForceField() = default;
  virtual MechanicalObject& mstate() const = 0;
  // f += f(x, v).
  virtual void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, Eigen::Matrix3Xd& f) const = 0;
  // df += kFactor * K dx.
  virtual void addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const {}
  // Node pairs coupled by K (for the sparsity pattern).
  virtual void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const {}
  // Called once the model's pattern is fixed (before stepping), to precompute value slots; a field
  // that assembles in upper storage is called again with the upper pattern (K.upper()) and keeps
  // one table per storage, as both are in use.
  virtual void prepareAssembly(const BlockSparseMatrix& K) {}
  // K += kFactor * (the force field's K).
  virtual void addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const {}
  // K = kFactor * (the force field's K), whatever K held (every block of K's pattern is written:
  // the ones it has no part in are zeroed), or false, K untouched, where it only adds: the first
  // field of a body then saves zeroing the matrix before the assembly.
  virtual bool setStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const { return false; }
  // Whether addStiffness also fills a matrix in upper storage (BlockSparseMatrix::Storage::Upper):
  // its K is symmetric and it skips the blocks below the diagonal (slot -1; addSymmetric does).
  virtual bool assemblesUpper() const { return false; }
  // Potential energy at x (0 when the field has none).
  virtual double potentialEnergy(const Eigen::Matrix3Xd& x) const { return 0.0; }
  // Whether Rayleigh stiffness damping applies to this field's K. Contact penalties return false:
  // their stiffness must not act as a dashpot anchored to the world.
  virtual bool rayleighDamped() const { return true; }
  // Elements that are inverted at x (for the health check).
  virtual std::vector<int> invertedElements(const Eigen::Matrix3Xd& x) const { return {}; }
  // Linearise with the exact tangent (the complete df/dx) where the default stiffness is an
  // approximation, as the corotational FEM's R^T K0 R is; Newton solvers ask for it. Fields whose
  // stiffness is exact already have nothing to change.
  virtual void setExactTangent(bool on) {}
  // True for a field that reads a mapped state's positions but acts on the mapping's input (a
  // collision surface on a mapped state): allowed beside a mapped state.
  virtual bool actsThroughMapping() const { return false; }
};

// A force field between two MechanicalObjects (SOFA's interaction force fields: springs whose
// object1 and object2 are set). The EulerImplicitSolver that integrates its ends couples them in
// its one system; an end that no solver integrates holds still (an anchor). Side 0 is object1,
// side 1 object2; where a side is held still, its dx and df are null.
class InteractionForceField {
 public:
  using Sides = std::array<const Eigen::Matrix3Xd*, 2>;
  using SideForces = std::array<Eigen::Matrix3Xd*, 2>;
  virtual ~InteractionForceField() = default;
  virtual MechanicalObject& object(int side) const = 0;
  // The node of the solver that integrates its ends (null: neither moves).
  virtual const Node* solverNode() const = 0;
  // f[k] += the forces on side k at positions x and velocities v; linearises there (kept in s).
  virtual void addForce(State& s, const Sides& x, const Sides& v, const SideForces& f) const = 0;
  // df[k] += factor K dx, at the last linearisation.
  virtual void addDForce(const State& s, const Sides& dx, const SideForces& df, double factor) const = 0;
  // The stiffness blocks at the last linearisation: visit(side i, node i, side j, node j, K_ij),
  // df_i = K_ij dx_j, once per block (blocks of one pair of nodes may come several times: add them).
  virtual void forEachStiffnessBlock(const State& s,
                                     const std::function<void(int, int, int, int, const Eigen::Matrix3d&)>& visit) const = 0;
  // The blocks forEachStiffnessBlock visits, as (side i, node i, side j, node j).
  virtual void stiffnessPattern(std::vector<std::array<int, 4>>& blocks) const = 0;
};

// Mass; also applies gravity. `nodeMass` is the lumped mass (each row of M summed), which is all
// of M for a diagonal mass. A consistent mass (SOFA's MeshMatrixMass without lumping) also couples
// neighbouring nodes: M_ij (times the 3 x 3 identity) for the pairs it lists.
class Mass {
 public:
  virtual ~Mass() = default;
  virtual MechanicalObject& mstate() const = 0;
  virtual const Eigen::VectorXd& nodeMass() const = 0;  // #nodes
  virtual bool consistent() const { return false; }
  // Consistent masses: the node pairs M couples, out += factor M dx, and A += factor M (A's
  // pattern holds the pairs).
  virtual void massPattern(std::vector<std::pair<int, int>>& pairs) const {}
  virtual void addMdx(const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& out, double factor) const {}
  virtual void addMassMatrix(BlockSparseMatrix& A, double factor) const {}
};

// Projective constraints: nodes whose motion is prescribed (zero rows in the system).
class ProjectiveConstraint {
 public:
  virtual ~ProjectiveConstraint() = default;
  virtual MechanicalObject& mstate() const = 0;
  virtual const std::vector<int>& fixedNodes() const = 0;
  // Nodes held along one direction only (unit vectors): the motion keeps the rest of its freedom.
  virtual const std::vector<std::pair<int, Eigen::Vector3d>>& heldDirections() const {
    static const std::vector<std::pair<int, Eigen::Vector3d>> none;
    return none;
  }
  // Whether it moves its nodes along a prescribed path over time (no other constraint may hold
  // them); holding and projecting constraints compose, in scene order, as in SOFA.
  virtual bool prescribesMotion() const { return false; }
};

// A numerical failure of a step: where, when and what.
struct Diverged {
  int step = 0;
  double time = 0.0;
  std::string reason;
  std::string object;         // the MechanicalObject or solver concerned
  std::vector<int> elements;  // element ids (inverted elements)
  std::vector<int> nodes;     // node ids (non-finite values)
  std::string str() const;
};

class MechanicalSystem;

// How an extra force applied during a step changes the result: the step's linear system is
// A = mFactor M + kFactor K (fixed nodes projected out), and a force F moves the end-of-step
// positions by xFactor A^-1 F and velocities by vFactor A^-1 F. Constraint corrections use it.
struct StepResponse {
  double mFactor = 0, kFactor = 0, xFactor = 0, vFactor = 0;
};

// Integrates the mechanical objects of its node (and sub-nodes) over one time step.
class OdeSolver {
 public:
  virtual ~OdeSolver() = default;
  // The response to a force added during a step of size dt; nothing if the solver has no
  // linear system (or is idle).
  virtual std::optional<StepResponse> stepResponse(double dt) const { return std::nullopt; }
  // The same for the rigid bodies it moves, where their step differs from its deformable bodies'.
  virtual std::optional<StepResponse> rigidStepResponse(double dt) const { return stepResponse(dt); }
  // Advances from time t to t + dt; returns a failure instead of writing bad state.
  virtual std::optional<Diverged> step(State& s, double t, double dt, int stepIndex) const = 0;
  // Statistics of the last step (linear iterations, residual), for summaries.
  virtual int lastLinearIterations(const State& s) const { return 0; }
  // The positions the last step's linear system was assembled at (the step's start), where a
  // constraint correction takes the same system; null when the solver keeps none.
  virtual const Eigen::Matrix3Xd* linearisedAt(const State& s) const { return nullptr; }
};

// Sets a kinematically driven state (an instrument) for time t: called with the start time before
// the first step and with the end time of each step before it is integrated. `dt` is the step
// that ends at t (the scene's step before the first one): a driver's velocity is the mean over it.
class Driver {
 public:
  virtual ~Driver() = default;
  virtual void drive(State& s, double t, double dt) const = 0;
};

// Changes the state after the solve and the contact constraints of a step, before mappings and
// observers read it (a learned correction of the simulated state). Corrections run in scene order,
// then those a library caller added to the Simulation.
class Correction {
 public:
  virtual ~Correction() = default;
  virtual void correct(State& s, double t, int stepIndex) const = 0;
  // Called at the start of every step, before the drivers, in reverse order: a correction that is
  // only seen (by mappings, observers and scores) takes back what it added, so that the mechanics
  // continue as they would without it; true when it changed the state (mappings then run again).
  // Corrections that change the mechanics do nothing here.
  virtual bool restore(State& s) const { return false; }
};

// Carries the state of a mechanical object to another representation at the end of each step
// (a finer visual surface embedded in the tetrahedra). Mappings run after the solvers and before
// the observers, in scene order.
class Mapping {
 public:
  virtual ~Mapping() = default;
  virtual void apply(State& s) const = 0;
  // For mappings linear in their input: the input state, and output point p as a weighted sum of
  // its nodes (what carries forces on the output back to the input). Null / false otherwise.
  virtual MechanicalObject* inputState() const { return nullptr; }
  virtual bool pointWeights(int p, std::vector<std::pair<int, double>>& out) const { return false; }
};

// Reads the state at the end of a step (exporters, recorders, metrics). Observers write outputs
// and keep their own bookkeeping (frame counts, files): a scene's observers serve one simulation
// at a time.
class Observer {
 public:
  virtual ~Observer() = default;
  // Called once before the first step (t = start time), after every step, and at the end.
  virtual void begin(const State& s, double t) {}
  virtual void observe(const State& s, double t, int stepIndex) = 0;
  // The step after `stepIndex` (at t) failed: the state no longer holds that step. Told before end.
  virtual void diverged(const State& s, double t, int stepIndex) {}
  virtual void end(const State& s, double t, int stepIndex) {}
};

}  // namespace viscera
