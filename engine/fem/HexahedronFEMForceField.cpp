// Linear elastic trilinear hexahedra, as SOFA's HexahedronFEMForceField (methods small, large,
// polar) and its newer element force fields on hexahedra (LinearSmallStrainFEMForceField,
// CorotationalFEMForceField). The element stiffness K0 (24 x 24) is integrated at rest with
// 2 x 2 x 2 Gauss points (exact for parallelepipeds). Corotational elements turn it with a
// rotation Q from rest to current: f_e = -Q K0 (Q^T x - X), linearised as Q K0 Q^T (SOFA's,
// without the derivative of Q). The rotations:
//   large: each configuration's frame from the mean edges along the element's first two axes,
//          made orthonormal (x first, then z = x * y, then y = z * x); Q = R(x)^T R(X);
//   polar: the rotation of the polar decomposition of the mean edges along its three axes;
//   centroid polar (the newer force field): the rotation of the polar decomposition of
//          sum_i (x_i - c)(X_i - C)^T, which maps rest to current directly.
#include <Eigen/Dense>
#include <Eigen/SVD>
#include <array>
#include <cmath>
#include <memory>

#include "engine/fem/HexahedronFEMForceField.h"

#include "core/Registry.h"
#include "engine/mechanics/ElementMass.h"
#include "core/Scene.h"
#include "engine/Roles.h"
#include "solvers/linear/LinearSolver.h"
#include "core/State.h"
#include "engine/fem/TetKernel.h"
#include "engine/mechanics/MechanicalObject.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

namespace {

using Mat24 = Eigen::Matrix<double, 24, 24>;
using Nodes8 = Eigen::Matrix<double, 3, 8>;

// Corner signs of the reference cube in SOFA's node order.
constexpr int kSign[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                             {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};

enum class HexMethod { Small, Large, Polar, CentroidPolar };

// d N_k / d xi at the reference point xi, one row per node.
Eigen::Matrix<double, 8, 3> shapeGradients(const Eigen::Vector3d& xi) {
  Eigen::Matrix<double, 8, 3> dN;
  for (int k = 0; k < 8; ++k) {
    const double a = 1 + kSign[k][0] * xi[0], b = 1 + kSign[k][1] * xi[1], c = 1 + kSign[k][2] * xi[2];
    dN.row(k) << kSign[k][0] * b * c / 8, kSign[k][1] * a * c / 8, kSign[k][2] * a * b / 8;
  }
  return dN;
}

Mat24 elementStiffness(const Nodes8& X, const fem::Lame& law) {
  Mat24 K = Mat24::Zero();
  const double g = 1.0 / std::sqrt(3.0);
  for (int q = 0; q < 8; ++q) {
    const Eigen::Vector3d xi(kSign[q][0] * g, kSign[q][1] * g, kSign[q][2] * g);
    const Eigen::Matrix<double, 8, 3> dN = shapeGradients(xi);
    const Eigen::Matrix3d J = X * dN;  // dX/dxi
    const double detJ = J.determinant();
    const Eigen::Matrix<double, 8, 3> G = dN * J.inverse();  // dN/dX
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 8; ++j) {
        // sigma(grad(N_j e_c)) contracted with grad(N_i e_r): lambda g_i g_j^T + mu g_j g_i^T + mu (g_i.g_j) I.
        const Eigen::Vector3d gi = G.row(i).transpose(), gj = G.row(j).transpose();
        Eigen::Matrix3d B = law.lambda * gi * gj.transpose() + law.mu * gj * gi.transpose();
        B.diagonal().array() += law.mu * gi.dot(gj);
        K.block<3, 3>(3 * i, 3 * j) += std::abs(detJ) * B;
      }
  }
  return K;
}

Eigen::Matrix3d orthogonalFactor(const Eigen::Matrix3d& A) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0) U.col(2) = -U.col(2);
  return U * V.transpose();
}

// The frame (rows) of an element for SOFA's large and polar methods.
Eigen::Matrix3d frame(HexMethod m, const Nodes8& p) {
  const Eigen::Vector3d ex = p.col(1) - p.col(0) + p.col(2) - p.col(3) + p.col(5) - p.col(4) + p.col(6) - p.col(7);
  const Eigen::Vector3d ey = p.col(3) - p.col(0) + p.col(2) - p.col(1) + p.col(7) - p.col(4) + p.col(6) - p.col(5);
  Eigen::Matrix3d R;
  if (m == HexMethod::Large) {
    const Eigen::Vector3d x = ex.normalized();
    const Eigen::Vector3d z = x.cross(ey).normalized();
    R.row(0) = x;
    R.row(1) = z.cross(x);
    R.row(2) = z;
    return R;
  }
  const Eigen::Vector3d ez = p.col(4) - p.col(0) + p.col(5) - p.col(1) + p.col(6) - p.col(2) + p.col(7) - p.col(3);
  Eigen::Matrix3d A;
  A.row(0) = ex;
  A.row(1) = ey;
  A.row(2) = ez;
  return orthogonalFactor(A);  // A = R S: R is the rows frame
}

class HexahedronFEM : public Component, public ForceField, public Stateful, public RotationFinder {
 public:
  using Component::Component;

  void init() override {
    state_ = &contextState(*this);
    if (spec().find("method")) {
      const std::string& m = attrs_.str("method");
      method_ = m == "small" ? HexMethod::Small : m == "polar" ? HexMethod::Polar : HexMethod::Large;
    } else {
      method_ = spec().find("rotationMethod") ? HexMethod::CentroidPolar : HexMethod::Small;
    }
    Topology& topo = contextHexahedra(*this);
    hexa_ = topo.hexahedra();
    const int n = state_->size();
    for (size_t e = 0; e < hexa_.size(); ++e)
      for (int k : hexa_[e])
        if (k < 0 || k >= n)
          throw error("hexahedron " + std::to_string(e) + " refers to node " + std::to_string(k) + ", but the MechanicalObject has " +
                      std::to_string(n) + " nodes");
    const auto E = linkedReals("youngModulus");
    if (E.size() != 1 && E.size() != hexa_.size())
      throw error("youngModulus", "has " + std::to_string(E.size()) + " values; give one, or one per hexahedron (" +
                                      std::to_string(hexa_.size()) + ")");
    const double nu = attrs_.real("poissonRatio");
    K0_.resize(hexa_.size());
    rest_.resize(hexa_.size());
    for (size_t e = 0; e < hexa_.size(); ++e) {
      rest_[e] = gather(state_->x0, e);
      if ((rest_[e] * shapeGradients(Eigen::Vector3d::Zero())).determinant() <= 0)
        throw error("hexahedron " + std::to_string(e) + " is inverted or flat at rest (its nodes are not in SOFA's order)");
      K0_[e] = elementStiffness(rest_[e], fem::Lame::fromYoungPoisson(E.size() == 1 ? E[0] : E[e], nu));
      restFrame_.push_back(method_ == HexMethod::Large || method_ == HexMethod::Polar ? frame(method_, rest_[e])
                                                                                       : Eigen::Matrix3d::Identity());
    }
  }
  MechanicalObject& mstate() const override { return *state_; }
  void nodeRotations(const State& s, std::vector<Eigen::Matrix3d>& R) const override {
    // The hexahedra's node lists, read as one array of 8 ints per element.
    static_assert(sizeof(std::array<int, 8>) == 8 * sizeof(int), "std::array<int, 8> is not 8 packed ints");
    const std::vector<Eigen::Matrix3d>& Q = stateIn<Live>(s).Q;
    R = averageNodeRotations(state_->size(), hexa_.empty() ? nullptr : hexa_[0].data(), 8, Q.data(), static_cast<int>(Q.size()));
  }
  // The rest -> current rotation of each element at the last addForce.
  struct Live : ComponentStateOf<Live> {
    std::vector<Eigen::Matrix3d> Q;
    void save(StateWriter& out) const override { out.put(Q); }
    void load(StateReader& in) override { in.getSameSize(Q, "element rotations"); }
  };
  std::unique_ptr<ComponentState> initialState() const override {
    auto l = std::make_unique<Live>();
    l->Q.assign(hexa_.size(), Eigen::Matrix3d::Identity());
    return l;
  }

  void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    std::vector<Eigen::Matrix3d>& Q = stateIn<Live>(s).Q;
    for (size_t e = 0; e < hexa_.size(); ++e) {
      const Nodes8 p = gather(x, e);
      Q[e] = rotation(e, p);
      Nodes8 u = Q[e].transpose() * p - rest_[e];
      const Eigen::Matrix<double, 24, 1> fe = -K0_[e] * Eigen::Map<const Eigen::Matrix<double, 24, 1>>(u.data());
      for (int k = 0; k < 8; ++k) f.col(hexa_[e][k]) += Q[e] * fe.segment<3>(3 * k);
    }
  }
  void addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const override {
    const std::vector<Eigen::Matrix3d>& Q = stateIn<Live>(s).Q;
    for (size_t e = 0; e < hexa_.size(); ++e) {
      Nodes8 d = Q[e].transpose() * gather(dx, e);
      const Eigen::Matrix<double, 24, 1> fe = -kFactor * (K0_[e] * Eigen::Map<const Eigen::Matrix<double, 24, 1>>(d.data()));
      for (int k = 0; k < 8; ++k) df.col(hexa_[e][k]) += Q[e] * fe.segment<3>(3 * k);
    }
  }
  void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const override {
    for (const auto& h : hexa_)
      for (int i = 0; i < 8; ++i)
        for (int j = i + 1; j < 8; ++j) pairs.push_back({h[i], h[j]});
  }
  void prepareAssembly(const BlockSparseMatrix& K) override {
    slots_.resize(hexa_.size());
    for (size_t e = 0; e < hexa_.size(); ++e)
      for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j) slots_[e][8 * i + j] = K.slot(hexa_[e][i], hexa_[e][j]);
  }
  void addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const override {
    const std::vector<Eigen::Matrix3d>& Q = stateIn<Live>(s).Q;
    for (size_t e = 0; e < hexa_.size(); ++e)
      for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j)
          K.block(slots_[e][8 * i + j]) -= kFactor * Q[e] * K0_[e].block<3, 3>(3 * i, 3 * j) * Q[e].transpose();
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    double w = 0;
    for (size_t e = 0; e < hexa_.size(); ++e) {
      Nodes8 u = rotation(e, gather(x, e)).transpose() * gather(x, e) - rest_[e];
      const Eigen::Map<const Eigen::Matrix<double, 24, 1>> uv(u.data());
      w += 0.5 * uv.dot(K0_[e] * uv);
    }
    return w;
  }
  std::vector<int> invertedElements(const Eigen::Matrix3Xd& x) const override {
    std::vector<int> bad;
    const Eigen::Matrix<double, 8, 3> dN = shapeGradients(Eigen::Vector3d::Zero());
    for (size_t e = 0; e < hexa_.size(); ++e)
      if ((gather(x, e) * dN).determinant() <= 0) bad.push_back(static_cast<int>(e));
    return bad;
  }

 protected:
  Nodes8 gather(const Eigen::Matrix3Xd& x, size_t e) const {
    Nodes8 p;
    for (int k = 0; k < 8; ++k) p.col(k) = x.col(hexa_[e][k]);
    return p;
  }
  // Q: rest to current.
  Eigen::Matrix3d rotation(size_t e, const Nodes8& p) const {
    switch (method_) {
      case HexMethod::Small: return Eigen::Matrix3d::Identity();
      case HexMethod::Large:
      case HexMethod::Polar: return frame(method_, p).transpose() * restFrame_[e];
      case HexMethod::CentroidPolar: {
        const Eigen::Vector3d c = p.rowwise().mean(), C = rest_[e].rowwise().mean();
        return orthogonalFactor((p.colwise() - c) * (rest_[e].colwise() - C).transpose());
      }
    }
    return Eigen::Matrix3d::Identity();
  }


  MechanicalObject* state_ = nullptr;
  HexMethod method_ = HexMethod::Large;
  HexList hexa_;
  std::vector<Mat24, Eigen::aligned_allocator<Mat24>> K0_;
  std::vector<Nodes8, Eigen::aligned_allocator<Nodes8>> rest_;
  std::vector<Eigen::Matrix3d> restFrame_;
  std::vector<std::array<int, 64>> slots_;
};

// SOFA's HexahedronFEMForceFieldAndMass: the force field and the mass of the same hexahedra, the
// consistent matrix of trilinear elements (rho times int N_i N_j dV, exact on parallelepipeds) or,
// with lumpedMass, its row sums. Gravity acts through the lumped masses (M g for a uniform g).
class HexahedronFEMAndMass : public HexahedronFEM, public Mass {
 public:
  using HexahedronFEM::HexahedronFEM;
  void init() override {
    HexahedronFEM::init();
    const double rho = attrs_.real("density");
    Eigen::MatrixXi elements(8, static_cast<Eigen::Index>(hexa_.size()));
    std::vector<Eigen::MatrixXd> Me;
    for (size_t e = 0; e < hexa_.size(); ++e) {
      for (int k = 0; k < 8; ++k) elements(k, static_cast<Eigen::Index>(e)) = hexa_[e][k];
      Me.push_back(hexahedronMassMatrix(rest_[e], [rho](const Eigen::VectorXd&) { return rho; }));
    }
    matrix_.set(elements, std::move(Me));
    m_ = matrix_.rowSums(state_->size());
    consistent_ = !attrs_.boolean("lumpedMass");
  }
  MechanicalObject& mstate() const override { return *state_; }
  void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, Eigen::Matrix3Xd& f) const override {
    HexahedronFEM::addForce(s, x, v, f);
    addGravity(m_, scene().gravity(), f);
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    return HexahedronFEM::potentialEnergy(x) + gravityEnergy(m_, scene().gravity(), x);
  }
  bool field(const std::string& name, FieldValue& out) const override { return massField(m_, name, out); }
  const Eigen::VectorXd& nodeMass() const override { return m_; }
  bool consistent() const override { return consistent_; }
  void massPattern(std::vector<std::pair<int, int>>& pairs) const override { matrix_.pattern(pairs); }
  void addMdx(const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& out, double factor) const override {
    matrix_.addMdx(dx, out, factor);
  }
  void addMassMatrix(BlockSparseMatrix& A, double factor) const override { matrix_.addTo(A, factor); }

 private:
  ElementMassMatrix matrix_;
  Eigen::VectorXd m_;
  bool consistent_ = true;
};

void addHexahedronFEMAttributes(ComponentSpec& s) {
  s.add(AttrSpec::reals("youngModulus").def("5000").above(0).unit(Dimension::pressure()).linked().help("Young's modulus: one value, or one per hexahedron"));
  s.add(AttrSpec::real("poissonRatio").def("0.45").above(-1).below(0.5).help("Poisson's ratio, in (-1, 0.5)"));
  s.add(AttrSpec::choice("method", {"large", "small", "polar"}).def("large").help("small | large | polar"));
  // SOFA's switch to rebuild the element stiffness from the deformed shape; its default (false),
  // the stiffness of the rest shape, is what is computed here.
  s.add(AttrSpec::choice("updateStiffnessMatrix", {"false", "0"}).def("false").help(
      "SOFA's rebuilding of the element stiffness from the deformed shape: only false (the rest shape's stiffness)"));
  s.add(AttrSpec::link("topology").help("topology with hexahedra (default: the nearest in the node or above)"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
}

}  // namespace

void registerHexahedronFEM(Registry& r) {
  {
    ComponentSpec s;
    s.name = "HexahedronFEMForceField";
    // SOFA's HexahedralFEMForceField: the same corotational hexahedra (frames from the mean edges or
    // their polar decomposition); its stiffness is a closed form exact for box-shaped cells only.
    s.aliases = {"HexahedralFEMForceField"};
    s.category = "forcefield";
    s.doc = "Linear elastic trilinear hexahedra, as SOFA's (stiffness by 2 x 2 x 2 Gauss points). method=small: linear; "
            "large: corotational with the element frame from its mean edges (SOFA's default); polar: corotational with "
            "the polar decomposition of the mean edges. The implicit solve uses R K0 R^T as SOFA does. SOFA's "
            "HexahedralFEMForceField is the same element with a closed-form stiffness that is exact for box-shaped "
            "cells (a regular grid) only; it maps here, exact on every cell.";
    addHexahedronFEMAttributes(s);
    s.factory = [](BuildContext& c) { return std::make_unique<HexahedronFEM>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "HexahedronFEMForceFieldAndMass";
    s.aliases = {"HexahedralFEMForceFieldAndMass"};
    s.category = "forcefield";
    s.doc = "HexahedronFEMForceField and the mass of the same hexahedra in one component, as SOFA's: the consistent mass "
            "matrix of trilinear elements (density times the integral of N_i N_j, 2 x 2 x 2 Gauss points, exact on "
            "parallelepipeds) or, with lumpedMass, its row sums. Applies gravity. SOFA's own element matrix differs: "
            "all its entries are rho V 8/27 (rank one, rows summing to 64/27 rho V per node, about 19 times the "
            "element's mass in all) while its gravity uses rho V / 8 per node; Viscera keeps the true mass.";
    addHexahedronFEMAttributes(s);
    s.add(AttrSpec::real("density").def("1").above(0).unit(Dimension::density()).help("mass per volume"));
    s.add(AttrSpec::boolean("lumpedMass").def("false").help("lump the mass on the diagonal (row sums); false keeps the consistent matrix"));
    s.factory = [](BuildContext& c) { return std::make_unique<HexahedronFEMAndMass>(c); };
    r.add(std::move(s));
  }
}

std::unique_ptr<Component> makeHexahedronElementFEM(BuildContext& c) { return std::make_unique<HexahedronFEM>(c); }

}  // namespace viscera
