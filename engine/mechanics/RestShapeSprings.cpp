// RestShapeSpringsForceField (SOFA's name): springs that pull nodes back to their rest positions,
// f_i = -k_i (x_i - x0_i). An elastic foundation where a FixedConstraint would hold the nodes
// rigidly (a phantom resting on a compliant support); stiff springs approach the fixed support.
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

namespace {

class RestShapeSpringsForceField : public Component, public ForceField {
 public:
  using Component::Component;
  MechanicalObject& mstate() const override { return *state_; }
  void init() override {
    state_ = &contextState(*this);
    if (attrs_.isSet("points")) {
      nodes_ = linkedInts("points");
    } else {
      for (int i = 0; i < state_->size(); ++i) nodes_.push_back(i);
    }
    for (int i : nodes_)
      if (i < 0 || i >= state_->size())
        throw error("points", "node " + std::to_string(i) + " is out of range (the MechanicalObject has " +
                                  std::to_string(state_->size()) + " nodes)");
    const auto& k = attrs_.reals("stiffness");
    if (k.size() != 1 && k.size() != nodes_.size())
      throw error("stiffness", "expected one value or one per point (" + std::to_string(nodes_.size()) + "), got " +
                                   std::to_string(k.size()));
    k_.resize(nodes_.size());
    for (size_t n = 0; n < nodes_.size(); ++n) k_[n] = k.size() == 1 ? k[0] : k[n];
  }
  void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    for (size_t n = 0; n < nodes_.size(); ++n) f.col(nodes_[n]) -= k_[n] * (x.col(nodes_[n]) - state_->x0.col(nodes_[n]));
  }
  void addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const override {
    for (size_t n = 0; n < nodes_.size(); ++n) df.col(nodes_[n]) -= kFactor * k_[n] * dx.col(nodes_[n]);
  }
  void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const override {
    for (int i : nodes_) pairs.push_back({i, i});
  }
  void addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const override {
    for (size_t n = 0; n < nodes_.size(); ++n)
      K.block(K.diagonalSlot(nodes_[n])).diagonal().array() -= kFactor * k_[n];
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    double e = 0;
    for (size_t n = 0; n < nodes_.size(); ++n) e += 0.5 * k_[n] * (x.col(nodes_[n]) - state_->x0.col(nodes_[n])).squaredNorm();
    return e;
  }

 private:
  MechanicalObject* state_ = nullptr;
  std::vector<int> nodes_;
  std::vector<double> k_;
};

}  // namespace

void registerRestShapeSprings(Registry& r) {
  ComponentSpec s;
  s.name = "RestShapeSpringsForceField";
  s.category = "forcefield";
  s.doc = "Springs pulling nodes back to their rest positions, f = -k (x - x0): an elastic foundation (a compliant "
          "support) where FixedConstraint would hold the nodes rigidly.";
  s.add(AttrSpec::ints("points").atLeast(0).linked().help("nodes on springs (default: all; a link such as @box.indices)"));
  s.add(AttrSpec::reals("stiffness").req().atLeast(0).unit(Dimension::stiffness()).help("spring stiffness: one value, or one per point"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
  s.factory = [](BuildContext& c) { return std::make_unique<RestShapeSpringsForceField>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
