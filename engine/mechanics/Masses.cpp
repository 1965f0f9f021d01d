// Masses: UniformMass (equal share per node), DiagonalMass (a quarter of each tetrahedron's mass
// to each of its nodes) and MeshMatrixMass (the consistent mass matrix of the tetrahedra, or the
// same lumped one). Each applies gravity as f += m g with the lumped masses (M g for a uniform g).
#include <Eigen/Dense>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/ElementMass.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/Placement.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

namespace {

class LumpedMass : public Component, public Mass, public ForceField {
 public:
  using Component::Component;
  bool assemblesUpper() const override { return true; }  // adds no stiffness
  MechanicalObject& mstate() const override { return *state_; }
  const Eigen::VectorXd& nodeMass() const override { return m_; }
  void addForce(State& s, const Eigen::Matrix3Xd&, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    addGravity(m_, scene().gravity(), f);
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override { return gravityEnergy(m_, scene().gravity(), x); }
  bool field(const std::string& name, FieldValue& out) const override { return massField(m_, name, out); }

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
    for (const char* rigidOnly : {"filename", "inertiaMatrix"})
      if (attrs_.isSet(rigidOnly)) throw error(rigidOnly, "applies to the mass of a Rigid3d body, not to Vec3d nodes");
    const int n = state_->size();
    double vm = attrs_.isSet("totalMass") ? attrs_.real("totalMass") / n : attrs_.real("vertexMass");
    if (!attrs_.isSet("totalMass") && !attrs_.isSet("vertexMass"))
      throw error("set totalMass or vertexMass");
    m_ = Eigen::VectorXd::Constant(n, vm);
    // SOFA's link to the mesh the mass follows through topological changes: here, a check that
    // the mesh and the state have the same nodes.
    if (attrs_.isSet("topology")) {
      auto* t = dynamic_cast<Topology*>(linkedComponent("topology"));
      if (!t) throw error("topology", "does not link to a topology");
      scene().initComponent(*dynamic_cast<Component*>(t));
      if (t->points().cols() > 0 && t->points().cols() != n)
        throw error("topology", "has " + std::to_string(t->points().cols()) + " points, but MechanicalObject '" +
                                    state_->name() + "' has " + std::to_string(n) + " nodes");
    }
  }
};

// UniformMass in the node of a rigid body: its mass and inertia (SOFA's RigidMass). The inertia
// about the frame's origin, in the body's frame, is mass x inertiaMatrix (per unit mass; the
// identity unless given), as SOFA sets it; a `.rigid` file (SOFA's Xsp format) gives the mass,
// volume and inertia of a shape. Driven bodies record the mass; integrated ones use it.
class RigidMass : public Component {
 public:
  using Component::Component;
  void init() override {
    RigidObject& body = contextRigid(*this, "mstate");
    if (attrs_.isSet("topology")) throw error("topology", "applies to the mass of Vec3d nodes, not to a Rigid3d body");
    Eigen::Matrix3d perUnitMass = Eigen::Matrix3d::Identity();
    double mass = 0;
    bool massSet = false;
    if (attrs_.isSet("filename")) {
      const std::string path = scene().resolvePath(attrs_.str("filename"));
      try {
        readRigidFile(path, mass, perUnitMass);
      } catch (const Error& e) {
        throw fileErrorFor(e, *this, "filename");
      }
      massSet = true;
    }
    if (attrs_.isSet("totalMass")) mass = attrs_.real("totalMass"), massSet = true;
    else if (attrs_.isSet("vertexMass")) mass = attrs_.real("vertexMass"), massSet = true;
    if (!massSet) throw error("set totalMass, vertexMass or filename");
    if (attrs_.isSet("inertiaMatrix")) {
      const auto& m = attrs_.reals("inertiaMatrix");
      if (m.size() != 9) throw error("inertiaMatrix", "takes 9 numbers (a 3 x 3 matrix, row by row), got " + std::to_string(m.size()));
      perUnitMass = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(m.data());
    }
    if (!perUnitMass.isApprox(perUnitMass.transpose(), 1e-9) || perUnitMass.selfadjointView<Eigen::Lower>().eigenvalues().minCoeff() <= 0)
      throw error(attrs_.isSet("inertiaMatrix") ? "inertiaMatrix" : "filename", "the inertia matrix is not symmetric positive definite");
    body.mass = mass;
    body.inertia = mass * perUnitMass;
  }

 private:
  // SOFA's Xsp rigid file: "Xsp 3.0", then keyword lines: mass (or vertexMass), inrt (9 numbers:
  // inertia per unit mass), and volm, center, frme, ... which SOFA reads and does not use.
  static void readRigidFile(const std::string& path, double& mass, Eigen::Matrix3d& inertia) {
    std::ifstream in(path);
    if (!in) throw Error(SourceLoc{path}, "cannot read the rigid-body file");
    std::string line;
    int n = 0;
    bool haveMass = false;
    while (std::getline(in, line)) {
      ++n;
      std::istringstream ls(line);
      std::string key;
      if (!(ls >> key) || key[0] == '#') continue;
      auto numbers = [&](int count) {
        std::vector<double> v(count);
        for (double& x : v)
          if (!(ls >> x) || !std::isfinite(x))
            throw Error(SourceLoc{path, n}, "'" + key + "' needs " + std::to_string(count) + " finite number(s)");
        return v;
      };
      if (key == "Xsp") continue;
      if (key == "mass" || key == "vertexMass") {
        mass = numbers(1)[0];
        if (!(mass > 0)) throw Error(SourceLoc{path, n}, "the mass must be positive");
        haveMass = true;
      } else if (key == "inrt") {
        const auto v = numbers(9);
        inertia = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(v.data());
      } else if (key != "volm" && key != "center" && key != "cntr" && key != "frme" && key != "grav" && key != "visc" &&
                 key != "stck" && key != "step" && key != "prec") {
        // SOFA reads the other keywords and uses none of them (the body turns about its frame's
        // origin, not the file's centre): so does Viscera.
        throw Error(SourceLoc{path, n}, "unknown keyword '" + key + "' (expected mass, volm, inrt, center, ...)");
      }
    }
    if (!haveMass) throw Error(SourceLoc{path}, "no 'mass' line");
  }
};

// A lumped mass that may also carry the consistent matrix whose rows it sums.
class MatrixMass : public LumpedMass {
 public:
  using LumpedMass::LumpedMass;
  bool consistent() const override { return consistent_; }
  void massPattern(std::vector<std::pair<int, int>>& pairs) const override { matrix_.pattern(pairs); }
  void addMdx(const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& out, double factor) const override {
    matrix_.addMdx(dx, out, factor);
  }
  void addMassMatrix(BlockSparseMatrix& A, double factor) const override { matrix_.addTo(A, factor); }

 protected:
  bool consistent_ = false;
  ElementMassMatrix matrix_;
};

double tetVolume(const Eigen::Matrix3Xd& X, const TetList& T, int e) {
  Eigen::Matrix3d E;
  E << X.col(T(1, e)) - X.col(T(0, e)), X.col(T(2, e)) - X.col(T(0, e)), X.col(T(3, e)) - X.col(T(0, e));
  return std::abs(E.determinant()) / 6.0;
}

// DiagonalMass and lumped MeshMatrixMass give the same nodal masses. MeshMatrixMass without
// lumping (SOFA's default) keeps the consistent matrix: on linear tetrahedra
// M_e = rho V_e / 20 (1 + delta_ij) I_3 over the element's four nodes; on hexahedra (a grid) the
// exact matrix of trilinear elements, rho int N_i N_j dV. Its rows sum to the lumped masses (a
// quarter, or an eighth, of rho V_e per node).
class MeshMass : public MatrixMass {
 public:
  using MatrixMass::MatrixMass;
  void init() override {
    consistent_ = spec().find("lumping") && !attrs_.boolean("lumping");
    state_ = &contextState(*this);
    Topology& topo = contextTopology(*this, "topology", true);
    // Element matrices for a unit density: their row sums are each node's share of the volume.
    Eigen::MatrixXi elements;
    std::vector<Eigen::MatrixXd> unit;
    if (topo.tetrahedra().cols() > 0) {
      const TetList& T = topo.tetrahedra();
      lumpedVolumes(topo);  // checks the node indices
      elements = T;
      const Eigen::Matrix4d shape = (Eigen::Matrix4d::Ones() + Eigen::Matrix4d::Identity()) / 20.0;
      for (int e = 0; e < T.cols(); ++e) unit.push_back(tetVolume(state_->x0, T, e) * shape);
    } else {
      const HexList& H = topo.hexahedra();
      const int n = state_->size();
      elements.resize(8, static_cast<Eigen::Index>(H.size()));
      for (size_t e = 0; e < H.size(); ++e) {
        Eigen::Matrix<double, 3, 8> corners;
        for (int k = 0; k < 8; ++k) {
          if (H[e][k] < 0 || H[e][k] >= n)
            throw error("hexahedron " + std::to_string(e) + " refers to node " + std::to_string(H[e][k]) +
                        ", but the MechanicalObject has " + std::to_string(n) + " nodes");
          elements(k, static_cast<Eigen::Index>(e)) = H[e][k];
          corners.col(k) = state_->x0.col(H[e][k]);
        }
        unit.push_back(hexahedronMassMatrix(corners, [](const Eigen::VectorXd&) { return 1.0; }));
      }
    }
    matrix_.set(elements, unit);
    const Eigen::VectorXd vol = matrix_.rowSums(state_->size());
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
    for (auto& M : unit) M *= density;
    matrix_.set(elements, std::move(unit));
  }
};

// SOFA's NodalMassDensity: the density of a body, one value or one per node, read by FEMMass in
// the same node or below.
class NodalMassDensity : public Component {
 public:
  using Component::Component;
  void init() override {
    const auto& v = attrs_.reals("property");
    density = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
  }
  Eigen::VectorXd density;
};

// SOFA's FEMMass: the consistent mass matrix of the elements, M_ij = int rho N_i N_j dV with the
// element's shape functions, by Gauss quadrature (4 points on a tetrahedron, 2 x 2 x 2 on a
// hexahedron: exact for a uniform density on tetrahedra and parallelepipeds). A per-node density
// is interpolated with the shape functions.
class FEMMass : public MatrixMass {
 public:
  using MatrixMass::MatrixMass;
  void init() override {
    consistent_ = true;
    state_ = &contextState(*this);
    NodalMassDensity* rho = node().findInContext<NodalMassDensity>();
    if (!rho) throw error("needs a NodalMassDensity in its node or above (the density of the body)");
    scene().initComponent(*rho);
    const int n = state_->size();
    if (rho->density.size() != 1 && rho->density.size() != n)
      throw rho->error("property", "has " + std::to_string(rho->density.size()) + " values; give one, or one per node (" +
                                       std::to_string(n) + ")");
    auto densityAt = [&](const Eigen::VectorXi& nodes, const Eigen::VectorXd& N) {
      if (rho->density.size() == 1) return rho->density[0];
      double d = 0;
      for (int k = 0; k < nodes.size(); ++k) d += N[k] * rho->density[nodes[k]];
      return d;
    };
    const bool hexa = attrs_.str("template").find("Hexahedron") != std::string::npos;
    Topology& topo = hexa ? contextHexahedra(*this) : contextTopology(*this, "topology", false);
    const Eigen::Matrix3Xd& X = state_->x0;
    Eigen::MatrixXi elements;
    std::vector<Eigen::MatrixXd> Me;
    if (hexa) {
      const HexList& H = topo.hexahedra();
      if (H.empty()) throw error("template", "Vec3,Hexahedron needs a topology with hexahedra");
      elements.resize(8, static_cast<Eigen::Index>(H.size()));
      for (size_t e = 0; e < H.size(); ++e) {
        Eigen::VectorXi nodes(8);
        Eigen::Matrix<double, 3, 8> corners;
        for (int k = 0; k < 8; ++k) {
          nodes[k] = elements(k, e) = checkedNode(H[e][k], n);
          corners.col(k) = X.col(nodes[k]);
        }
        const Eigen::MatrixXd M = hexahedronMassMatrix(corners, [&](const Eigen::VectorXd& N) { return densityAt(nodes, N); });
        Me.push_back(M);
      }
    } else {
      const TetList& T = topo.tetrahedra();
      if (T.cols() == 0) throw error("template", "Vec3,Tetrahedron needs a topology with tetrahedra");
      elements = T;
      // The 4-point rule of degree 2: barycentric (a, b, b, b) and permutations, weight V / 4.
      const double a = 0.5854101966249685, b = 0.1381966011250105;
      for (int e = 0; e < T.cols(); ++e) {
        Eigen::VectorXi nodes(4);
        for (int k = 0; k < 4; ++k) nodes[k] = checkedNode(T(k, e), n);
        const double V = tetVolume(X, T, e);
        Eigen::MatrixXd M = Eigen::MatrixXd::Zero(4, 4);
        for (int q = 0; q < 4; ++q) {
          Eigen::VectorXd N = Eigen::VectorXd::Constant(4, b);
          N[q] = a;
          M += V / 4 * densityAt(nodes, N) * N * N.transpose();
        }
        Me.push_back(M);
      }
    }
    matrix_.set(elements, std::move(Me));
    m_ = matrix_.rowSums(n);
  }

 private:
  int checkedNode(int i, int n) const {
    if (i < 0 || i >= n)
      throw error("an element refers to node " + std::to_string(i) + ", but the MechanicalObject has " + std::to_string(n) + " nodes");
    return i;
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
            "Rigid3d body it is the body's mass and inertia (mass x inertiaMatrix about the frame's origin, or from a "
            "SOFA .rigid file); a driven body records it, an integrated one moves with it.";
    s.add(AttrSpec::real("totalMass").above(0).unit(Dimension::mass()).help("mass of the whole body (wins over vertexMass)"));
    s.add(AttrSpec::real("vertexMass").above(0).unit(Dimension::mass()).help("mass of each node"));
    s.add(AttrSpec::file("filename").help("Rigid3d bodies: a SOFA .rigid file (mass, volm, inrt, center)"));
    s.add(AttrSpec::reals("inertiaMatrix").help("Rigid3d bodies: inertia per unit mass about the frame's origin, body frame, 9 numbers (default: identity)"));
    s.add(AttrSpec::link("topology").help("SOFA's mesh of the nodes (it follows topological changes there); checked to have the state's nodes"));
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
                ? "Lumped mass from the tetrahedra (or, without them, the hexahedra of a grid): each node receives a "
                  "quarter (an eighth) of the mass of each element it belongs to (density x rest volume). totalMass "
                  "rescales the density. Applies gravity."
                : "Mass matrix of the tetrahedra (density x rest volume): the consistent matrix rho V / 20 (1 + delta_ij) "
                  "of linear elements, as SOFA, or with lumping=\"true\" its row sums on the diagonal (as DiagonalMass). "
                  "On hexahedra (a grid, when there are no tetrahedra) the exact matrix of trilinear elements; SOFA "
                  "uses rho V / 20 on the diagonal and rho V / 40 on the edges there, a matrix that is not positive "
                  "definite. totalMass rescales the density. Applies gravity.";
    s.add(AttrSpec::real("massDensity").above(0).unit(Dimension::density()).help("mass per volume"));
    s.add(AttrSpec::real("totalMass").above(0).unit(Dimension::mass()).help("mass of the whole body (wins over massDensity)"));
    s.add(AttrSpec::real("vertexMass").above(0).unit(Dimension::mass()).help("the same mass for every node"));
    if (std::string(name) == "MeshMatrixMass")
      s.add(AttrSpec::boolean("lumping").def("false").help("lump the mass on the diagonal; false keeps the consistent mass matrix (as SOFA)"));
    s.add(AttrSpec::boolean("computeMassOnRest").def("true").help("masses from rest positions (always)"));
    s.add(AttrSpec::link("topology").help("the tetrahedral (or hexahedral) topology (default: the nearest in the node or above)"));
    s.add(massLink());
    s.factory = [](BuildContext& c) { return std::make_unique<MeshMass>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "NodalMassDensity";
    s.category = "mass";
    s.doc = "The density of a body (mass per volume), one value or one per node, for FEMMass in the same node or below.";
    s.add(AttrSpec::reals("property").req().above(0).unit(Dimension::density()).help("density: one value, or one per node"));
    s.factory = [](BuildContext& c) { return std::make_unique<NodalMassDensity>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "FEMMass";
    s.category = "mass";
    s.doc = "Consistent mass matrix of the elements, M_ij = integral of rho N_i N_j with the linear tetrahedron's or "
            "trilinear hexahedron's shape functions (Gauss quadrature: 4 points, 2 x 2 x 2), the density from the "
            "NodalMassDensity above. Applies gravity.";
    s.add(AttrSpec::choice("template", {"Vec3,Tetrahedron", "Vec3d,Tetrahedron", "Vec3,Hexahedron", "Vec3d,Hexahedron"})
              .def("Vec3,Tetrahedron")
              .help("the element type"));
    s.add(AttrSpec::link("topology").help("the topology with the elements (default: the one in the node or above)"));
    s.add(massLink());
    s.factory = [](BuildContext& c) { return std::make_unique<FEMMass>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
