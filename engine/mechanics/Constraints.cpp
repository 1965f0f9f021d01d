// FixedConstraint (projective), BoxROI (index selection) and ConstantForceField.
#include <algorithm>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/BlockSparseMatrix.h"
#include "core/State.h"
#include <cmath>

namespace viscera {

namespace {

// The points of X inside any of the axis-aligned boxes (xmin ymin zmin xmax ymax zmax, repeated).
std::vector<int> pointsInBoxes(const Eigen::Matrix3Xd& X, const std::vector<double>& b) {
  std::vector<int> inside;
  for (int i = 0; i < X.cols(); ++i) {
    for (size_t k = 0; k + 6 <= b.size(); k += 6) {
      bool in = true;
      for (int a = 0; a < 3; ++a) {
        double lo = std::min(b[k + a], b[k + a + 3]), hi = std::max(b[k + a], b[k + a + 3]);
        if (X(a, i) < lo || X(a, i) > hi) in = false;
      }
      if (in) {
        inside.push_back(i);
        break;
      }
    }
  }
  return inside;
}

class FixedConstraint : public Component, public ProjectiveConstraint {
 public:
  using Component::Component;
  MechanicalObject& mstate() const override { return *state_; }
  const std::vector<int>& fixedNodes() const override { return nodes_; }
  void init() override {
    state_ = &contextState(*this);
    if (attrs_.boolean("fixAll")) {
      nodes_.resize(state_->size());
      for (int i = 0; i < state_->size(); ++i) nodes_[i] = i;
      return;
    }
    // SOFA's BoxConstraint: the nodes whose rest positions lie in the boxes.
    nodes_ = spec().find("box") ? pointsInBoxes(state_->x0, attrs_.reals("box")) : linkedInts("indices");
    for (int i : nodes_)
      if (i < 0 || i >= state_->size())
        throw error("indices", "node " + std::to_string(i) + " is out of range (the MechanicalObject has " +
                                   std::to_string(state_->size()) + " nodes)");
    std::sort(nodes_.begin(), nodes_.end());
    nodes_.erase(std::unique(nodes_.begin(), nodes_.end()), nodes_.end());
    // The solve never changes a fixed node's velocity; SOFA's switch would also zero a velocity
    // it starts with, which is refused here rather than silently kept.
    if (spec().find("activate_projectVelocity") && attrs_.boolean("activate_projectVelocity"))
      for (int i : nodes_)
        if (state_->vInit.col(i).squaredNorm() > 0)
          throw error("activate_projectVelocity", "fixed node " + std::to_string(i) +
                                                      " starts with a velocity; give it none");
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name != "indices") return false;
    out.values.assign(nodes_.begin(), nodes_.end());
    return true;
  }

 private:
  MechanicalObject* state_ = nullptr;
  std::vector<int> nodes_;
};

// Projective constraints that hold nodes along directions only: SOFA's
// PartialFixedProjectiveConstraint (chosen axes of chosen nodes) and FixedPlaneProjectiveConstraint
// (the nodes of a slab keep their position along its normal, and move freely in the plane).
class DirectionalConstraint : public Component, public ProjectiveConstraint {
 public:
  using Component::Component;
  MechanicalObject& mstate() const override { return *state_; }
  const std::vector<int>& fixedNodes() const override { return none_; }
  const std::vector<std::pair<int, Eigen::Vector3d>>& heldDirections() const override { return held_; }
  void init() override {
    state_ = &contextState(*this);
    const int n = state_->size();
    std::vector<int> nodes;
    if (typeName() == "FixedPlaneProjectiveConstraint") {
      const auto& d = attrs_.reals("direction");
      const Eigen::Vector3d dir(d[0], d[1], d[2]);
      if (!(dir.norm() > 0)) throw error("direction", "must not be zero");
      const Eigen::Vector3d u = dir.normalized();
      if (attrs_.isSet("indices")) {
        nodes = linkedInts("indices");
      } else {
        const double lo = attrs_.real("dmin"), hi = attrs_.real("dmax");
        if (lo > hi) throw error("dmax", "is below dmin");
        for (int i = 0; i < n; ++i) {
          const double s = u.dot(state_->x0.col(i));
          if (s >= lo && s <= hi) nodes.push_back(i);
        }
      }
      for (int i : nodes) held_.push_back({i, u});
    } else {
      const auto& axes = attrs_.ints("fixedDirections");
      if (axes.size() != 3)
        throw error("fixedDirections", "takes three flags (x y z) on a Vec3d object");
      if (attrs_.boolean("fixAll")) {
        for (int i = 0; i < n; ++i) nodes.push_back(i);
      } else {
        nodes = linkedInts("indices");
      }
      for (int i : nodes)
        for (int a = 0; a < 3; ++a)
          if (axes[a] != 0) held_.push_back({i, Eigen::Vector3d::Unit(a)});
    }
    for (int i : nodes)
      if (i < 0 || i >= n)
        throw error("indices", "node " + std::to_string(i) + " is out of range (the MechanicalObject has " + std::to_string(n) + " nodes)");
  }

 private:
  MechanicalObject* state_ = nullptr;
  std::vector<int> none_;
  std::vector<std::pair<int, Eigen::Vector3d>> held_;
};

// SOFA's projections onto a point, a line or a plane (PointProjectiveConstraint,
// LineProjectiveConstraint, PlaneProjectiveConstraint): the nodes keep only the freedom the
// shape leaves them in the solve (none, along the line, in the plane), and after each solve their
// positions and velocities are projected onto it, as SOFA projects them.
class ShapeProjection : public Component, public ProjectiveConstraint, public Correction {
 public:
  using Component::Component;
  MechanicalObject& mstate() const override { return *state_; }
  const std::vector<int>& fixedNodes() const override { return kind_ == Kind::Point ? nodes_ : none_; }
  const std::vector<std::pair<int, Eigen::Vector3d>>& heldDirections() const override { return held_; }
  void init() override {
    state_ = &contextState(*this);
    const int n = state_->size();
    kind_ = typeName() == "PointProjectiveConstraint" ? Kind::Point
            : typeName() == "LineProjectiveConstraint" ? Kind::Line
                                                       : Kind::Plane;
    if (kind_ == Kind::Point && attrs_.boolean("fixAll")) {
      for (int i = 0; i < n; ++i) nodes_.push_back(i);
    } else {
      nodes_ = linkedInts("indices");
    }
    for (int i : nodes_)
      if (i < 0 || i >= n)
        throw error("indices", "node " + std::to_string(i) + " is out of range (the MechanicalObject has " + std::to_string(n) + " nodes)");
    auto vec = [&](const char* name) {
      const auto& v = attrs_.reals(name);
      return Eigen::Vector3d(v[0], v[1], v[2]);
    };
    if (kind_ == Kind::Point) {
      origin_ = vec("point");
      return;
    }
    origin_ = vec("origin");
    const char* dirName = kind_ == Kind::Line ? "direction" : "normal";
    const Eigen::Vector3d d = vec(dirName);
    if (!(d.norm() > 0)) throw error(dirName, "must not be zero");
    axis_ = d.normalized();
    // The held directions: the plane's normal, or the two directions across the line.
    std::vector<Eigen::Vector3d> across;
    if (kind_ == Kind::Plane) {
      across.push_back(axis_);
    } else {
      const Eigen::Vector3d a = axis_.unitOrthogonal();
      across = {a, axis_.cross(a)};
    }
    for (int i : nodes_)
      for (const auto& u : across) held_.push_back({i, u});
  }
  void correct(State& s, double, int) const override {
    MechanicalObject::Live& l = state_->live(s);
    for (int i : nodes_) {
      switch (kind_) {
        case Kind::Point:
          l.x.col(i) = origin_;
          l.v.col(i).setZero();
          break;
        case Kind::Line:
          l.x.col(i) = origin_ + axis_ * axis_.dot(l.x.col(i) - origin_);
          l.v.col(i) = axis_ * axis_.dot(l.v.col(i));
          break;
        case Kind::Plane:
          l.x.col(i) -= axis_ * axis_.dot(l.x.col(i) - origin_);
          l.v.col(i) -= axis_ * axis_.dot(l.v.col(i));
          break;
      }
    }
  }

 private:
  enum class Kind { Point, Line, Plane };
  Kind kind_ = Kind::Plane;
  MechanicalObject* state_ = nullptr;
  std::vector<int> nodes_, none_;
  std::vector<std::pair<int, Eigen::Vector3d>> held_;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero(), axis_ = Eigen::Vector3d::UnitX();
};

// FixedConstraint or PartialFixedProjectiveConstraint on a Rigid3d body: holds the chosen velocity
// components (world x y z, then rotation about x y z) of an integrated body at zero.
class RigidHold : public Component {
 public:
  using Component::Component;
  void init() override {
    RigidObject& body = contextRigid(*this, "mstate");
    for (int i : linkedInts("indices"))
      if (i != 0) throw error("indices", "a Rigid3d object has one frame (index 0), got " + std::to_string(i));
    std::vector<int> flags(6, 1);
    if (spec().find("fixedDirections") && attrs_.isSet("fixedDirections")) {
      flags = attrs_.ints("fixedDirections");
      if (flags.size() != 6)
        throw error("fixedDirections", "takes six flags on a Rigid3d object (x y z translation, then rotation about x y z), got " +
                                           std::to_string(flags.size()));
    }
    if (spec().find("indices") && attrs_.isSet("indices") && linkedInts("indices").empty()) flags.assign(6, 0);
    for (int k = 0; k < 6; ++k) body.held[k] = body.held[k] || flags[k] != 0;
  }
};

bool inRigidNode(const BuildContext& c) { return c.node().find<RigidObject>() && !c.node().find<MechanicalObject>(); }

class BoxROI : public Component {
 public:
  using Component::Component;
  void init() override {
    Eigen::Matrix3Xd X;
    if (attrs_.isSet("position")) {
      auto p = linkedReals("position");
      X = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, p.size() / 3);
    } else {
      X = contextState(*this).x0;  // SOFA tests the rest positions
    }
    indices_ = pointsInBoxes(X, attrs_.reals("box"));
    for (int i : indices_)
      for (int k = 0; k < 3; ++k) pointsIn_.push_back(X(k, i));
    if (indices_.empty() && attrs_.boolean("strict"))
      throw error("box", "selects no point (set strict=\"false\" to allow an empty selection)");
    // Triangles given: those with all three vertices inside (SOFA's strict rule), by index and
    // by their vertices.
    if (attrs_.isSet("triangles")) {
      // SOFA's strict="false" takes a triangle by its centre; only its default rule is here.
      if (attrs_.isSet("strict") && !attrs_.boolean("strict"))
        throw error("strict", "with triangles, SOFA's strict=\"false\" (a triangle by its centre) is not supported; "
                              "triangles are taken when all three vertices are inside");
      const auto t = linkedInts("triangles");
      std::vector<char> in(static_cast<size_t>(X.cols()), 0);
      for (int i : indices_) in[static_cast<size_t>(i)] = 1;
      for (size_t k = 0; k + 3 <= t.size(); k += 3) {
        bool all = true;
        for (size_t c = k; c < k + 3; ++c) {
          if (t[c] < 0 || t[c] >= X.cols())
            throw error("triangles", "triangle " + std::to_string(k / 3) + " refers to point " + std::to_string(t[c]) +
                                         ", but there are " + std::to_string(X.cols()) + " points");
          all = all && in[static_cast<size_t>(t[c])];
        }
        if (!all) continue;
        triangleIndices_.push_back(static_cast<double>(k / 3));
        trianglesIn_.insert(trianglesIn_.end(), t.begin() + static_cast<long>(k), t.begin() + static_cast<long>(k + 3));
      }
    }
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "indices") out.values.assign(indices_.begin(), indices_.end());
    else if (name == "pointsInROI") out.values = pointsIn_;
    else if (name == "triangleIndices" && attrs_.isSet("triangles")) out.values = triangleIndices_;
    else if (name == "trianglesInROI" && attrs_.isSet("triangles")) out.values.assign(trianglesIn_.begin(), trianglesIn_.end());
    else return false;
    return true;
  }

 private:
  std::vector<int> indices_;
  std::vector<double> pointsIn_;  // the selected points' positions, x y z each
  std::vector<double> triangleIndices_;
  std::vector<int> trianglesIn_;
};

// SOFA's TrianglePressureForceField: a load per unit area, a fixed vector, on chosen triangles of a
// surface; each triangle carries pressure x its rest area, a third on each vertex.
class TrianglePressureForceField : public Component, public ForceField {
 public:
  using Component::Component;
  bool assemblesUpper() const override { return true; }  // adds no stiffness
  MechanicalObject& mstate() const override { return *state_; }
  void init() override {
    state_ = &contextState(*this);
    if (!attrs_.boolean("useConstantForce"))
      throw error("useConstantForce", "only the load on the rest areas (true) is supported");
    FieldValue tris;
    for (const Node* n = &node(); n && tris.values.empty(); n = n->parent())
      for (auto it = n->components().rbegin(); it != n->components().rend(); ++it)
        if (dynamic_cast<Topology*>(it->get())) {
          scene().initComponent(**it);
          if ((*it)->field("triangles", tris) && !tris.values.empty()) break;
        }
    if (tris.values.empty()) throw error("no topology with triangles in its node or above");
    const auto& p = attrs_.reals("pressure");
    const Eigen::Vector3d pressure(p[0], p[1], p[2]);
    const int count = static_cast<int>(tris.values.size() / 3);
    const Eigen::Matrix3Xd& X = state_->x0;
    forces_ = Eigen::Matrix3Xd::Zero(3, X.cols());
    for (int t : linkedInts("triangleList")) {
      if (t < 0 || t >= count)
        throw error("triangleList", "triangle " + std::to_string(t) + " is out of range (the surface has " +
                                        std::to_string(count) + ")");
      int v[3];
      for (int k = 0; k < 3; ++k) {
        v[k] = static_cast<int>(tris.values[static_cast<size_t>(3 * t + k)]);
        if (v[k] < 0 || v[k] >= X.cols())
          throw error("triangleList", "triangle " + std::to_string(t) + " refers to node " + std::to_string(v[k]) +
                                          ", but MechanicalObject '" + state_->name() + "' has " + std::to_string(X.cols()));
      }
      const double area = 0.5 * (X.col(v[1]) - X.col(v[0])).cross(X.col(v[2]) - X.col(v[0])).norm();
      for (int k = 0; k < 3; ++k) forces_.col(v[k]) += pressure * (area / 3.0);
    }
  }
  void addForce(State&, const Eigen::Matrix3Xd&, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    f += forces_;
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    return -(forces_.array() * x.array()).sum();
  }

 private:
  MechanicalObject* state_ = nullptr;
  Eigen::Matrix3Xd forces_;  // per node, constant
};

// SOFA's PlaneForceField: a penalty half-space. A node at signed distance d = x.n - d0 < 0 gets
// f = -k d n + c d v (the damping grows with the depth, against the node's whole velocity), and
// -k n n^T in the stiffness (the damping stays out of the matrix, as in SOFA).
class PlaneForceField : public Component, public ForceField, public Stateful {
 public:
  using Component::Component;
  bool assemblesUpper() const override { return true; }  // diagonal blocks only
  MechanicalObject& mstate() const override { return *state_; }
  struct Live : ComponentStateOf<Live> {
    std::vector<char> inside;  // per node, below the plane at the last addForce
    void save(StateWriter& out) const override { out.put(inside); }
    void load(StateReader& in) override { in.getSameSize(inside, "nodes"); }
  };
  std::unique_ptr<ComponentState> initialState() const override {
    auto l = std::make_unique<Live>();
    l->inside.assign(state_->size(), 0);
    return l;
  }
  void init() override {
    state_ = &contextState(*this);
    const auto& n = attrs_.reals("normal");
    n_ = Eigen::Vector3d(n[0], n[1], n[2]);
    if (!(n_.norm() > 0)) throw error("normal", "must not be zero");
    n_.normalize();
    d_ = attrs_.real("d");
    k_ = attrs_.real("stiffness");
    c_ = attrs_.real("damping");
    if (attrs_.boolean("bilateral")) throw error("bilateral", "only the one-sided plane is handled");
  }
  void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, Eigen::Matrix3Xd& f) const override {
    std::vector<char>& inside = stateIn<Live>(s).inside;
    for (Eigen::Index i = 0; i < x.cols(); ++i) {
      const double depth = x.col(i).dot(n_) - d_;
      inside[i] = depth < 0;
      if (inside[i]) f.col(i) += -k_ * depth * n_ + c_ * depth * v.col(i);
    }
  }
  void addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const override {
    const std::vector<char>& inside = stateIn<Live>(s).inside;
    for (Eigen::Index i = 0; i < dx.cols(); ++i)
      if (inside[i]) df.col(i) -= kFactor * k_ * n_.dot(dx.col(i)) * n_;
  }
  // Any node may go below the plane: every diagonal block.
  void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const override {
    for (int i = 0; i < state_->size(); ++i) pairs.push_back({i, i});
  }
  void addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const override {
    const std::vector<char>& inside = stateIn<Live>(s).inside;
    const Eigen::Matrix3d nn = n_ * n_.transpose();
    for (size_t i = 0; i < inside.size(); ++i)
      if (inside[i]) K.block(K.diagonalSlot(static_cast<int>(i))) -= kFactor * k_ * nn;
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    double e = 0;
    for (Eigen::Index i = 0; i < x.cols(); ++i) e += 0.5 * k_ * std::pow(std::min(0.0, x.col(i).dot(n_) - d_), 2);
    return e;
  }

 private:
  MechanicalObject* state_ = nullptr;
  Eigen::Vector3d n_ = Eigen::Vector3d::UnitY();
  double d_ = 0, k_ = 500, c_ = 5;
};

class ConstantForceField : public Component, public ForceField {
 public:
  using Component::Component;
  bool assemblesUpper() const override { return true; }  // adds no stiffness
  MechanicalObject& mstate() const override { return *state_; }
  void init() override {
    state_ = &contextState(*this);
    if (attrs_.isSet("indices")) {
      nodes_ = linkedInts("indices");
    } else {
      for (int i = 0; i < state_->size(); ++i) nodes_.push_back(i);
    }
    for (int i : nodes_)
      if (i < 0 || i >= state_->size()) throw error("indices", "node " + std::to_string(i) + " is out of range");
    forces_ = Eigen::Matrix3Xd::Zero(3, nodes_.size());
    if (attrs_.isSet("totalForce")) {
      const auto& t = attrs_.reals("totalForce");
      if (nodes_.empty()) throw error("totalForce", "no node to apply the force to");
      for (size_t k = 0; k < nodes_.size(); ++k) forces_.col(k) = Eigen::Vector3d(t[0], t[1], t[2]) / nodes_.size();
    } else if (attrs_.isSet("forces")) {
      const auto& f = attrs_.reals("forces");
      if (f.size() == 3) {
        for (size_t k = 0; k < nodes_.size(); ++k) forces_.col(k) = Eigen::Vector3d(f[0], f[1], f[2]);
      } else if (f.size() == 3 * nodes_.size()) {
        forces_ = Eigen::Map<const Eigen::Matrix3Xd>(f.data(), 3, nodes_.size());
      } else {
        throw error("forces", "expected one force or one per index (" + std::to_string(nodes_.size()) + "), got " +
                                  std::to_string(f.size() / 3));
      }
    } else {
      throw error("set forces or totalForce");
    }
  }
  void addForce(State& s, const Eigen::Matrix3Xd&, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    for (size_t k = 0; k < nodes_.size(); ++k) f.col(nodes_[k]) += forces_.col(k);
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    double e = 0;
    for (size_t k = 0; k < nodes_.size(); ++k) e -= forces_.col(k).dot(x.col(nodes_[k]));
    return e;
  }

 private:
  MechanicalObject* state_ = nullptr;
  std::vector<int> nodes_;
  Eigen::Matrix3Xd forces_;
};

}  // namespace

void registerConstraints(Registry& r) {
  for (const char* shape : {"PointProjectiveConstraint", "LineProjectiveConstraint", "PlaneProjectiveConstraint"}) {
    const std::string name = shape;
    ComponentSpec s;
    s.name = name;
    s.aliases = {"ProjectTo" + name.substr(0, name.find("Projective")) + "Constraint"};  // SOFA's older names
    s.category = "constraint";
    const bool point = name[1] == 'o', line = name[0] == 'L';
    s.doc = point ? "Holds nodes at `point`: they are out of the solve, and after each solve they are put there with zero "
                    "velocity (SOFA's projection)."
            : line ? "Keeps nodes on the line through `origin` along `direction`: in the solve they move along it only; "
                     "after each solve positions and velocities are projected onto it (SOFA's projection)."
                   : "Keeps nodes in the plane through `origin` with `normal`: in the solve they move in it only; after "
                     "each solve positions and velocities are projected onto it (SOFA's projection).";
    s.add(AttrSpec::ints("indices").def("0").atLeast(0).linked().help("the nodes (SOFA's default: node 0)"));
    if (point) {
      s.add(AttrSpec::reals("point", 3).def("0 0 0").unit(Dimension::length()).help("where the nodes are held"));
      s.add(AttrSpec::boolean("fixAll").def("false").help("hold every node"));
    } else {
      s.add(AttrSpec::reals("origin", 3).def("0 0 0").unit(Dimension::length()).help(line ? "a point of the line" : "a point of the plane"));
      s.add(AttrSpec::reals(line ? "direction" : "normal", 3).req().help(line ? "the line's direction" : "the plane's normal"));
    }
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<ShapeProjection>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "FixedConstraint";
    s.aliases = {"FixedProjectiveConstraint"};
    s.category = "constraint";
    s.doc = "Holds nodes at their positions: their rows are removed from the implicit system.";
    s.add(AttrSpec::ints("indices").def("").atLeast(0).linked().help("fixed nodes (or a link such as @box.indices)"));
    s.add(AttrSpec::boolean("fixAll").def("false").help("fix every node"));
    s.add(AttrSpec::boolean("activate_projectVelocity").def("false").help(
        "SOFA's switch to zero the fixed nodes' velocities too; the solve never changes them, so they stay zero "
        "(true with a fixed node that starts with a velocity is refused)"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
      if (inRigidNode(c)) return std::make_unique<RigidHold>(c);
      return std::make_unique<FixedConstraint>(c);
    };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "PartialFixedProjectiveConstraint";
    s.aliases = {"PartialFixedConstraint"};
    s.category = "constraint";
    s.doc = "Holds chosen nodes along chosen axes (fixedDirections=\"1 0 1\": x and z held, y free): those "
            "components of their motion are projected out of the system, the others move freely.";
    s.add(AttrSpec::ints("indices").def("0").atLeast(0).linked().help("the nodes (SOFA's default: node 0)"));
    s.add(AttrSpec::ints("fixedDirections").def("1 1 1").help("per axis x y z: 1 holds it, 0 leaves it free"));
    s.add(AttrSpec::boolean("fixAll").def("false").help("every node"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
      if (inRigidNode(c)) return std::make_unique<RigidHold>(c);
      return std::make_unique<DirectionalConstraint>(c);
    };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "FixedPlaneProjectiveConstraint";
    s.aliases = {"FixedPlaneConstraint"};
    s.category = "constraint";
    s.doc = "Keeps nodes in their plane: the nodes whose rest position p has dmin <= p . direction <= dmax (or the "
            "given indices) cannot move along `direction`, and move freely in the plane across it.";
    s.add(AttrSpec::reals("direction", 3).def("0 0 1").help("the plane's normal (need not be unit)"));
    s.add(AttrSpec::real("dmin").def("0").unit(Dimension::length()).help("lower bound of p . direction (direction normalised)"));
    s.add(AttrSpec::real("dmax").def("0").unit(Dimension::length()).help("upper bound of p . direction"));
    s.add(AttrSpec::ints("indices").atLeast(0).linked().help("the nodes, instead of the slab"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<DirectionalConstraint>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "BoxConstraint";
    s.category = "constraint";
    s.doc = "Holds the nodes whose rest positions lie in the boxes at their positions (SOFA's BoxConstraint: a "
            "BoxROI and a FixedConstraint in one).";
    s.add(AttrSpec::reals("box").req().multipleOf(6).unit(Dimension::length()).help("xmin ymin zmin xmax ymax zmax, repeated for several boxes"));
    s.add(AttrSpec::boolean("fixAll").def("false").help("fix every node"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<FixedConstraint>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "BoxROI";
    s.category = "engine";
    s.doc = "Selects the nodes inside one or more axis-aligned boxes (bounds inclusive, rest positions); output "
            "fields `indices` and `pointsInROI` (their positions).";
    s.add(AttrSpec::reals("box").def("0 0 0 1 1 1").multipleOf(6).unit(Dimension::length()).help("xmin ymin zmin xmax ymax zmax, repeated for several boxes"));
    s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("points to test (default: rest positions of the node's MechanicalObject)"));
    s.add(AttrSpec::boolean("strict").def("false").help("fail if the box selects nothing"));
    s.add(AttrSpec::ints("indices").help("SOFA's output: the selection, computed from the box; a value in the scene is replaced, as in SOFA"));
    s.add(AttrSpec::ints("triangles").multipleOf(3).atLeast(0).linked().help(
        "triangles to select from (three point indices each): those with all vertices inside give the output fields "
        "`triangleIndices` and `trianglesInROI`"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<BoxROI>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "PlaneForceField";
    s.category = "forcefield";
    s.doc = "A penalty half-space (SOFA's PlaneForceField): a node below the plane x.n = d, at depth d_i < 0, gets "
            "-stiffness d_i n + damping d_i v; its stiffness -stiffness n n^T enters the implicit system.";
    s.add(AttrSpec::reals("normal", 3).def("0 1 0").help("the plane's normal, towards the free side (normalised)"));
    s.add(AttrSpec::real("d").def("0").unit(Dimension::length()).help("the plane's offset along the normal"));
    s.add(AttrSpec::real("stiffness").def("500").atLeast(0).unit(Dimension::stiffness()).help("penalty stiffness"));
    s.add(AttrSpec::real("damping").def("5").atLeast(0).unit({0, 1, -1}).help("damping per unit depth (force per speed per length)"));
    s.add(AttrSpec::boolean("bilateral").def("false").help("SOFA's two-sided plane; only false is handled"));
    for (const char* draw : {"showPlane", "draw"}) s.add(AttrSpec::boolean(draw).def("false").help("drawing only"));
    s.add(AttrSpec::real("showPlaneSize").def("10").help("drawing only"));
    s.add(AttrSpec::string("color").help("drawing only"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<PlaneForceField>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "ConstantForceField";
    s.category = "forcefield";
    s.doc = "Constant forces on nodes: one per index, one for all, or a total spread evenly.";
    s.add(AttrSpec::ints("indices").atLeast(0).linked().help("nodes (default: all)"));
    s.add(AttrSpec::reals("forces").multipleOf(3).unit(Dimension::force()).help("force per node, or one force for all"));
    s.add(AttrSpec::reals("totalForce", 3).unit(Dimension::force()).help("total force, split evenly over the nodes"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<ConstantForceField>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "TrianglePressureForceField";
    s.category = "forcefield";
    s.doc = "A load per unit area on chosen triangles of a surface (SOFA's TrianglePressureForceField): `pressure` is a "
            "vector; each triangle carries pressure x its rest area, a third on each of its vertices, whatever the "
            "motion. The triangles are those of the topology in its node or above (e.g. a surface filled by "
            "Tetra2TriangleTopologicalMapping), their vertices nodes of the MechanicalObject.";
    s.add(AttrSpec::reals("pressure", 3).def("0 0 0").unit(Dimension::pressure()).help("the load per unit area (a vector)"));
    s.add(AttrSpec::ints("triangleList").def("").atLeast(0).linked().help("the loaded triangles (e.g. @box.triangleIndices)"));
    s.add(AttrSpec::boolean("useConstantForce").def("true").help("the load on the rest areas (only true)"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node or above)"));
    s.factory = [](BuildContext& c) { return std::make_unique<TrianglePressureForceField>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
