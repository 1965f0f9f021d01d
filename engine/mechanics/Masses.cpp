// Lumped masses: UniformMass (equal share per node), DiagonalMass and MeshMatrixMass (a quarter
// of each tetrahedron's mass to each of its nodes). Each applies gravity as f += m g.
#include <Eigen/Dense>
#include <cmath>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"

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

// DiagonalMass and lumped MeshMatrixMass give the same nodal masses on tetrahedra.
class TetLumpedMass : public LumpedMass {
 public:
  using LumpedMass::LumpedMass;
  void init() override {
    if (spec().find("lumping") && !attrs_.boolean("lumping"))
      throw error("lumping", "only the lumped (diagonal) mass matrix is supported; set lumping=\"true\"");
    state_ = &contextState(*this);
    Topology& topo = contextTopology(*this, "topology", false);
    Eigen::VectorXd vol = lumpedVolumes(topo);
    if (attrs_.isSet("totalMass")) {
      m_ = vol * (attrs_.real("totalMass") / vol.sum());
    } else if (attrs_.isSet("massDensity")) {
      m_ = vol * attrs_.real("massDensity");
    } else if (attrs_.isSet("vertexMass")) {
      m_ = Eigen::VectorXd::Constant(vol.size(), attrs_.real("vertexMass"));
    } else {
      throw error("set massDensity or totalMass");
    }
  }
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
    s.doc = "Lumped mass from the tetrahedra: each node receives a quarter of the mass of each tetrahedron it "
            "belongs to (density x rest volume). totalMass rescales the density. Applies gravity.";
    s.add(AttrSpec::real("massDensity").above(0).unit(Dimension::density()).help("mass per volume"));
    s.add(AttrSpec::real("totalMass").above(0).unit(Dimension::mass()).help("mass of the whole body (wins over massDensity)"));
    s.add(AttrSpec::real("vertexMass").above(0).unit(Dimension::mass()).help("the same mass for every node"));
    if (std::string(name) == "MeshMatrixMass")
      s.add(AttrSpec::boolean("lumping").def("true").help("must be true: only the lumped matrix is supported"));
    s.add(AttrSpec::boolean("computeMassOnRest").def("true").help("masses from rest positions (always)"));
    s.add(AttrSpec::link("topology").help("the tetrahedral topology (default: the one in the node)"));
    s.add(massLink());
    s.factory = [](BuildContext& c) { return std::make_unique<TetLumpedMass>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
