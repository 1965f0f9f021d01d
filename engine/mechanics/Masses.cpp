// Masses: UniformMass (equal share per node), DiagonalMass (a quarter of each tetrahedron's mass
// to each of its nodes) and MeshMatrixMass (the consistent mass matrix of the tetrahedra, or the
// same lumped one). Each applies gravity as f += m g with the lumped masses (M g for a uniform g).
#include <Eigen/Dense>
#include <cmath>
#include <stdexcept>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

namespace {

class LumpedMass : public Component, public Mass, public ForceField {
 public:
  using Component::Component;
  MechanicalObject& mstate() const override { return *state_; }
  const Eigen::VectorXd& nodeMass() const override { return m_; }
  void addForce(const Eigen::Matrix3Xd&, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) override {
    const Eigen::Vector3d g = scene().gravity();
    if (g.isZero()) return;
    for (int i = 0; i < f.cols(); ++i) f.col(i) += m_[i] * g;
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    double e = 0;
    for (int i = 0; i < x.cols(); ++i) e -= m_[i] * scene().gravity().dot(x.col(i));
    return e;
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "vertexMass") out.values.assign(m_.data(), m_.data() + m_.size());
    else if (name == "totalMass") out.values = {m_.sum()};
    else return false;
    return true;
  }

 protected:
  MechanicalObject* state_ = nullptr;
  Eigen::VectorXd m_;

  // Per-node volume share (a quarter of each tetrahedron's rest volume).
  Eigen::VectorXd lumpedVolumes(Topology& topo) {
    const TetList& T = topo.tetrahedra();
    if (T.cols() == 0) throw error("needs a topology with tetrahedra");
    const Eigen::Matrix3Xd& X = state_->x0;
    Eigen::VectorXd vol = Eigen::VectorXd::Zero(X.cols());
    for (int e = 0; e < T.cols(); ++e) {
      for (int k = 0; k < 4; ++k)
        if (T(k, e) < 0 || T(k, e) >= X.cols())
          throw error("tetrahedron " + std::to_string(e) + " refers to node " + std::to_string(T(k, e)) +
                      ", but the MechanicalObject has " + std::to_string(X.cols()) + " nodes");
      Eigen::Matrix3d E;
      E << X.col(T(1, e)) - X.col(T(0, e)), X.col(T(2, e)) - X.col(T(0, e)), X.col(T(3, e)) - X.col(T(0, e));
      double v = std::abs(E.determinant()) / 6.0;
      for (int k = 0; k < 4; ++k) vol[T(k, e)] += v / 4.0;
    }
    return vol;
  }
};

class UniformMass : public LumpedMass {
 public:
  using LumpedMass::LumpedMass;
  void init() override {
    state_ = &contextState(*this);
    const int n = state_->size();
    double vm = attrs_.isSet("totalMass") ? attrs_.real("totalMass") / n : attrs_.real("vertexMass");
    if (!attrs_.isSet("totalMass") && !attrs_.isSet("vertexMass"))
      throw error("set totalMass or vertexMass");
    m_ = Eigen::VectorXd::Constant(n, vm);
  }
};

// UniformMass in the node of a rigid body: the instrument's mass. The body is driven, so the mass
// is recorded (and reported) but does not enter any equation.
class RigidMass : public Component {
 public:
  using Component::Component;
  void init() override {
    RigidObject& body = contextRigid(*this, "mstate");
    if (!attrs_.isSet("totalMass") && !attrs_.isSet("vertexMass")) throw error("set totalMass or vertexMass");
    body.mass = attrs_.isSet("totalMass") ? attrs_.real("totalMass") : attrs_.real("vertexMass");
  }
};

// DiagonalMass and lumped MeshMatrixMass give the same nodal masses on tetrahedra. MeshMatrixMass
// without lumping (SOFA's default) keeps the consistent matrix of linear tetrahedra,
// M_e = rho V_e / 20 (1 + delta_ij) I_3 over the element's four nodes, whose rows sum to the
// lumped masses (a quarter of rho V_e per node).
class TetLumpedMass : public LumpedMass {
 public:
  using LumpedMass::LumpedMass;
  void init() override {
    consistent_ = spec().find("lumping") && !attrs_.boolean("lumping");
    state_ = &contextState(*this);
    Topology& topo = contextTopology(*this, "topology", false);
    Eigen::VectorXd vol = lumpedVolumes(topo);
    double density = 0;
    if (attrs_.isSet("totalMass")) {
      density = attrs_.real("totalMass") / vol.sum();
    } else if (attrs_.isSet("massDensity")) {
      density = attrs_.real("massDensity");
    } else if (attrs_.isSet("vertexMass")) {
      if (consistent_) throw error("vertexMass", "gives a lumped mass: set lumping=\"true\", or give massDensity or totalMass");
      m_ = Eigen::VectorXd::Constant(vol.size(), attrs_.real("vertexMass"));
      return;
    } else {
      throw error("set massDensity or totalMass");
    }
    m_ = vol * density;
    if (!consistent_) return;
    tets_ = topo.tetrahedra();
    elementMass_.resize(tets_.cols());
    const Eigen::Matrix3Xd& X = state_->x0;
    for (int e = 0; e < tets_.cols(); ++e) {
      Eigen::Matrix3d E;
      E << X.col(tets_(1, e)) - X.col(tets_(0, e)), X.col(tets_(2, e)) - X.col(tets_(0, e)),
          X.col(tets_(3, e)) - X.col(tets_(0, e));
      elementMass_[e] = density * std::abs(E.determinant()) / 6.0;
    }
  }
  bool consistent() const override { return consistent_; }
  void massPattern(std::vector<std::pair<int, int>>& pairs) const override {
    for (int e = 0; e < tets_.cols(); ++e)
      for (int i = 0; i < 4; ++i)
        for (int j = i + 1; j < 4; ++j) pairs.push_back({tets_(i, e), tets_(j, e)});
  }
  void addMdx(const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& out, double factor) const override {
    for (int e = 0; e < tets_.cols(); ++e) {
      const double off = factor * elementMass_[e] / 20.0;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int j = 0; j < 4; ++j) sum += dx.col(tets_(j, e));
      // (M_e dx)_i = m/20 (sum_j dx_j + dx_i)
      for (int i = 0; i < 4; ++i) out.col(tets_(i, e)) += off * (sum + dx.col(tets_(i, e)));
    }
  }
  void addMassMatrix(BlockSparseMatrix& A, double factor) const override {
    for (int e = 0; e < tets_.cols(); ++e) {
      const double off = factor * elementMass_[e] / 20.0;
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
          const int slot = A.slot(tets_(i, e), tets_(j, e));
          if (slot < 0) throw std::logic_error("MeshMatrixMass: the matrix pattern lacks the mass's node pairs");
          A.block(slot).diagonal().array() += i == j ? 2 * off : off;
        }
    }
  }

 private:
  bool consistent_ = false;
  TetList tets_;
  std::vector<double> elementMass_;
};

AttrSpec massLink() { return AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"); }

}  // namespace

void registerMasses(Registry& r) {
  {
    ComponentSpec s;
    s.name = "UniformMass";
    s.category = "mass";
    s.doc = "The same mass for every node: totalMass / #nodes, or vertexMass. Applies gravity. In the node of a "
            "Rigid3d body it is the body's mass (recorded; driven bodies do not integrate it).";
    s.add(AttrSpec::real("totalMass").above(0).unit(Dimension::mass()).help("mass of the whole body (wins over vertexMass)"));
    s.add(AttrSpec::real("vertexMass").above(0).unit(Dimension::mass()).help("mass of each node"));
    s.add(massLink());
    s.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
      if (c.node().find<RigidObject>() && !c.node().find<MechanicalObject>()) return std::make_unique<RigidMass>(c);
      return std::make_unique<UniformMass>(c);
    };
    r.add(std::move(s));
  }
  for (const char* name : {"DiagonalMass", "MeshMatrixMass"}) {
    ComponentSpec s;
    s.name = name;
    s.category = "mass";
    s.doc = std::string(name) == "DiagonalMass"
                ? "Lumped mass from the tetrahedra: each node receives a quarter of the mass of each tetrahedron it "
                  "belongs to (density x rest volume). totalMass rescales the density. Applies gravity."
                : "Mass matrix of the tetrahedra (density x rest volume): the consistent matrix rho V / 20 (1 + delta_ij) "
                  "of linear elements, as SOFA, or with lumping=\"true\" its row sums on the diagonal (as DiagonalMass). "
                  "totalMass rescales the density. Applies gravity.";
    s.add(AttrSpec::real("massDensity").above(0).unit(Dimension::density()).help("mass per volume"));
    s.add(AttrSpec::real("totalMass").above(0).unit(Dimension::mass()).help("mass of the whole body (wins over massDensity)"));
    s.add(AttrSpec::real("vertexMass").above(0).unit(Dimension::mass()).help("the same mass for every node"));
    if (std::string(name) == "MeshMatrixMass")
      s.add(AttrSpec::boolean("lumping").def("false").help("lump the mass on the diagonal; false keeps the consistent mass matrix (as SOFA)"));
    s.add(AttrSpec::boolean("computeMassOnRest").def("true").help("masses from rest positions (always)"));
    s.add(AttrSpec::link("topology").help("the tetrahedral topology (default: the one in the node)"));
    s.add(massLink());
    s.factory = [](BuildContext& c) { return std::make_unique<TetLumpedMass>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
