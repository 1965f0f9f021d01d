// Springs between node pairs of one MechanicalObject: MeshSpringForceField (SOFA's: a spring on
// every node pair of the mesh's elements, with the rest length of the pair at rest) and
// SpringForceField (the springs listed). Per spring between a and b, with u the unit vector from a to b and
// d the length:  f_a = (ks (d - L0) + kd u.(v_b - v_a)) u,  f_b = -f_a.  The stiffness (SOFA's,
// damping left out of the matrix as SOFA does): df_a/dx_b = J = (ks - t) u u^T + t I with
// t = (ks (d - L0) + kd u.(v_b - v_a)) / d, and df_a/dx_a = -J.
#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "core/Registry.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidDynamics.h"
#include "engine/rigid/RigidObject.h"
#include "core/State.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

namespace {

struct Spring {
  int a = 0, b = 0;
  double ks = 0, kd = 0, rest = 0;
};

// One spring's force on its end a (end b takes the opposite) and J = df_a/dx_b; a spring shorter
// than 1e-9 pushes nothing (SOFA skips it) and has J = 0.
Eigen::Vector3d springForce(const Spring& s, const Eigen::Vector3d& xa, const Eigen::Vector3d& xb, const Eigen::Vector3d& va,
                            const Eigen::Vector3d& vb, Eigen::Matrix3d& J) {
  Eigen::Vector3d u = xb - xa;
  const double d = u.norm();
  if (!(d > 1e-9)) {
    J.setZero();
    return Eigen::Vector3d::Zero();
  }
  u /= d;
  const double intensity = s.ks * (d - s.rest) + s.kd * u.dot(vb - va);
  const double t = intensity / d;
  J = (s.ks - t) * u * u.transpose() + t * Eigen::Matrix3d::Identity();
  return intensity * u;
}

// The springs of SOFA's SpringForceField from its attributes: `spring` ("i j ks kd L" each), or
// indices1/indices2 with lengths and one stiffness and damping. `node(attr, side, i)` checks and
// converts an index of end `side`.
template <class NodeOf>
std::vector<Spring> listedSprings(Component& c, const NodeOf& node) {
  std::vector<Spring> out;
  const Attributes& attrs = c.attrs();
  if (attrs.isSet("spring")) {
    const auto& v = attrs.reals("spring");
    for (size_t k = 0; k + 5 <= v.size(); k += 5) {
      if (v[k + 2] < 0 || v[k + 3] < 0 || v[k + 4] < 0)
        throw c.error("spring", "spring " + std::to_string(k / 5) + " has a negative stiffness, damping or length");
      out.push_back({node("spring", 0, v[k]), node("spring", 1, v[k + 1]), v[k + 2], v[k + 3], v[k + 4]});
    }
    return out;
  }
  const auto a = c.linkedInts("indices1"), b = c.linkedInts("indices2");
  auto lengths = attrs.reals("lengths");
  if (a.size() != b.size()) throw c.error("indices2", "has " + std::to_string(b.size()) + " nodes, indices1 " + std::to_string(a.size()));
  if (lengths.size() == 1) lengths.assign(a.size(), lengths[0]);
  if (!lengths.empty() && lengths.size() != a.size())
    throw c.error("lengths", "needs one length, or one per spring (" + std::to_string(a.size()) + ")");
  for (size_t k = 0; k < a.size(); ++k)
    out.push_back({node("indices1", 0, a[k]), node("indices2", 1, b[k]), attrs.real("stiffness"), attrs.real("damping"),
                   lengths.empty() ? 0.0 : lengths[k]});
  return out;
}

// df_a/dx_b of each spring at the last force evaluation.
struct SpringsLive : ComponentStateOf<SpringsLive> {
  std::vector<Eigen::Matrix3d> J;
  void save(StateWriter& out) const override { out.put(J); }
  void load(StateReader& in) override { in.getSameSize(J, "springs"); }
};

class MeshSpringForceField : public Component, public ForceField, public Stateful {
 public:
  using Component::Component;
  bool assemblesUpper() const override { return true; }  // symmetric, written with addSymmetric
  MechanicalObject& mstate() const override { return *state_; }
  using Live = SpringsLive;
  std::unique_ptr<ComponentState> initialState() const override {
    auto l = std::make_unique<Live>();
    l->J.assign(springs_.size(), Eigen::Matrix3d::Zero());
    return l;
  }
  void init() override {
    state_ = &contextState(*this);
    if (typeName() == "SpringForceField") {
      const int n = state_->size();
      springs_ = listedSprings(*this, [&](const char* attr, int, double i) {
        if (!(i >= 0 && i < n && i == std::floor(i)))
          throw error(attr, "node " + formatNumber(i) + " is not a node of '" + state_->name() + "' (" + std::to_string(n) + " nodes)");
        return static_cast<int>(i);
      });
      return;
    }
    const Eigen::Matrix3Xd& X = state_->x0;
    // The element kinds in SOFA's order: a pair keeps the stiffness of the first kind that lists it.
    auto value = [&](const char* kind, const char* fallback) {
      // A kind's own value, else the common one (given, or its default), else none.
      return attrs_.isSet(kind) ? attrs_.real(kind) : attrs_.get(fallback).nums.empty() ? 0.0 : attrs_.real(fallback);
    };
    std::set<std::pair<int, int>> seen;
    // As SOFA's mesh and grid springs, the given stiffness and damping are per unit rest length:
    // a spring of rest length L gets k / L and d / L (a uniform bar whatever its subdivision).
    auto add = [&](int a, int b, double ks, double kd) {
      if (a == b) return;
      if (!seen.insert({std::min(a, b), std::max(a, b)}).second) return;
      const double rest = (X.col(b) - X.col(a)).norm();
      const double per = rest > std::numeric_limits<double>::epsilon() ? 1.0 / rest : 1.0;
      springs_.push_back({a, b, ks * per, kd * per, rest});
    };
    Topology* tets = nullptr;
    Topology* hexa = nullptr;
    FieldValue quads;  // a surface of quads (a flat grid), when there are no volume cells
    FieldValue edges;  // node pairs of an edge set, when there are neither
    const bool gridOnly = typeName() == "RegularGridSpringForceField";
    for (const Node* n = &node(); n && !tets && !hexa; n = n->parent())
      for (auto it = n->components().rbegin(); it != n->components().rend(); ++it)
        if (auto* t = dynamic_cast<Topology*>(it->get())) {
          scene().initComponent(**it);
          if (!tets && !gridOnly && t->tetrahedra().cols() > 0) tets = t;
          if (!hexa && !t->hexahedra().empty()) hexa = t;
          if (quads.values.empty()) (*it)->field("quads", quads);
          if (edges.values.empty()) (*it)->field("edges", edges);
        }
    if (gridOnly && !hexa && quads.values.empty()) throw error("no grid (hexahedra or a flat grid's quads) in its node or above");
    if (!tets && !hexa && quads.values.empty() && (gridOnly || edges.values.empty()))
      throw error("no topology with tetrahedra, hexahedra, quads or edges in its node or above");
    const int n = state_->size();
    auto check = [&](int i) {
      if (i < 0 || i >= n) throw error("an element refers to node " + std::to_string(i) + ", but the MechanicalObject has " + std::to_string(n) + " nodes");
      return i;
    };
    if (tets) {
      // Every edge of a tetrahedron is an edge, a triangle side and a tetrahedron edge: it takes the
      // first of those stiffnesses that is given.
      const double ks = value("linesStiffness", "stiffness") != 0 ? value("linesStiffness", "stiffness")
                        : value("trianglesStiffness", "stiffness") != 0 ? value("trianglesStiffness", "stiffness")
                                                                         : value("tetrasStiffness", "stiffness");
      const double kd = value("linesStiffness", "stiffness") != 0 ? value("linesDamping", "damping")
                        : value("trianglesStiffness", "stiffness") != 0 ? value("trianglesDamping", "damping")
                                                                         : value("tetrasDamping", "damping");
      const TetList& T = tets->tetrahedra();
      for (int e = 0; e < T.cols(); ++e)
        for (int i = 0; i < 4; ++i)
          for (int j = i + 1; j < 4; ++j) add(check(T(i, e)), check(T(j, e)), ks, kd);
    } else if (!hexa && quads.values.empty()) {
      // An edge set: its edges are lines.
      const double lk = value("linesStiffness", "stiffness"), ld = value("linesDamping", "damping");
      for (size_t e = 0; e + 2 <= edges.values.size(); e += 2)
        add(check(static_cast<int>(edges.values[e])), check(static_cast<int>(edges.values[e + 1])), lk, ld);
    } else if (!hexa) {
      // Quads: their four sides (lines), then the sides and diagonals (quads).
      const double lk = value("linesStiffness", "stiffness"), ld = value("linesDamping", "damping");
      const double qk = value("quadsStiffness", "stiffness"), qd = value("quadsDamping", "damping");
      for (size_t q = 0; q + 4 <= quads.values.size(); q += 4) {
        int v[4];
        for (int k = 0; k < 4; ++k) v[k] = check(static_cast<int>(quads.values[q + k]));
        if (lk != 0 || ld != 0)
          for (int k = 0; k < 4; ++k) add(v[k], v[(k + 1) % 4], lk, ld);
        if (qk != 0 || qd != 0)
          for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j) add(v[i], v[j], qk, qd);
      }
    } else {
      // Hexahedra: the 12 edges (lines), then the face diagonals (quads), then the body
      // diagonals (cubes: every pair of the 8 nodes).
      static const int edges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6}, {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
      static const int faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
      const double lk = value("linesStiffness", "stiffness"), ld = value("linesDamping", "damping");
      const double qk = value("quadsStiffness", "stiffness"), qd = value("quadsDamping", "damping");
      const double ck = value("cubesStiffness", "stiffness"), cd = value("cubesDamping", "damping");
      for (const auto& h : hexa->hexahedra()) {
        for (int k : h) check(k);
        if (lk != 0 || ld != 0)
          for (const auto& e : edges) add(h[e[0]], h[e[1]], lk, ld);
        if (qk != 0 || qd != 0)
          for (const auto& f : faces)
            for (int i = 0; i < 4; ++i)
              for (int j = i + 1; j < 4; ++j) add(h[f[i]], h[f[j]], qk, qd);
        if (ck != 0 || cd != 0)
          for (int i = 0; i < 8; ++i)
            for (int j = i + 1; j < 8; ++j) add(h[i], h[j], ck, cd);
      }
    }
    for (const auto& s : springs_)
      if (!(s.rest > 0)) throw error("two nodes of an element coincide at rest (nodes " + std::to_string(s.a) + " and " + std::to_string(s.b) + ")");
  }
  void addForce(State& st, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, Eigen::Matrix3Xd& f) const override {
    std::vector<Eigen::Matrix3d>& J = stateIn<Live>(st).J;
    for (size_t i = 0; i < springs_.size(); ++i) {
      const Spring& s = springs_[i];
      const Eigen::Vector3d fa = springForce(s, x.col(s.a), x.col(s.b), v.col(s.a), v.col(s.b), J[i]);
      f.col(s.a) += fa;
      f.col(s.b) -= fa;
    }
  }
  void addDForce(const State& st, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const override {
    const std::vector<Eigen::Matrix3d>& J = stateIn<Live>(st).J;
    for (size_t i = 0; i < springs_.size(); ++i) {
      const Eigen::Vector3d d = kFactor * (J[i] * (dx.col(springs_[i].b) - dx.col(springs_[i].a)));
      df.col(springs_[i].a) += d;
      df.col(springs_[i].b) -= d;
    }
  }
  void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const override {
    for (const auto& s : springs_) pairs.push_back({s.a, s.b});
  }
  void addStiffness(const State& st, BlockSparseMatrix& K, double kFactor) const override {
    const std::vector<Eigen::Matrix3d>& J = stateIn<Live>(st).J;
    for (size_t i = 0; i < springs_.size(); ++i) {
      const Spring& s = springs_[i];
      const Eigen::Matrix3d B = kFactor * J[i];
      K.block(K.diagonalSlot(s.a)) -= B;
      K.block(K.diagonalSlot(s.b)) -= B;
      K.addSymmetric(s.a, s.b, B);
      K.addSymmetric(s.b, s.a, B);
    }
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    double e = 0;
    for (const auto& s : springs_) e += 0.5 * s.ks * std::pow((x.col(s.b) - x.col(s.a)).norm() - s.rest, 2);
    return e;
  }

 private:
  MechanicalObject* state_ = nullptr;
  std::vector<Spring> springs_;
};

// SOFA's SpringForceField between two MechanicalObjects (object1, object2; a missing one is the
// node's): spring ends a on object1, b on object2. The EulerImplicitSolver integrating both
// couples them (InteractionForceField); an end that nothing integrates holds still.
class InteractionSprings : public Component, public InteractionForceField, public Stateful {
 public:
  using Component::Component;
  std::unique_ptr<ComponentState> initialState() const override {
    auto l = std::make_unique<SpringsLive>();
    l->J.assign(springs_.size(), Eigen::Matrix3d::Zero());
    return l;
  }
  void init() override {
    for (int k = 0; k < 2; ++k) {
      const char* attr = k ? "object2" : "object1";
      if (attrs_.isSet(attr)) {
        Component* c = linkedComponent(attr);
        obj_[k] = dynamic_cast<MechanicalObject*>(c);
        if (dynamic_cast<RigidObject*>(c))
          throw error(attr, "links to the rigid body '" + c->name() + "'; springs on a Rigid3d object are not handled");
        if (!obj_[k]) throw error(attr, "does not link to a MechanicalObject");
        scene().initComponent(*obj_[k]);
      } else {
        obj_[k] = &contextState(*this);
      }
      if (obj_[k]->mappedBy())
        throw error(attr, "'" + obj_[k]->name() + "' is moved by a mapping; springs on a mapped object are not handled (link "
                          "the object the mapping follows)");
    }
    springs_ = listedSprings(*this, [&](const char* attr, int side, double i) {
      const int n = obj_[side]->size();
      if (!(i >= 0 && i < n && i == std::floor(i)))
        throw error(attr, "node " + formatNumber(i) + " is not a node of '" + obj_[side]->name() + "' (object" +
                              std::to_string(side + 1) + ", " + std::to_string(n) + " nodes)");
      return static_cast<int>(i);
    });
    // Both ends on one object: that object's springs, whatever solver moves it (MechanicalSystem
    // takes them as its own force field).
    if (obj_[0] == obj_[1]) return;
    const Node* n1 = integratingNode(*obj_[0]);
    const Node* n2 = integratingNode(*obj_[1]);
    if (n1 && n2 && n1 != n2)
      throw error("its ends are integrated by two solvers (in " + n1->path() + " and " + n2->path() +
                  "); put both objects under one EulerImplicitSolver (in a node above both, without a MechanicalObject)");
    solver_ = n1 ? n1 : n2;
    if (!solver_) {
      scene().addNote(loc().str() + ": note: SpringForceField '" + name() + "': no solver integrates either end; the springs move nothing");
      return;
    }
    auto& ode = dynamic_cast<Component&>(*solver_->find<OdeSolver>());
    if (ode.typeName() != "EulerImplicitSolver")
      throw error("its ends are integrated by " + ode.typeName() + " '" + ode.name() + "'; springs between two objects are "
                  "solved by EulerImplicitSolver");
  }
  MechanicalObject& object(int side) const override { return *obj_[side]; }
  const Node* solverNode() const override { return solver_; }
  void addForce(State& st, const Sides& x, const Sides& v, const SideForces& f) const override {
    std::vector<Eigen::Matrix3d>& J = stateIn<SpringsLive>(st).J;
    for (size_t i = 0; i < springs_.size(); ++i) {
      const Spring& s = springs_[i];
      const Eigen::Vector3d fa = springForce(s, x[0]->col(s.a), x[1]->col(s.b), v[0]->col(s.a), v[1]->col(s.b), J[i]);
      if (f[0]) f[0]->col(s.a) += fa;
      if (f[1]) f[1]->col(s.b) -= fa;
    }
  }
  void addDForce(const State& st, const Sides& dx, const SideForces& df, double factor) const override {
    const std::vector<Eigen::Matrix3d>& J = stateIn<SpringsLive>(st).J;
    for (size_t i = 0; i < springs_.size(); ++i) {
      const Spring& s = springs_[i];
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      if (dx[1]) d += dx[1]->col(s.b);
      if (dx[0]) d -= dx[0]->col(s.a);
      d = factor * (J[i] * d);
      if (df[0]) df[0]->col(s.a) += d;
      if (df[1]) df[1]->col(s.b) -= d;
    }
  }
  void forEachStiffnessBlock(const State& st, const std::function<void(int, int, int, int, const Eigen::Matrix3d&)>& visit) const override {
    const std::vector<Eigen::Matrix3d>& J = stateIn<SpringsLive>(st).J;
    for (size_t i = 0; i < springs_.size(); ++i) {
      const Spring& s = springs_[i];
      visit(0, s.a, 0, s.a, -J[i]);
      visit(0, s.a, 1, s.b, J[i]);
      visit(1, s.b, 0, s.a, J[i]);
      visit(1, s.b, 1, s.b, -J[i]);
    }
  }
  void stiffnessPattern(std::vector<std::array<int, 4>>& blocks) const override {
    for (const Spring& s : springs_) {
      blocks.push_back({0, s.a, 0, s.a});
      blocks.push_back({0, s.a, 1, s.b});
      blocks.push_back({1, s.b, 0, s.a});
      blocks.push_back({1, s.b, 1, s.b});
    }
  }

 private:
  std::array<MechanicalObject*, 2> obj_{};
  const Node* solver_ = nullptr;
  std::vector<Spring> springs_;
};

}  // namespace

void registerSprings(Registry& r) {
  for (const char* name : {"MeshSpringForceField", "RegularGridSpringForceField"}) {
    const bool grid = std::string(name) == "RegularGridSpringForceField";
    ComponentSpec s;
    s.name = name;
    s.category = "forcefield";
    s.doc = grid ? "Springs along a grid, as SOFA's: on its hexahedra the edges (lines), face diagonals (quads) and body "
                   "diagonals (cubes), on a flat grid's quads their sides (lines) and diagonals (quads), each with its rest length L "
                   "and, as SOFA's, the kind's stiffness and damping divided by L. Every kind defaults to stiffness 100 and damping 5 "
                   "(SOFA's); `stiffness` and `damping` set all kinds at once. Damping acts along the spring and stays "
                   "out of the implicit matrix, as in SOFA."
                 : "Springs on the node pairs of the mesh's elements, each with its rest length L and, as SOFA's, the kind's "
                   "stiffness and damping divided by L: on tetrahedra "
                   "their edges; on hexahedra the edges (lines), face diagonals (quads) and body diagonals (cubes); on quads (a flat grid) their sides (lines) and diagonals (quads); on an edge set its edges (lines). A kind "
                   "takes its own stiffness and damping when given, else `stiffness` and `damping`; a pair keeps the first "
                   "kind that lists it. Damping acts along the spring and stays out of the implicit matrix, as in SOFA.";
    // Per unit rest length (each spring takes k / L, d / L): a force, and a force times a time.
    AttrSpec k = AttrSpec::real("stiffness").atLeast(0).unit(Dimension::force()).help("stiffness per unit rest length of every kind not given its own");
    AttrSpec d = AttrSpec::real("damping").atLeast(0).unit({1, 1, -1}).help("damping per unit rest length of every kind not given its own");
    if (grid) {
      k.def("100");
      d.def("5");
    }
    s.add(k);
    s.add(d);
    for (const char* kind : grid ? std::vector<const char*>{"lines", "quads", "cubes"}
                                 : std::vector<const char*>{"lines", "triangles", "quads", "tetras", "cubes"}) {
      s.add(AttrSpec::real(std::string(kind) + "Stiffness").atLeast(0).unit(Dimension::force()).help(std::string("stiffness per unit rest length of the ") + kind + "' springs"));
      s.add(AttrSpec::real(std::string(kind) + "Damping").atLeast(0).unit({1, 1, -1}).help(std::string("damping per unit rest length of the ") + kind + "' springs"));
    }
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<MeshSpringForceField>(c); };
    r.add(std::move(s));
  }
  ComponentSpec s;
  s.name = "SpringForceField";
  s.aliases = {"StiffSpringForceField"};  // SOFA's name for it before they merged
  s.category = "forcefield";
  s.doc = "Springs between listed node pairs (SOFA's SpringForceField), of one MechanicalObject or, with object1 and "
          "object2, between two: `spring` gives \"i j "
          "ks kd L\" for each, or indices1/indices2 with lengths and one stiffness and damping. Per spring f = ks (d - L) "
          "+ kd u.(v_j - v_i) along u, the unit vector from i to j; damping stays out of the implicit matrix, as in SOFA. "
          "A spring shorter than 1e-9 of the scene's length pushes nothing. Between two objects, the EulerImplicitSolver "
          "integrating both couples them in its one system (CG, MINRES or a direct solver over all their nodes); an end on "
          "an object that no solver integrates (no mass) holds still, as an anchor.";
  s.add(AttrSpec::reals("spring").multipleOf(5).help("i j ks kd L per spring (stiffness in force per length, damping in force per speed)"));
  s.add(AttrSpec::ints("indices1").alias("springsIndices1").atLeast(0).linked().help("first nodes (without `spring`)"));
  s.add(AttrSpec::ints("indices2").alias("springsIndices2").atLeast(0).linked().help("second nodes"));
  s.add(AttrSpec::reals("lengths").alias("length").atLeast(0).unit(Dimension::length()).help("rest lengths: one for all or one per spring (default 0)"));
  s.add(AttrSpec::real("stiffness").def("100").atLeast(0).unit(Dimension::stiffness()).help("stiffness of the indexed springs"));
  s.add(AttrSpec::real("damping").def("5").atLeast(0).unit({0, 1, -1}).help("damping of the indexed springs"));
  s.add(AttrSpec::link("object1").help("the MechanicalObject of the first nodes (default: the node's); with object1 or "
                                       "object2 set, springs between two objects"));
  s.add(AttrSpec::link("object2").help("the MechanicalObject of the second nodes (default: the node's)"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node); without object1 and object2"));
  s.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
    if (c.attrs().isSet("object1") || c.attrs().isSet("object2")) return std::make_unique<InteractionSprings>(c);
    return std::make_unique<MeshSpringForceField>(c);
  };
  r.add(std::move(s));
}

}  // namespace viscera
