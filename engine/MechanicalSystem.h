// The mechanical system of one solver node: its MechanicalObject with the masses, force fields
// and projective constraints acting on it. Global assembly and the health check live here.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "engine/Roles.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

class Component;
class MechanicalObject;

class MechanicalSystem {
 public:
  // Collects what acts on the MechanicalObject of `owner`'s node. Throws a clear error if the
  // node has no MechanicalObject or no mass.
  explicit MechanicalSystem(Component& owner);
  // The same for `body` in its own node, which `owner` (a solver above it) integrates.
  MechanicalSystem(Component& owner, MechanicalObject& body);

  MechanicalObject& state() const { return *state_; }
  int nodes() const;
  // The lumped mass per node (row sums of M), for gravity, contact and explicit steps.
  const Eigen::VectorXd& nodeMass() const { return mass_; }  // #nodes
  // Whether M has off-diagonal terms (a consistent mass acts on the object).
  bool consistentMass() const { return !consistent_.empty(); }
  // out += factor * M dx.
  void addMdx(const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& out, double factor) const;
  // A += factor * M, for a matrix whose pattern assembleStiffness built.
  void addMass(BlockSparseMatrix& A, double factor) const;
  const std::vector<int>& fixedNodes() const { return fixed_; }
  // Nodes held along some directions: the projector onto their remaining freedom (I - sum n n^T).
  const std::vector<std::pair<int, Eigen::Matrix3d>>& partialNodes() const { return partial_; }
  // The projector of node i: 0 for a fixed node, its projector for a partly held one, I otherwise.
  Eigen::Matrix3d projector(int i) const;
  // Applies the projective constraints to a system matrix: identity rows and columns for fixed
  // nodes, P A P + (I - P) for partly held ones.
  void constrain(BlockSparseMatrix& A) const;
  const std::vector<ForceField*>& forceFields() const { return forces_; }
  // Interaction force fields with both ends on this object (its own springs placed elsewhere).
  const std::vector<const InteractionForceField*>& internalForces() const { return internal_; }

  // f = f(x, v) from every force field and mass (gravity); linearises the force fields at x (the
  // linearisation is kept in `s`).
  void computeForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, Eigen::Matrix3Xd& f) const;
  // df += factor * K dx, matrix-free. `undampedScale` multiplies the K of force fields that
  // Rayleigh damping does not apply to (contact), so that a solver can form
  // K_damped + undampedScale K_undamped in one pass.
  void addKdx(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double factor,
              double undampedScale = 1.0) const;
  // Fixes the pattern of the assembled matrix (part of the model): solvers that assemble call it
  // at init.
  void prepareAssembly();
  // The prepared pattern, with zero values.
  const BlockSparseMatrix& pattern() const { return pattern_; }
  // The same pattern in upper storage (half the memory, faster products), where every
  // contribution is symmetric and assembles that way: force fields that say so
  // (ForceField::assemblesUpper), no interaction fields inside the object, no consistent masses.
  // Returns whether it could; after prepareAssembly. A matrix that starts as upperPattern()
  // assembles in upper storage.
  bool prepareUpperAssembly();
  const BlockSparseMatrix& upperPattern() const { return upperPattern_; }
  // factor (K_damped + undampedScale K_undamped) (as the force fields report it at their last
  // linearisation in `s`) into `K`, which takes the prepared pattern on first use.
  void assembleStiffness(const State& s, BlockSparseMatrix& K, double undampedScale = 1.0, double factor = 1.0) const;
  // Zeroes the rows of fixed nodes and projects those of partly held ones.
  void project(Eigen::Matrix3Xd& v) const;
  // Non-finite values and inverted elements at (x, v), as a failure, or nothing.
  std::optional<Diverged> check(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, int step, double time) const;
  double potentialEnergy(const Eigen::Matrix3Xd& x) const;

 private:
  MechanicalObject* state_ = nullptr;
  std::vector<ForceField*> forces_;
  // Interaction force fields with both ends on this object, wherever they are placed.
  std::vector<const InteractionForceField*> internal_;
  std::vector<int> fixed_;
  std::vector<std::pair<int, Eigen::Matrix3d>> partial_;
  Eigen::VectorXd mass_;
  Eigen::VectorXd diagonalMass_;      // the sum of the lumped masses
  std::vector<Mass*> consistent_;     // masses with off-diagonal terms
  BlockSparseMatrix pattern_;        // the assembled matrix's pattern, zero values
  BlockSparseMatrix upperPattern_;   // the same in upper storage, if prepared
  bool patternReady_ = false;
};

}  // namespace viscera
