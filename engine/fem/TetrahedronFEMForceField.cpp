#include <Eigen/Dense>
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/fem/HexahedronFEMForceField.h"
#include "engine/fem/TetSimd.h"
#include "io/scene/InputCache.h"

#include <stdexcept>

#include "engine/Coloring.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/topology/GridSplit.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

using fem::Mat12;
using fem::Mat34;

void TetrahedronFEMForceField::init() {
  state_ = &contextState(*this);
  // SOFA's element force fields fix the method by their type (LinearSmallStrain: small;
  // Corotational: its rotationMethod, a polar decomposition).
  const std::string m = spec().find("method") ? attrs_.str("method") : spec().find("rotationMethod") ? "polar" : "small";
  method_ = m == "small" ? fem::Method::Small : m == "polar" || m == "svd" ? fem::Method::Polar : fem::Method::Large;
  svd_ = m == "svd";
  if (spec().find("updateStiffnessMatrix") && attrs_.boolean("updateStiffnessMatrix"))
    throw error("updateStiffnessMatrix", "element matrices are built once on the rest shape; only false is handled");
  exact_ = spec().find("exactTangent") && attrs_.boolean("exactTangent");
  if (svd_ && exact_) throw error("exactTangent", "is for methods large and polar; svd uses SOFA's tangent");
  if (spec().find("plasticMaxThreshold"))
    plasticity_ = {attrs_.real("plasticYieldThreshold"), attrs_.real("plasticMaxThreshold"), attrs_.real("plasticCreep")};
  if (plasticity_.on() && exact_)
    throw error("exactTangent", "is the derivative of the elastic force; with plasticity (plasticMaxThreshold > 0) use SOFA's tangent");
  tets_ = elementTetrahedra(contextTopology(*this));
  const int n = state_->size();
  for (int e = 0; e < tets_.cols(); ++e)
    for (int k = 0; k < 4; ++k)
      if (tets_(k, e) < 0 || tets_(k, e) >= n)
        throw error("tetrahedron " + std::to_string(e) + " refers to node " + std::to_string(tets_(k, e)) +
                    ", but the MechanicalObject has " + std::to_string(n) + " nodes");

  const std::vector<double> E = linkedReals("youngModulus");
  const double nu = attrs_.real("poissonRatio");
  if (E.size() != 1 && static_cast<long>(E.size()) != tets_.cols())
    throw error("youngModulus", "expected one value or one per tetrahedron (" + std::to_string(tets_.cols()) + "), got " +
                                    std::to_string(E.size()));
  rest_.resize(tets_.cols());
  rot0_.assign(tets_.cols(), Eigen::Matrix3d::Identity());
  for (int e = 0; e < tets_.cols(); ++e) {
    const Mat34 X = gather(state_->x0, e);
    try {
      rest_[e] = fem::restElement(method_, X, fem::Lame::fromYoungPoisson(E.size() == 1 ? E[0] : E[e], nu));
    } catch (const std::domain_error&) {
      throw error("tetrahedron " + std::to_string(e) + " is degenerate (zero volume)");
    }
    rot0_[e] = fem::frame(method_, X);
  }
  if (method_ == fem::Method::Large && !svd_) lanes_ = fem::largeTetrahedraLanes(rest_);
  signs_ = fem::restSigns(rest_);
  colors_ = io::cachedDerived<ElementColoring>("element colouring", io::keyBytes(tets_) + std::to_string(n),
                                                              [&] { return colorElements(tets_, n); });
}

void TetrahedronFEMForceField::nodeRotations(const State& s, std::vector<Eigen::Matrix3d>& R) const {
  const Live& l = live(s);
  // An element's frame maps world to element axes: rest -> current is rot^T rot0.
  std::vector<Eigen::Matrix3d> Q(tets_.cols());
  for (int e = 0; e < tets_.cols(); ++e) Q[e] = l.rot[e].transpose() * rot0_[e];
  R = averageNodeRotations(state_->size(), tets_.data(), 4, Q.data(), static_cast<int>(Q.size()));
}

Mat34 TetrahedronFEMForceField::gather(const Eigen::Matrix3Xd& x, int e) const {
  Mat34 p;
  for (int k = 0; k < 4; ++k) p.col(k) = x.col(tets_(k, e));
  return p;
}

std::unique_ptr<ComponentState> TetrahedronFEMForceField::initialState() const {
  auto l = std::make_unique<Live>();
  l->rot = rot0_;
  if (plasticity_.on()) l->plastic.setZero(6, tets_.cols());
  return l;
}

void TetrahedronFEMForceField::Live::load(StateReader& in) {
  in.getSameSize(rot, "element frames");
  in.get(xLast);
  // Plastic strains: one column per element with plasticity on, none without.
  Eigen::Matrix<double, 6, Eigen::Dynamic> p;
  in.get(p);
  if (p.cols() != plastic.cols())
    in.mismatch(std::to_string(p.cols()) + " plastic strains where this component has " + std::to_string(plastic.cols()));
  plastic = std::move(p);
}

void TetrahedronFEMForceField::addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd&,
                                        Eigen::Matrix3Xd& f) const {
  Live& l = live(s);
  if (exact_) l.xLast = x;
  std::vector<Eigen::Matrix3d>& rot = l.rot;
  if (method_ == fem::Method::Large && !svd_ && !plasticity_.on()) {
    forEachColoredRun(*colors_, [&](int first, int count) {
      fem::addLargeTetrahedraForces(x.data(), tets_.data(), first, count, rest_, lanes_, rot.data(), f.data());
    });
    return;
  }
  // Element by element (fem::elementForce written out, so that a plastic element can update its
  // plastic strain from its local displacement).
  forEachColored(*colors_, [&](int e) {
    const Mat34 xe = gather(x, e);
    rot[e] = svd_ ? fem::frameSvd(rest_[e], xe) : fem::frame(method_, xe);
    const Mat34 U = fem::localPositions(svd_ ? fem::Method::Polar : method_, rot[e], xe) - rest_[e].X;
    const Mat34 fe = rot[e].transpose() * (plasticity_.on() ? fem::plasticForce(rest_[e], U, plasticity_, l.plastic.col(e))
                                                            : fem::elasticForce(rest_[e], U));
    for (int k = 0; k < 4; ++k) f.col(tets_(k, e)) += fe.col(k);
  });
}

Mat12 TetrahedronFEMForceField::stiffnessOf(const Live& l, int e) const {
  if (exact_ && method_ != fem::Method::Small) return fem::elementTangent(method_, rest_[e], gather(l.xLast, e));
  return fem::elementStiffness(method_, rest_[e], l.rot[e]);
}

void TetrahedronFEMForceField::addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df,
                                         double kFactor) const {
  const Live& l = live(s);
  if (exact_ && method_ != fem::Method::Small) {
    forEachColored(*colors_, [&](int e) {
      const Mat34 d = gather(dx, e);
      Eigen::Matrix<double, 12, 1> r = stiffnessOf(l, e) * Eigen::Map<const Eigen::Matrix<double, 12, 1>>(d.data());
      for (int k = 0; k < 4; ++k) df.col(tets_(k, e)) += kFactor * r.segment<3>(3 * k);
    });
    return;
  }
  // K dx per element without forming K: with h = R^T G and M = h dX^T, (K dx)_i = -V sigma(M) h_i.
  forEachColored(*colors_, [&](int e) {
    const fem::ElementRest& r = rest_[e];
    const Mat34 h = l.rot[e].transpose() * r.G;
    const Mat34 d = gather(dx, e);
    const Eigen::Matrix3d M = h * d.transpose();
    const Mat34 out = (-kFactor * r.volume) * (r.lame.stress(M) * h);
    for (int k = 0; k < 4; ++k) df.col(tets_(k, e)) += out.col(k);
  });
}

void TetrahedronFEMForceField::stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const {
  for (int e = 0; e < tets_.cols(); ++e)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) pairs.push_back({tets_(i, e), tets_(j, e)});
}

void TetrahedronFEMForceField::prepareAssembly(const BlockSparseMatrix& K) {
  auto& slots = slots_[K.upper()];
  slots.resize(tets_.cols());
  for (int e = 0; e < tets_.cols(); ++e)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) slots[e][4 * i + j] = K.slot(tets_(i, e), tets_(j, e));
  // Each slot's first writer in the assembly's order: colour by colour, run by run (elements of
  // one colour share no slot, so threads keep this order for each slot).
  auto& first = firstWriter_[K.upper()];
  first.assign(tets_.cols(), 0);
  std::vector<char> written(K.nonZeroBlocks(), 0);
  forEachColoredRun(*colors_, [&](int begin, int count) {
    for (int e = begin; e < begin + count; ++e)
      for (int b = 0; b < 16; ++b)
        if (slots[e][b] >= 0 && !written[slots[e][b]]) {
          written[slots[e][b]] = 1;
          first[e] |= static_cast<std::uint16_t>(1u << b);
        }
  });
  auto& unwritten = unwritten_[K.upper()];
  unwritten.clear();
  for (int s = 0; s < K.nonZeroBlocks(); ++s)
    if (!written[s]) unwritten.push_back(s);
}

void TetrahedronFEMForceField::addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const {
  const auto& slots = slots_[K.upper()];
  if (slots.size() != static_cast<size_t>(tets_.cols())) throw std::logic_error("addStiffness before prepareAssembly");
  const Live& l = live(s);
  if (exact_ && method_ != fem::Method::Small) {
    if (K.upper()) throw std::logic_error("the exact tangent is not symmetric: it needs the full storage");
    forEachColored(*colors_, [&](int e) {
      const Mat12 Ke = stiffnessOf(l, e);
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) K.block(slots[e][4 * i + j]) += kFactor * Ke.block<3, 3>(3 * i, 3 * j);
    });
    return;
  }
  assembleBlocks(l, K, kFactor, nullptr);
}

// Blocks -V times the law's coupling of the rotated gradients h = R^T G (Lame::coupling, written
// out on plain arrays, vectorised where the CPU allows: this loop is a fifth of a step), added, or
// set at the slots' first writers (firstWriter).
void TetrahedronFEMForceField::assembleBlocks(const Live& l, BlockSparseMatrix& K, double kFactor,
                                              const std::uint16_t* firstWriter) const {
  const auto& slots = slots_[K.upper()];
  double* values = K.values();
  forEachColoredRun(*colors_, [&](int first, int count) {
    fem::addTetrahedraBlocks(rest_, l.rot.data(), slots.data(), first, count, kFactor, values, firstWriter);
  });
}

bool TetrahedronFEMForceField::setStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const {
  const auto& slots = slots_[K.upper()];
  if ((exact_ && method_ != fem::Method::Small) || slots.size() != static_cast<size_t>(tets_.cols()) ||
      firstWriter_[K.upper()].size() != slots.size())
    return false;
  for (int b : unwritten_[K.upper()]) std::fill_n(K.values() + 9 * static_cast<long>(b), 9, 0.0);
  assembleBlocks(live(s), K, kFactor, firstWriter_[K.upper()].data());
  return true;
}

double TetrahedronFEMForceField::potentialEnergy(const Eigen::Matrix3Xd& x) const {
  double s = 0;
  for (int e = 0; e < tets_.cols(); ++e) s += fem::elementEnergy(method_, rest_[e], gather(x, e));
  return s;
}

std::vector<int> TetrahedronFEMForceField::invertedElements(const Eigen::Matrix3Xd& x) const {
  // An element is inverted when its orientation differs from the rest orientation.
  return fem::invertedTetrahedra(x.data(), tets_.data(), signs_);
}

namespace {

Eigen::VectorXd vonMisesOf(fem::Method method, const TetList& tets, const std::vector<fem::ElementRest>& rest,
                           const Eigen::Matrix3Xd& x) {
  Eigen::VectorXd out(tets.cols());
  for (int e = 0; e < tets.cols(); ++e) {
    Mat34 p;
    for (int k = 0; k < 4; ++k) p.col(k) = x.col(tets(k, e));
    const Eigen::Matrix3d R = fem::frame(method, p);
    out[e] = fem::vonMises(fem::stress(rest[e], fem::localPositions(method, R, p) - rest[e].X));
  }
  return out;
}

}  // namespace

Eigen::VectorXd TetrahedronFEMForceField::vonMises(const Eigen::Matrix3Xd& x) const {
  if (lanes_.empty()) return vonMisesOf(method_, tets_, rest_, x);
  Eigen::VectorXd out(tets_.cols());
  fem::largeTetrahedraVonMises(x.data(), tets_.data(), rest_, lanes_, out.data());
  return out;
}

std::function<Eigen::VectorXd(const Eigen::Matrix3Xd&)> TetrahedronFEMForceField::vonMisesFunction() const {
  // The corotational elements through the step's vector kernel (an exporter computes this every
  // frame), the others element by element.
  if (!lanes_.empty())
    return [tets = tets_, rest = rest_, lanes = lanes_](const Eigen::Matrix3Xd& x) {
      Eigen::VectorXd out(tets.cols());
      fem::largeTetrahedraVonMises(x.data(), tets.data(), rest, lanes, out.data());
      return out;
    };
  return [method = method_, tets = tets_, rest = rest_](const Eigen::Matrix3Xd& x) { return vonMisesOf(method, tets, rest, x); };
}

void registerTetrahedronFEM(Registry& r) {
  ComponentSpec s;
  s.name = "TetrahedronFEMForceField";
  s.aliases = {"TetrahedralCorotationalFEMForceField"};
  s.category = "forcefield";
  s.doc = "Linear elastic tetrahedra. method=small: linear; large: corotational with the element frame built "
          "from its edges (SOFA's default); polar: corotational with the polar decomposition of the edge "
          "matrix; svd: polar, except that an inverted or nearly flat element (volume ratio below 1e-6) takes "
          "the rotation of the SVD of its deformation gradient, which turns it back (SOFA's svd). The implicit solve "
          "uses R^T K0 R as SOFA does, or the exact tangent with exactTangent (large, polar). With plasticMaxThreshold > 0, "
          "SOFA's plasticity: each element keeps a plastic strain that creeps from the elastic strain above the yield "
          "threshold and is capped at the max threshold (strains measured as SOFA's, 6 V |strain|).";
  s.add(AttrSpec::reals("youngModulus").def("5000").above(0).unit(Dimension::pressure()).linked().help("Young's modulus: one value, or one per tetrahedron (or a link such as @young.outputValues)"));
  s.add(AttrSpec::real("poissonRatio").def("0.45").above(-1).below(0.5).help("Poisson's ratio, in (-1, 0.5)"));
  s.add(AttrSpec::choice("method", {"large", "small", "polar", "svd"}).def("large").help("small | large | polar | svd"));
  s.add(AttrSpec::boolean("exactTangent").def("false").help("use the exact derivative of the corotational force (Newton)"));
  s.add(AttrSpec::real("plasticMaxThreshold").def("0").atLeast(0).unit(Dimension{3, 0, 0}).help(
      "SOFA's plasticity: the largest plastic strain, as SOFA measures it (6 V |strain|, so a volume); 0 (default) turns "
      "plasticity off"));
  s.add(AttrSpec::real("plasticYieldThreshold").def("0.0001").atLeast(0).unit(Dimension{3, 0, 0}).help(
      "SOFA's plasticity: the elastic strain (6 V |strain|) above which it creeps into plastic strain"));
  s.add(AttrSpec::real("plasticCreep").def("0.9").atLeast(0).atMost(1).help(
      "SOFA's plasticity: the share of the elastic strain above the yield threshold that becomes plastic at each force "
      "evaluation (so it depends on the time step)"));
  s.add(AttrSpec::boolean("updateStiffnessMatrix").def("false").help(
      "SOFA's rebuild of the element matrices from the rotated shape each step; only false (the rest shape's) is handled"));
  s.add(AttrSpec::link("topology").help("tetrahedral topology (default: the last one in the node, or the grid)"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
  s.factory = [](BuildContext& c) { return std::make_unique<TetrahedronFEMForceField>(c); };
  r.add(std::move(s));

  // SOFA's element force fields (Sofa.Component.SolidMechanics.FEM.Elastic) on tetrahedra: the
  // same elements with the method fixed by the type.
  for (const char* name : {"LinearSmallStrainFEMForceField", "CorotationalFEMForceField"}) {
    const bool corotational = std::string(name) == "CorotationalFEMForceField";
    ComponentSpec e;
    e.name = name;
    e.category = "forcefield";
    e.doc = corotational ? "SOFA's corotational element force field: on tetrahedra, TetrahedronFEMForceField with the "
                           "element rotation from the polar decomposition (method=polar); on hexahedra, trilinear "
                           "elements turned by the polar decomposition of sum (x_i - c)(X_i - C)^T."
                         : "SOFA's linear small-strain element force field: TetrahedronFEMForceField with method=small on "
                           "tetrahedra, linear trilinear elements on hexahedra.";
    e.add(AttrSpec::choice("template", {"Vec3,Tetrahedron", "Vec3d,Tetrahedron", "Vec3,Hexahedron", "Vec3d,Hexahedron"})
              .def("Vec3,Tetrahedron")
              .help("the element type"));
    e.add(AttrSpec::reals("youngModulus").def("5000").above(0).unit(Dimension::pressure()).linked().help("Young's modulus: one value, or one per element"));
    e.add(AttrSpec::real("poissonRatio").def("0.45").above(-1).below(0.5).help("Poisson's ratio, in (-1, 0.5)"));
    if (corotational)
      e.add(AttrSpec::choice("rotationMethod", {"polar"}).def("polar").help("the element rotation: the polar decomposition (SOFA's stable variant agrees for elements that are not inverted)"));
    e.add(AttrSpec::link("topology").help("the topology with the elements (default: the nearest in the node or above)"));
    e.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node or above)"));
    e.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
      if (c.attrs().str("template").find("Hexahedron") != std::string::npos) return makeHexahedronElementFEM(c);
      return std::make_unique<TetrahedronFEMForceField>(c);
    };
    r.add(std::move(e));
  }
}

}  // namespace viscera
