// RestShapeSpringsForceField (SOFA's name): springs that pull nodes back to their rest positions,
// f_i = -k_i (x_i - x0_i). An elastic foundation where a FixedConstraint would hold the nodes
// rigidly (a phantom resting on a compliant support); stiff springs approach the fixed support.
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidDynamics.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

namespace {

class RestShapeSpringsForceField : public Component, public ForceField {
 public:
  using Component::Component;
  bool assemblesUpper() const override { return true; }  // diagonal blocks only
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
    if (attrs_.isSet("angularStiffness")) throw error("angularStiffness", "applies to a Rigid3d body, not to Vec3d nodes");
    // The directions the springs act along (SOFA's activeDirections): the others are free.
    if (attrs_.isSet("activeDirections")) {
      const auto& d = attrs_.ints("activeDirections");
      if (d.size() != 3) throw error("activeDirections", "takes 3 flags (x y z) on Vec3d nodes, got " + std::to_string(d.size()));
      for (int a = 0; a < 3; ++a) mask_[a] = d[a] != 0 ? 1.0 : 0.0;
    }
    // The rest positions: the nodes' own, or (SOFA's external_rest_shape) another state's, which
    // may move.
    if (attrs_.isSet("external_rest_shape")) {
      external_ = dynamic_cast<MechanicalObject*>(linkedComponent("external_rest_shape"));
      if (!external_) throw error("external_rest_shape", "does not link to a Vec3d MechanicalObject");
      scene().initComponent(*external_);
      externalNodes_ = attrs_.isSet("external_points") ? linkedInts("external_points") : nodes_;
      if (externalNodes_.size() != nodes_.size())
        throw error("external_points", "has " + std::to_string(externalNodes_.size()) + " points, `points` " +
                                           std::to_string(nodes_.size()));
      for (int i : externalNodes_)
        if (i < 0 || i >= external_->size())
          throw error("external_points", "node " + std::to_string(i) + " is out of range ('" + external_->name() + "' has " +
                                             std::to_string(external_->size()) + " nodes)");
    } else if (attrs_.isSet("external_points")) {
      throw error("external_points", "goes with external_rest_shape");
    }
  }
  void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    for (size_t n = 0; n < nodes_.size(); ++n)
      f.col(nodes_[n]) -= k_[n] * (x.col(nodes_[n]) - rest(s, n)).cwiseProduct(mask_);
  }
  void addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const override {
    for (size_t n = 0; n < nodes_.size(); ++n) df.col(nodes_[n]) -= kFactor * k_[n] * dx.col(nodes_[n]).cwiseProduct(mask_);
  }
  void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const override {
    for (int i : nodes_) pairs.push_back({i, i});
  }
  void addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const override {
    for (size_t n = 0; n < nodes_.size(); ++n)
      K.block(K.diagonalSlot(nodes_[n])).diagonal() -= kFactor * k_[n] * mask_;
  }
  // With a moving external rest shape the springs store no energy of their own; measured from
  // the nodes' own rest positions they do.
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    if (external_) return 0.0;
    double e = 0;
    for (size_t n = 0; n < nodes_.size(); ++n)
      e += 0.5 * k_[n] * (x.col(nodes_[n]) - state_->x0.col(nodes_[n])).cwiseProduct(mask_).squaredNorm();
    return e;
  }

 private:
  Eigen::Vector3d rest(const State& s, size_t n) const {
    return external_ ? Eigen::Vector3d(external_->x(s).col(externalNodes_[n])) : Eigen::Vector3d(state_->x0.col(nodes_[n]));
  }

  MechanicalObject* state_ = nullptr;
  MechanicalObject* external_ = nullptr;
  std::vector<int> nodes_, externalNodes_;
  std::vector<double> k_;
  Eigen::Vector3d mask_ = Eigen::Vector3d::Ones();
};

}  // namespace

void registerRestShapeSprings(Registry& r) {
  ComponentSpec s;
  s.name = "RestShapeSpringsForceField";
  s.category = "forcefield";
  s.doc = "Springs pulling nodes back to their rest positions, f = -k (x - x0): an elastic foundation (a compliant "
          "support) where FixedConstraint would hold the nodes rigidly. The rest positions may be another state's "
          "(external_rest_shape, at external_points), followed as it moves; activeDirections limits the springs to "
          "some axes. On a Rigid3d body: a translational spring -k (p - p0) and an angular one -angularStiffness x the "
          "rotation vector from the rest orientation (its own initial pose, or another body's), as SOFA's.";
  s.add(AttrSpec::ints("points").atLeast(0).linked().help("nodes on springs (default: all; a link such as @box.indices; a Rigid3d body: 0)"));
  s.add(AttrSpec::reals("stiffness").req().atLeast(0).unit(Dimension::stiffness()).help("spring stiffness: one value, or one per point"));
  s.add(AttrSpec::reals("angularStiffness").atLeast(0).help("Rigid3d bodies: the torque per radian of turn"));
  s.add(AttrSpec::link("external_rest_shape").help("a MechanicalObject (of the same kind) whose positions are the rest positions"));
  s.add(AttrSpec::ints("external_points").atLeast(0).linked().help("its nodes paired with `points` (default: the same indices)"));
  s.add(AttrSpec::ints("activeDirections").help(
      "flags of the directions the springs act along: 3 (x y z) on Vec3d nodes, SOFA's 7 on a Rigid3d body (x y z, "
      "rotation about x y z, and an unused seventh)"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
  s.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
    if (auto rigid = makeRigidRestShapeSprings(c)) return rigid;
    return std::make_unique<RestShapeSpringsForceField>(c);
  };
  r.add(std::move(s));
}

}  // namespace viscera
