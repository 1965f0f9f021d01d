// Linear tetrahedral FEM with SOFA's small, large (corotational, edge frame) and polar methods.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "engine/Roles.h"
#include "core/State.h"
#include "core/Component.h"
#include "engine/fem/TetKernel.h"
#include "solvers/linear/LinearSolver.h"

namespace viscera {

class Registry;
struct ElementColoring;

class TetrahedronFEMForceField : public Component, public ForceField, public Stateful, public RotationFinder {
 public:
  using Component::Component;
  void init() override;
  MechanicalObject& mstate() const override { return *state_; }
  // The element frames and positions of the last linearisation (addDForce and addStiffness use them).
  struct Live : ComponentStateOf<Live> {
    std::vector<Eigen::Matrix3d> rot;  // frame of each element at the last addForce
    Eigen::Matrix3Xd xLast;            // positions of the last addForce (exact tangent)
    Eigen::Matrix<double, 6, Eigen::Dynamic> plastic;  // plastic strain of each element (fem::Plasticity), if on
    void save(StateWriter& out) const override {
      out.put(rot);
      out.put(xLast);
      out.put(plastic);
    }
    void load(StateReader& in) override;
  };
  std::unique_ptr<ComponentState> initialState() const override;

  void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, Eigen::Matrix3Xd& f) const override;
  void addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const override;
  void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const override;
  void prepareAssembly(const BlockSparseMatrix& K) override;
  void addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const override;
  bool setStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const override;
  // R K0 R^T is symmetric; the exact tangent is not.
  bool assemblesUpper() const override { return !exact_ || method_ == fem::Method::Small; }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override;
  std::vector<int> invertedElements(const Eigen::Matrix3Xd& x) const override;
  // Each node's rest -> current rotation, from its elements' frames at the last addForce.
  void nodeRotations(const State& s, std::vector<Eigen::Matrix3d>& R) const override;

  fem::Method method() const { return method_; }
  const fem::Plasticity& plasticity() const { return plasticity_; }
  // Each element's plastic strain in `s` (fem::Plasticity; no columns with plasticity off).
  const Eigen::Matrix<double, 6, Eigen::Dynamic>& plasticStrains(const State& s) const { return live(s).plastic; }
  const TetList& tetrahedra() const { return tets_; }
  // Von Mises stress per element at x.
  Eigen::VectorXd vonMises(const Eigen::Matrix3Xd& x) const;
  // The same, as a function that keeps its own copy of what it needs (it outlives the model).
  std::function<Eigen::VectorXd(const Eigen::Matrix3Xd&)> vonMisesFunction() const;
  // Uses the exact tangent (with the derivative of the rotation) instead of SOFA's R^T K0 R.
  bool exactTangent() const { return exact_; }
  // With plasticity the exact tangent of the elastic force is not the plastic one: keep SOFA's.
  void setExactTangent(bool on) override { exact_ = on && !plasticity_.on(); }

 private:
  fem::Mat34 gather(const Eigen::Matrix3Xd& x, int e) const;
  fem::Mat12 stiffnessOf(const Live& l, int e) const;
  void assembleBlocks(const Live& l, BlockSparseMatrix& K, double kFactor, const std::uint16_t* firstWriter) const;
  Live& live(State& s) const { return stateIn<Live>(s); }
  const Live& live(const State& s) const { return stateIn<Live>(s); }

  MechanicalObject* state_ = nullptr;
  fem::Method method_ = fem::Method::Large;
  bool svd_ = false;  // SOFA's svd: polar, with inverted or flat elements turned back (fem::frameSvd)
  bool exact_ = false;
  fem::Plasticity plasticity_;
  TetList tets_;
  std::vector<fem::ElementRest> rest_;
  std::vector<Eigen::Matrix3d> rot0_;      // frame of each element at rest
  std::vector<double> lanes_;              // rest data eight elements abreast (fem::largeTetrahedraLanes)
  std::vector<double> signs_;              // rest orientations (fem::restSigns), for the health check
  std::shared_ptr<const ElementColoring> colors_;  // shared by models of one mesh
  // Block slots of each element in the assembled matrix, for the full and the upper storage; per
  // element, which of its slots it writes first in the assembly's order (fem::addTetrahedraBlocks'
  // firstWriter); and the pattern's slots no element writes.
  std::array<std::vector<std::array<int, 16>>, 2> slots_;
  std::array<std::vector<std::uint16_t>, 2> firstWriter_;
  std::array<std::vector<int>, 2> unwritten_;
};

void registerTetrahedronFEM(Registry& r);

}  // namespace viscera
