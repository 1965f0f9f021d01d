#include "engine/collision/Collision.h"
#include "engine/topology/GridSplit.h"
#include "io/mesh/Mesh.h"
#include "io/scene/InputCache.h"

#include <algorithm>
#include <sstream>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <cstdlib>

#include "engine/collision/Geometry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidDynamics.h"
#include "engine/rigid/RigidMapping.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/BlockSparseMatrix.h"
#include "core/Text.h"

namespace viscera {

// ---------------------------------------------------------------------------------------------
// SphereCollisionModel

void SphereCollisionModel::init() {
  if (node().find<MechanicalObject>() && !node().find<RigidObject>())
    throw error("is on a Vec3d object; Viscera's spheres sit on a rigid body (MechanicalObject template=\"Rigid3d\")");
  body_ = &contextRigid(*this, "mstate");
  const auto& r = attrs_.reals("radius");
  if (r.size() != 1) throw error("radius", "one radius per sphere, and a rigid body carries one sphere");
  radius_ = r[0];
  if (!(radius_ > 0)) throw error("radius", "must be positive");
  stiffness_ = linkedReals("contactStiffness").at(0);
}

Eigen::Vector3d SphereCollisionModel::centre(const State& s) const { return body_->live(s).p; }

void NodeSphereCollisionModel::init() {
  state_ = &contextState(*this, "mstate");
  const int n = state_->size();
  if (attrs().isSet("listRadius")) {
    radii_ = linkedReals("listRadius");
    if (static_cast<int>(radii_.size()) != n)
      throw error("listRadius", "has " + std::to_string(radii_.size()) + " radii for the " + std::to_string(n) +
                                    " nodes of MechanicalObject '" + state_->name() + "' (one per node)");
  } else {
    const auto& r = attrs().reals("radius");
    if (r.size() == 1) radii_.assign(n, r[0]);
    else if (static_cast<int>(r.size()) == n) radii_ = r;
    else throw error("radius", "one radius, or one per node of MechanicalObject '" + state_->name() + "' (" + std::to_string(n) + ")");
  }
  for (double r : radii_)
    if (!(r > 0)) throw error(attrs().isSet("listRadius") ? "listRadius" : "radius", "radii must be positive");
  if (attrs().boolean("selfCollision"))
    throw error("selfCollision", "self-collision is not handled: set it false");
}

// ---------------------------------------------------------------------------------------------
// SurfaceCollisionModel

struct SurfaceCollisionModel::Bvh {
  geom::AabbTree tree;
  std::vector<geom::AabbTree::Box> boxes;
};

namespace {

// The boundary surface of tetrahedra T at rest positions X, with its edges and adjacency.
struct SurfaceTopology {
  std::vector<std::array<int, 3>> tris;
  std::vector<int> verts;
  std::vector<std::array<int, 2>> edges;
  std::vector<std::array<int, 3>> triEdges;
  std::vector<std::vector<int>> edgeTris, vertexNeighbours;
};

// The surface's edges and neighbours from its outward boundary triangles.
SurfaceTopology surfaceTopology(const io::TriangleList& boundary, const Eigen::Matrix3Xd& X) {
  SurfaceTopology s;
  for (Eigen::Index t = 0; t < boundary.cols(); ++t) s.tris.push_back({boundary(0, t), boundary(1, t), boundary(2, t)});
  std::map<std::pair<int, int>, int> edgeId;
  s.triEdges.resize(s.tris.size());
  s.vertexNeighbours.assign(X.cols(), {});
  for (size_t t = 0; t < s.tris.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      int a = s.tris[t][k], b = s.tris[t][(k + 1) % 3];
      auto key = std::minmax(a, b);
      auto [it, fresh] = edgeId.try_emplace({key.first, key.second}, static_cast<int>(s.edges.size()));
      if (fresh) {
        s.edges.push_back({key.first, key.second});
        s.edgeTris.emplace_back();
        s.vertexNeighbours[a].push_back(b);
        s.vertexNeighbours[b].push_back(a);
      }
      s.edgeTris[it->second].push_back(static_cast<int>(t));
      s.triEdges[t][k] = it->second;
    }
  }
  for (int i = 0; i < X.cols(); ++i)
    if (!s.vertexNeighbours[i].empty()) s.verts.push_back(i);
  return s;
}

}  // namespace

const Eigen::Matrix3Xd& SurfaceCollisionModel::surfacePositions(const State& s) const { return surfaceState_->x(s); }

Eigen::Vector3d SurfaceCollisionModel::vertexPosition(const State& s, int v) const {
  const Eigen::Matrix3Xd& x = state_->x(s);
  if (vertexMap_.empty()) return x.col(v);
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (const auto& [n, w] : vertexMap_[v]) p += w * x.col(n);
  return p;
}

SurfaceCollisionModel::~SurfaceCollisionModel() = default;

SurfaceCollisionModel::Live::Live(const Live& o)
    : model(o.model), penalty(o.penalty), contacts(o.contacts), bvh(o.bvh ? std::make_shared<Bvh>(*o.bvh) : nullptr) {}

std::unique_ptr<ComponentState> SurfaceCollisionModel::initialState() const {
  auto l = std::make_unique<Live>();
  l->model = this;
  l->bvh = std::make_shared<Bvh>(*bvh0_);
  return l;
}

void SurfaceCollisionModel::init() {
  const std::string& t = typeName();
  kind_ = t == "PointCollisionModel" ? Kind::Points : t == "LineCollisionModel" ? Kind::Lines : Kind::Triangles;
  if (attrs_.boolean("selfCollision")) throw error("selfCollision", "self-collision is not handled; set it to false");
  surfaceState_ = state_ = &contextState(*this);
  stiffness_ = linkedReals("contactStiffness").at(0);
  ownDistance_ = attrs_.real("contactDistance");
  // A surface on a mapped state (SOFA's collision node under a body) acts on the mapping's input:
  // each surface vertex is a weighted sum of the body's nodes, and so is each contact.
  for (const auto& c : surfaceState_->node().components())
    if (dynamic_cast<Mapping*>(c.get())) scene().initComponent(*c);
  if (const auto* rm = dynamic_cast<const RigidMapping*>(surfaceState_->mappedBy())) {
    // A rigid body's surface: it moves with the body and takes no contact force.
    rigid_ = &rm->body();
  } else if (const Component* by = surfaceState_->mappedBy()) {
    const auto* m = dynamic_cast<const Mapping*>(by);
    if (!m || !m->inputState())
      throw error("its MechanicalObject '" + surfaceState_->name() + "' is mapped by " + by->typeName() +
                  ", which does not carry forces back to a body");
    state_ = m->inputState();
    vertexMap_.resize(surfaceState_->size());
    for (int v = 0; v < surfaceState_->size(); ++v) {
      if (!m->pointWeights(v, vertexMap_[v]))
        throw error("its MechanicalObject '" + surfaceState_->name() + "' is mapped by " + by->typeName() +
                    ", which does not give point " + std::to_string(v) + " as a weighted sum of the body's nodes");
      if (vertexMap_[v].size() > 8) throw error("a surface vertex depends on more than 8 nodes of the body");
    }
  }
  // The surface: from the `topology` link or the nearest node with a topology, the boundary of its
  // tetrahedra, else of its hexahedra (a grid), else its own triangles (a TriangleSetTopologyContainer,
  // e.g. filled by Tetra2TriangleTopologicalMapping, or a surface loader).
  const Eigen::Matrix3Xd& X = surfaceState_->x0;
  io::TriangleList boundary;
  Component& source = surfaceSource();
  const Topology& topo = dynamic_cast<const Topology&>(source);
  if (topo.points().cols() > 0 && topo.points().cols() != X.cols())
    throw error("its surface comes from '" + source.name() + "' (" + source.node().path() + "), whose " +
                std::to_string(topo.points().cols()) + " points are not the nodes of MechanicalObject '" + state_->name() +
                "' (" + std::to_string(X.cols()) + ")");
  if (topo.tetrahedra().cols() > 0) {
    const TetList& T = topo.tetrahedra();
    checkNodes(T.data(), T.size(), X.cols());
    boundary = io::boundaryTriangles(T, X);
  } else if (!topo.hexahedra().empty()) {
    for (const auto& h : topo.hexahedra()) checkNodes(h.data(), 8, X.cols());
    boundary = hexahedronBoundaryTriangles(topo.hexahedra(), X);
  } else {
    FieldValue tris;
    source.field("triangles", tris);
    boundary.resize(3, static_cast<Eigen::Index>(tris.values.size() / 3));
    for (Eigen::Index i = 0; i < boundary.size(); ++i) {
      if (!(tris.values[i] >= 0 && tris.values[i] < static_cast<double>(X.cols())))
        throw error("its surface '" + source.name() + "' refers to node " + formatNumber(tris.values[i]) +
                    ", but MechanicalObject '" + state_->name() + "' has " + std::to_string(X.cols()) + " nodes");
      boundary.data()[i] = static_cast<int>(tris.values[i]);
    }
  }
  // Shared by every scene variant with the same mesh (input cache).
  const auto surface = io::cachedDerived<SurfaceTopology>("collision surface", io::keyBytes(boundary) + io::keyBytes(X),
                                                       [&] { return surfaceTopology(boundary, X); });
  if (surface->tris.empty()) throw error("the topology has no boundary triangles");
  tris_ = surface->tris;
  verts_ = surface->verts;
  edges_ = surface->edges;
  meanEdge_ = 0;
  for (const auto& e : edges_) meanEdge_ += (X.col(e[1]) - X.col(e[0])).norm();
  if (!edges_.empty()) meanEdge_ /= static_cast<double>(edges_.size());
  triEdges_ = surface->triEdges;
  edgeTris_ = surface->edgeTris;
  vertexNeighbours_ = surface->vertexNeighbours;
  vertexTris_.assign(X.cols(), {});
  for (int t = 0; t < static_cast<int>(tris_.size()); ++t)
    for (int v : tris_[t]) vertexTris_[v].push_back(t);
  auto bvh = std::make_shared<Bvh>();
  fitBoxes(X, *bvh);
  bvh->tree.build(bvh->boxes);
  bvh0_ = std::move(bvh);
  // Nothing moves a body no solver integrates (its node's, or one above that collects it).
  static_ = !rigid_ && !integratingNode(*state_);
  if (rigid_)
    for (const Node* n = &rigid_->node(); n && !solverAbove_; n = n->parent()) solverAbove_ = n->find<OdeSolver>() != nullptr;
}

bool SurfaceCollisionModel::integrated() const {
  // A rigid body's mass, driver and prescribed velocity are known once the scene is initialised.
  if (rigid_) return solverAbove_ && rigid_->mass > 0 && !rigid_->driven && !rigid_->prescribedVelocity;
  return !static_;
}

namespace {
// 3: tetrahedra, 2: hexahedra, 1: triangles only, 0: nothing a surface can come from.
int surfaceRank(const Component& c) {
  const auto* t = dynamic_cast<const Topology*>(&c);
  if (!t) return 0;
  if (t->tetrahedra().cols() > 0) return 3;
  if (!t->hexahedra().empty()) return 2;
  FieldValue tris;
  return c.field("triangles", tris) && !tris.values.empty() ? 1 : 0;
}
}  // namespace

Component& SurfaceCollisionModel::surfaceSource() {
  if (attrs_.isSet("topology")) {
    Component* c = linkedComponent("topology");
    if (!c) throw error("topology", "does not link to a component");
    scene().initComponent(*c);
    if (!surfaceRank(*c)) throw error("topology", "links to '" + c->name() + "', which has no tetrahedra, hexahedra or triangles");
    return *c;
  }
  // The nearest node with a topology; in it, tetrahedra before hexahedra before triangles, and
  // among equals one whose points are the state's nodes, then a topology container before a loader
  // (a node may also load its visual mesh).
  const Eigen::Index nodes = surfaceState_->x0.cols();
  for (const Node* n = &node(); n; n = n->parent()) {
    Component* best = nullptr;
    int bestRank = 0;
    for (auto it = n->components().rbegin(); it != n->components().rend(); ++it) {
      const auto* topo = dynamic_cast<Topology*>(it->get());
      if (!topo) continue;
      scene().initComponent(**it);
      const int rank = surfaceRank(**it);
      if (!rank) continue;
      const bool fits = topo->points().cols() == 0 || topo->points().cols() == nodes;
      if (const int r = 4 * rank + 2 * fits + ((*it)->spec().category != "loader"); r > bestRank) {
        best = it->get();
        bestRank = r;
      }
    }
    if (best) return *best;
  }
  throw error("no topology with tetrahedra, hexahedra or triangles in its node or above");
}

void SurfaceCollisionModel::checkNodes(const int* nodes, Eigen::Index count, Eigen::Index size) const {
  for (Eigen::Index i = 0; i < count; ++i)
    if (nodes[i] < 0 || nodes[i] >= size)
      throw error("an element refers to node " + std::to_string(nodes[i]) + " but the MechanicalObject has " +
                  std::to_string(size) + " nodes");
}

void SurfaceCollisionModel::fitBoxes(const Eigen::Matrix3Xd& x, Bvh& bvh) const {
  const size_t n = kind_ == Kind::Points ? verts_.size() : tris_.size();
  bvh.boxes.resize(n);
  for (size_t i = 0; i < n; ++i) {
    geom::AabbTree::Box b;
    if (kind_ == Kind::Points) b.extend(x.col(verts_[i]));
    else for (int k : tris_[i]) b.extend(x.col(k));
    bvh.boxes[i] = b;
  }
}

double SurfaceCollisionModel::distanceTo(const State& s, const Eigen::Vector3d& p, double within,
                                         const Eigen::Matrix3Xd& x) const {
  double best = std::numeric_limits<double>::infinity();
  const geom::AabbTree::Box query(p - Eigen::Vector3d::Constant(within), p + Eigen::Vector3d::Constant(within));
  stateIn<Live>(s).bvh->tree.query(query, [&](int i) {
    double d;
    if (kind_ == Kind::Points) {
      d = (x.col(verts_[i]) - p).norm();
    } else {
      const auto& t = tris_[i];
      d = (geom::closestOnTriangle(p, x.col(t[0]), x.col(t[1]), x.col(t[2])).point - p).norm();
    }
    best = std::min(best, d);
  });
  return best < within ? best : std::numeric_limits<double>::infinity();
}

void SurfaceCollisionModel::refit(State& st, const Eigen::Matrix3Xd& x) const {
  Bvh& bvh = *stateIn<Live>(st).bvh;
  fitBoxes(x, bvh);
  bvh.tree.refit(bvh.boxes);
}

void SurfaceCollisionModel::detect(const State& st, const SphereCollisionModel& sphere, const Eigen::Matrix3Xd& x,
                                   const ContactSettings& s, std::vector<Contact>& out) const {
  const size_t first = out.size();
  detectAt(st, sphere.centre(st), sphere.radius(), sphere.radius(), x, s, out);
  for (size_t i = first; i < out.size(); ++i) out[i].sphere = &sphere;
}

void SurfaceCollisionModel::detectVertices(const State& st, const SurfaceCollisionModel& other, const ContactSettings& s,
                                           std::vector<Contact>& here, std::vector<Contact>& there) const {
  const Eigen::Matrix3Xd& x = surfacePositions(st);
  const Eigen::Matrix3Xd& y = other.surfacePositions(st);
  // A vertex may be found inside this surface down to the alarm distance (or a tenth of an edge).
  const double depth = std::max(s.alarmDistance, 0.1 * meanEdge_);
  // SOFA's penalty stiffness for a point: the two models' factors over the contact distance.
  const double k = stiffness_ * other.stiffness_ / std::max(s.contactDistance, 1e-12 * std::max(meanEdge_, 1.0));
  for (int v : other.verts_) {
    const size_t first = here.size();
    detectAt(st, y.col(v), 0.0, depth, x, s, here);
    for (size_t i = first; i < here.size(); ++i) {
      Contact& c = here[i];
      c.partner = &other;
      c.mirror = static_cast<int>(there.size());
      c.k = k;
      c.active = c.gap0 < 0;
      // The mirror on the vertex: the same gap, the opposite normal, on the nodes the vertex follows.
      Contact m;
      m.partner = this;
      m.mirror = static_cast<int>(i);
      m.surface = &other;
      m.feature = Feature::Vertex;
      other.addVertex(m, v, 1.0);
      m.n = -c.n;
      // The vertex's own point at detection: its nodes' weighted sum (the vertex itself, or the
      // body nodes a mapped vertex follows).
      m.p0 = m.point(other.state_->x(st));
      m.gap0 = c.gap0;
      m.active = c.active;
      m.k = k;
      there.push_back(m);
    }
  }
}

void SurfaceCollisionModel::addVertex(Contact& c, int v, double w) const {
  if (vertexMap_.empty()) {
    c.nodes[c.count] = v;
    c.w[c.count] = w;
    ++c.count;
    return;
  }
  for (auto [node, bw] : vertexMap_[v]) {
    c.nodes[c.count] = node;
    c.w[c.count] = w * bw;
    ++c.count;
  }
}

Eigen::Vector3d SurfaceCollisionModel::faceNormal(int t, const Eigen::Matrix3Xd& x) const {
  const auto& tri = tris_[t];
  return (x.col(tri[1]) - x.col(tri[0])).cross(x.col(tri[2]) - x.col(tri[0])).normalized();
}

Eigen::Vector3d SurfaceCollisionModel::edgeNormal(int e, const Eigen::Matrix3Xd& x) const {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int t : edgeTris_[e]) n += faceNormal(t, x);
  return n;
}

Eigen::Vector3d SurfaceCollisionModel::vertexNormal(int v, const Eigen::Matrix3Xd& x) const {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int t : vertexTris_[v]) n += faceNormal(t, x);
  return n;
}

void SurfaceCollisionModel::detectEdges(const State& st, const SurfaceCollisionModel& other, const ContactSettings& s,
                                        std::vector<Contact>& here, std::vector<Contact>& there) const {
  if (kind_ == Kind::Points || other.kind_ == Kind::Points) return;
  const Eigen::Matrix3Xd& x = surfacePositions(st);
  const Eigen::Matrix3Xd& y = other.surfacePositions(st);
  const Bvh& bvh = *stateIn<Live>(st).bvh;
  const double k = stiffness_ * other.stiffness_ / std::max(s.contactDistance, 1e-12 * std::max(meanEdge_, 1.0));
  const double interior = 1e-6;  // closest points strictly inside both edges (else a vertex contact)
  std::vector<int> tested(edges_.size(), -1);  // the last edge of `other` each edge here was tested against
  for (int eb = 0; eb < static_cast<int>(other.edges_.size()); ++eb) {
    const Eigen::Vector3d b0 = y.col(other.edges_[eb][0]), b1 = y.col(other.edges_[eb][1]);
    geom::AabbTree::Box box(b0.cwiseMin(b1), b0.cwiseMax(b1));
    box.extend(box.min() - Eigen::Vector3d::Constant(s.alarmDistance));
    box.extend(box.max() + Eigen::Vector3d::Constant(s.alarmDistance));
    bvh.tree.query(box, [&](int t) {
      for (int ea : triEdges_[t]) {
        if (tested[ea] == eb) continue;
        tested[ea] = eb;
        const Eigen::Vector3d a0 = x.col(edges_[ea][0]), a1 = x.col(edges_[ea][1]);
        const Eigen::Vector3d u = a1 - a0, v = b1 - b0, w0 = a0 - b0;
        const double uu = u.dot(u), uv = u.dot(v), vv = v.dot(v), uw = u.dot(w0), vw = v.dot(w0);
        const double det = uu * vv - uv * uv;
        // Nearly parallel (within a milliradian): the closest points slide along the edges with
        // rounding, and the ends' vertex contacts hold such edges.
        if (!(det > 1e-6 * uu * vv)) continue;
        const double sa = (uv * vw - vv * uw) / det, sb = (uu * vw - uv * uw) / det;
        if (sa < interior || sa > 1 - interior || sb < interior || sb > 1 - interior) continue;
        const Eigen::Vector3d p = a0 + sa * u, q = b0 + sb * v, pq = q - p;
        const double dist = pq.norm();
        if (dist >= s.alarmDistance || !(dist > 1e-12 * std::sqrt(uu))) continue;
        // Each edge sees the other outside its own body (not past the faces at the edge).
        if (!(edgeNormal(ea, x).dot(pq) > 0) || !(other.edgeNormal(eb, y).dot(-pq) > 0)) continue;
        Contact c;
        c.surface = this;
        c.feature = Feature::Edge;
        addVertex(c, edges_[ea][0], 1 - sa);
        addVertex(c, edges_[ea][1], sa);
        c.n = pq / dist;
        c.p0 = p;
        c.gap0 = dist - s.contactDistance;
        c.partner = &other;
        c.mirror = static_cast<int>(there.size());
        c.k = k;
        c.active = c.gap0 < 0;
        Contact m;
        m.surface = &other;
        m.feature = Feature::Edge;
        other.addVertex(m, other.edges_[eb][0], 1 - sb);
        other.addVertex(m, other.edges_[eb][1], sb);
        m.n = -c.n;
        m.p0 = m.point(other.state_->x(st));
        m.gap0 = c.gap0;
        m.partner = this;
        m.mirror = static_cast<int>(here.size());
        m.k = k;
        m.active = c.active;
        here.push_back(c);
        there.push_back(m);
      }
    });
  }
}

void SurfaceCollisionModel::addPair(const State& st, const SurfaceCollisionModel& other, const ContactSettings& s, Feature fa,
                                    std::initializer_list<std::pair<int, double>> a, Feature fb,
                                    std::initializer_list<std::pair<int, double>> b, const Eigen::Vector3d& n, double dist,
                                    std::vector<Contact>& here, std::vector<Contact>& there) const {
  if (!(n.norm() > 0.5)) return;  // no direction (coincident features on a degenerate surface): nothing to push along
  Contact c, m;
  c.surface = this;
  c.feature = fa;
  for (auto [v, w] : a) addVertex(c, v, w);
  m.surface = &other;
  m.feature = fb;
  for (auto [v, w] : b) other.addVertex(m, v, w);
  c.n = n;
  m.n = -n;
  c.p0 = c.point(state_->x(st));
  m.p0 = m.point(other.state_->x(st));
  c.gap0 = m.gap0 = dist - s.contactDistance;
  c.active = m.active = c.gap0 < 0;
  c.k = m.k = stiffness_ * other.stiffness_ / std::max(s.contactDistance, 1e-12 * std::max(meanEdge_, 1.0));
  c.partner = &other;
  m.partner = this;
  c.mirror = static_cast<int>(there.size());
  m.mirror = static_cast<int>(here.size());
  here.push_back(c);
  there.push_back(m);
}

// LocalMinDistance's validity tests, as SOFA writes them: d points from the feature's closest point
// to the other feature. The cones around an edge and a vertex open with the angle between the
// faces (coneFactor) plus angleCone.
bool SurfaceCollisionModel::triangleSees(const Eigen::Matrix3Xd& x, int t, const Eigen::Vector3d& d,
                                         const ContactSettings& s) const {
  if (!s.filter) return true;
  const auto& tri = tris_[t];
  return (x.col(tri[1]) - x.col(tri[0])).cross(x.col(tri[2]) - x.col(tri[0])).dot(d) >= 0.0;
}

bool SurfaceCollisionModel::edgeSees(const Eigen::Matrix3Xd& x, int e, const Eigen::Vector3d& d, const ContactSettings& s) const {
  if (!s.filter) return true;
  const int i1 = edges_[e][0], i2 = edges_[e][1];
  const Eigen::Vector3d ab = (x.col(i2) - x.col(i1)).normalized();
  const auto& around = edgeTris_[e];
  // A border or non-manifold edge: only a contact square to it.
  if (around.size() != 2) return std::abs(ab.dot(d.normalized())) <= s.angleCone + 1e-4;
  auto runs = [&](const std::array<int, 3>& t) {  // the triangle on the edge's left runs i1 -> i2
    for (int k = 0; k < 3; ++k)
      if (t[k] == i1 && t[(k + 1) % 3] == i2) return true;
    return false;
  };
  const bool firstLeft = runs(tris_[around[0]]);
  const Eigen::Vector3d n1 = faceNormal(around[firstLeft ? 1 : 0], x), n2 = faceNormal(around[firstLeft ? 0 : 1], x);
  const Eigen::Vector3d mean = (n1 + n2).normalized();
  if (mean.dot(d) < 0) return false;
  // Each face's tangent pointing away from it across the edge.
  const Eigen::Vector3d tangents[2] = {n1.cross(ab).normalized(), ab.cross(n2).normalized()};
  const double len = d.norm();
  for (const Eigen::Vector3d& t : tangents) {
    const double cone = std::max(0.0, mean.dot(t) * s.coneFactor) + s.angleCone;
    if (t.dot(d) < -cone * len) return false;
  }
  return true;
}

bool SurfaceCollisionModel::vertexSees(const Eigen::Matrix3Xd& x, int v, const Eigen::Vector3d& d, const ContactSettings& s,
                                       bool lines) const {
  // SOFA filters a point only where its node also has a line model.
  if (!s.filter || !lines) return true;
  const Eigen::Vector3d p = x.col(v);
  Eigen::Vector3d mean = vertexNormal(v, x);
  if (vertexTris_[v].empty())
    for (int u : vertexNeighbours_[v]) mean += (p - x.col(u)).normalized();
  const double len = d.norm();
  if (mean.norm() > 1e-10) {
    mean.normalize();
    if (mean.dot(d) < -s.angleCone * len) return false;
  }
  for (int u : vertexNeighbours_[v]) {
    const Eigen::Vector3d l = (p - x.col(u)).normalized();  // along the edge, out of the body
    const double cone = std::max(0.0, mean.dot(l) * s.coneFactor) + s.angleCone;
    if (l.dot(d) < -cone * len) return false;
  }
  return true;
}

void SurfaceCollisionModel::localMinVertices(const State& st, const SurfaceCollisionModel& other, const ContactSettings& s,
                                             Features mine, Features theirs, std::vector<Contact>& here,
                                             std::vector<Contact>& there) const {
  if (!theirs.points) return;
  const Eigen::Matrix3Xd& x = surfacePositions(st);
  const Eigen::Matrix3Xd& y = other.surfacePositions(st);
  const Bvh& bvh = *stateIn<Live>(st).bvh;
  const double alarm2 = s.alarmDistance * s.alarmDistance;
  // Features closer than this touch: SOFA's direction between them is undefined (it divides by
  // zero), so the contact takes this surface's normal there and skips the validity tests.
  const double touch = 1e-12 * std::max(meanEdge_, other.meanEdge_);
  std::vector<int> tested(edges_.size(), -1);  // the last vertex each edge was tested against
  for (int v : other.verts_) {
    const Eigen::Vector3d P = y.col(v);
    const geom::AabbTree::Box box(P - Eigen::Vector3d::Constant(s.alarmDistance), P + Eigen::Vector3d::Constant(s.alarmDistance));
    bvh.tree.query(box, [&](int t) {
      const auto& tri = tris_[t];
      // The vertex against the triangle's interior (barycentric coordinates above 1e-6).
      const Eigen::Vector3d A = x.col(tri[0]), AB = x.col(tri[1]) - A, AC = x.col(tri[2]) - A, AP = P - A;
      const double a00 = AB.dot(AB), a11 = AC.dot(AC), a01 = AB.dot(AC), b0 = AP.dot(AB), b1 = AP.dot(AC);
      const double det = a00 * a11 - a01 * a01;
      const double alpha = (b0 * a11 - b1 * a01) / det, beta = (b1 * a00 - b0 * a01) / det;
      if (alpha >= 1e-6 && beta >= 1e-6 && alpha + beta <= 0.999999) {
        const Eigen::Vector3d Q = A + alpha * AB + beta * AC, QP = P - Q;
        const double dist = QP.norm();
        const bool touching = dist <= touch;  // no direction between them: the face's own
        if (dist * dist < alarm2 &&
            (touching || (other.vertexSees(y, v, -QP, s, theirs.lines) && triangleSees(x, t, QP, s))))
          addPair(st, other, s, Feature::Face, {{tri[0], 1 - alpha - beta}, {tri[1], alpha}, {tri[2], beta}}, Feature::Vertex,
                  {{v, 1.0}}, touching ? faceNormal(t, x) : Eigen::Vector3d(QP / dist), dist, here, there);
      }
      if (!mine.lines) return;
      // The vertex against the interior of the triangle's edges (each edge once per vertex).
      for (int e : triEdges_[t]) {
        if (tested[e] == v) continue;
        tested[e] = v;
        const Eigen::Vector3d E0 = x.col(edges_[e][0]), E = x.col(edges_[e][1]) - E0, EP = P - E0;
        if (!(E.norm() >= 1e-12 * EP.norm())) continue;
        const double a = EP.dot(E) / E.dot(E);
        if (!(a >= 1e-6 && a <= 0.999999)) continue;
        const Eigen::Vector3d Q = E0 + a * E, QP = P - Q;
        const double dist = QP.norm();
        const bool touching = dist <= touch;
        if (dist * dist < alarm2 && (touching || (other.vertexSees(y, v, -QP, s, theirs.lines) && edgeSees(x, e, QP, s))))
          addPair(st, other, s, Feature::Edge, {{edges_[e][0], 1 - a}, {edges_[e][1], a}}, Feature::Vertex, {{v, 1.0}},
                  touching ? Eigen::Vector3d(edgeNormal(e, x).normalized()) : Eigen::Vector3d(QP / dist), dist, here, there);
      }
    });
  }
}

void SurfaceCollisionModel::detectLocalMinDistance(const State& st, const SurfaceCollisionModel& other,
                                                   const ContactSettings& s, Features mine, Features theirs,
                                                   std::vector<Contact>& here, std::vector<Contact>& there) const {
  localMinVertices(st, other, s, mine, theirs, here, there);
  other.localMinVertices(st, *this, s, theirs, mine, there, here);
  const Eigen::Matrix3Xd& x = surfacePositions(st);
  const Eigen::Matrix3Xd& y = other.surfacePositions(st);
  const Bvh& bvh = *stateIn<Live>(st).bvh;
  const double alarm2 = s.alarmDistance * s.alarmDistance;
  const double touch = 1e-12 * std::max(meanEdge_, other.meanEdge_);  // as in localMinVertices
  const Eigen::Vector3d reach = Eigen::Vector3d::Constant(s.alarmDistance);
  if (mine.points && theirs.points) {
    std::vector<int> tested(x.cols(), -1);
    for (int v : other.verts_) {
      const Eigen::Vector3d P = y.col(v);
      bvh.tree.query(geom::AabbTree::Box(P - reach, P + reach), [&](int t) {
        for (int u : tris_[t]) {
          if (tested[u] == v) continue;
          tested[u] = v;
          const Eigen::Vector3d d = P - x.col(u);
          const double dist = d.norm();
          if (dist <= touch) {  // coincident vertices: this one's mean face normal
            addPair(st, other, s, Feature::Vertex, {{u, 1.0}}, Feature::Vertex, {{v, 1.0}}, vertexNormal(u, x).normalized(), dist,
                    here, there);
          } else if (dist * dist < alarm2 && vertexSees(x, u, d, s, mine.lines) && other.vertexSees(y, v, -d, s, theirs.lines)) {
            addPair(st, other, s, Feature::Vertex, {{u, 1.0}}, Feature::Vertex, {{v, 1.0}}, d / dist, dist, here, there);
          }
        }
      });
    }
  }
  if (!(mine.lines && theirs.lines)) return;
  std::vector<int> tested(edges_.size(), -1);
  for (int eb = 0; eb < static_cast<int>(other.edges_.size()); ++eb) {
    const Eigen::Vector3d C = y.col(other.edges_[eb][0]), D = y.col(other.edges_[eb][1]);
    bvh.tree.query(geom::AabbTree::Box(C.cwiseMin(D) - reach, C.cwiseMax(D) + reach), [&](int t) {
      for (int ea : triEdges_[t]) {
        if (tested[ea] == eb) continue;
        tested[ea] = eb;
        const Eigen::Vector3d A = x.col(edges_[ea][0]), AB = x.col(edges_[ea][1]) - A, CD = D - C, AC = C - A;
        const double a00 = AB.dot(AB), a11 = CD.dot(CD), a01 = -CD.dot(AB), b0 = AB.dot(AC), b1 = -CD.dot(AC);
        const double det = a00 * a11 - a01 * a01;
        double alpha = 0.5, beta = 0.5;  // parallel edges: their middles
        if (std::abs(det) > 1e-30) {
          alpha = (b0 * a11 - b1 * a01) / det;
          beta = (b1 * a00 - b0 * a01) / det;
          if (!(alpha >= 1e-15 && alpha <= 1 - 1e-15 && beta >= 1e-15 && beta <= 1 - 1e-15)) continue;
        }
        const Eigen::Vector3d PQ = C + beta * CD - (A + alpha * AB);
        const double dist = PQ.norm();
        const bool touching = dist <= touch;
        if (dist * dist < alarm2 && (touching || (edgeSees(x, ea, PQ, s) && other.edgeSees(y, eb, -PQ, s))))
          addPair(st, other, s, Feature::Edge, {{edges_[ea][0], 1 - alpha}, {edges_[ea][1], alpha}}, Feature::Edge,
                  {{other.edges_[eb][0], 1 - beta}, {other.edges_[eb][1], beta}},
                  touching ? Eigen::Vector3d(edgeNormal(ea, x).normalized()) : Eigen::Vector3d(PQ / dist), dist, here, there);
      }
    });
  }
}

void SurfaceCollisionModel::detectAt(const State& st, const Eigen::Vector3d& c, double R, double depth,
                                     const Eigen::Matrix3Xd& x, const ContactSettings& s, std::vector<Contact>& out) const {
  const Bvh& bvh = *stateIn<Live>(st).bvh;
  const double reach = std::max(R, depth) + s.alarmDistance;
  const geom::AabbTree::Box query(c - Eigen::Vector3d::Constant(reach), c + Eigen::Vector3d::Constant(reach));

  auto make = [&](Feature f, std::initializer_list<std::pair<int, double>> nw, const Eigen::Vector3d& q,
                  const Eigen::Vector3d& nrm, double dist) {
    Contact ct;
    ct.surface = this;
    ct.feature = f;
    for (auto [node, w] : nw) addVertex(ct, node, w);
    ct.n = nrm;
    ct.p0 = q;
    ct.gap0 = dist - R - s.contactDistance;
    out.push_back(ct);
  };

  if (kind_ == Kind::Points) {
    bvh.tree.query(query, [&](int i) {
      const int v = verts_[i];
      const Eigen::Vector3d d = c - x.col(v);
      const double dist = d.norm();
      if (dist - R >= s.alarmDistance || dist < 1e-12 * reach) return;
      make(Feature::Vertex, {{v, 1.0}}, x.col(v), d / dist, dist);
    });
    return;
  }

  std::set<std::pair<int, int>> seen;  // (feature kind, id): a feature is reported once
  bvh.tree.query(query, [&](int t) {
    const auto& tri = tris_[t];
    const Eigen::Vector3d a = x.col(tri[0]), b = x.col(tri[1]), cc = x.col(tri[2]);
    geom::TriangleClosest cl = geom::closestOnTriangle(c, a, b, cc);
    const Eigen::Vector3d d = c - cl.point;
    if (d.norm() - R >= s.alarmDistance && cl.region != 0) return;
    if (cl.region == 0) {
      if (kind_ == Kind::Lines) return;
      const Eigen::Vector3d nf = (b - a).cross(cc - a).normalized();
      const double dist = d.dot(nf);  // signed: negative once the centre is under the face
      if (dist - R >= s.alarmDistance || dist < -depth) return;
      if (!seen.insert({0, t}).second) return;
      make(Feature::Face, {{tri[0], cl.w[0]}, {tri[1], cl.w[1]}, {tri[2], cl.w[2]}}, cl.point, nf, dist);
      return;
    }
    // Edge or vertex: keep it only if the centre lies in the feature's outer Voronoi region,
    // i.e. the closest point is a local minimum over the neighbouring faces too.
    const double dn = d.norm();
    if (cl.region <= 3) {
      const int k = cl.region - 1;  // edge (tri[k], tri[k+1])
      const int eid = triEdges_[t][k];
      if (!seen.insert({1, eid}).second) return;
      const int ia = tri[k], ib = tri[(k + 1) % 3];
      const Eigen::Vector3d dir = (x.col(ib) - x.col(ia)).normalized();
      Eigen::Vector3d nsum = Eigen::Vector3d::Zero();
      for (int adj : edgeTris_[eid]) {
        const auto& at = tris_[adj];
        int o = at[0] + at[1] + at[2] - ia - ib;
        Eigen::Vector3d tv = x.col(o) - cl.point;
        tv -= tv.dot(dir) * dir;
        if (d.dot(tv) > 1e-9 * dn * tv.norm()) return;
        nsum += (x.col(at[1]) - x.col(at[0])).cross(x.col(at[2]) - x.col(at[0])).normalized();
      }
      const double wa = cl.w[k], wb = cl.w[(k + 1) % 3];
      Eigen::Vector3d nrm = dn > 1e-12 * reach ? Eigen::Vector3d(d / dn) : nsum.normalized();
      double dist = dn;
      if (nrm.dot(nsum) < 0) {  // centre inside the body past this edge
        nrm = -nrm;
        dist = -dist;
      }
      make(Feature::Edge, {{ia, wa}, {ib, wb}}, cl.point, nrm, dist);
      return;
    }
    const int vtx = tri[cl.region - 4];
    if (!seen.insert({2, vtx}).second) return;
    for (int u : vertexNeighbours_[vtx]) {
      const Eigen::Vector3d e = x.col(u) - x.col(vtx);
      if (d.dot(e) > 1e-9 * dn * e.norm()) return;
    }
    Eigen::Vector3d nrm;
    if (dn > 1e-12 * reach) {
      nrm = d / dn;
    } else {
      // The centre exactly on the vertex: no direction from the vertex to the centre, so the
      // outward normal of the faces around it (a rare case: the scan over the faces is fine).
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (const auto& at : tris_)
        if (at[0] == vtx || at[1] == vtx || at[2] == vtx)
          sum += (x.col(at[1]) - x.col(at[0])).cross(x.col(at[2]) - x.col(at[0])).normalized();
      if (!(sum.norm() > 0)) return;  // no face: no side to push towards
      nrm = sum.normalized();
    }
    make(Feature::Vertex, {{vtx, 1.0}}, cl.point, nrm, dn);
  });
}

void SurfaceCollisionModel::Live::save(StateWriter& out) const {
  // A contact's sphere is written as its index among the scene's spheres.
  const auto spheres = model->scene().all<SphereCollisionModel>();
  const auto surfaces = model->scene().all<SurfaceCollisionModel>();
  out.put(penalty);
  out.count(static_cast<std::int64_t>(contacts.size()));
  for (const Contact& c : contacts) {
    out.put(c.sphere ? static_cast<int>(std::find(spheres.begin(), spheres.end(), c.sphere) - spheres.begin()) : -1);
    out.put(c.partner ? static_cast<int>(std::find(surfaces.begin(), surfaces.end(), c.partner) - surfaces.begin()) : -1);
    out.put(c.mirror);
    out.put(c.feature);
    out.put(c.count);
    for (int k = 0; k < c.count; ++k) out.put(c.nodes[k]);
    for (int k = 0; k < c.count; ++k) out.put(c.w[k]);
    out.put(c.n);
    out.put(c.p0);
    out.put(c.gap0);
    out.put(c.force);
    out.put(c.active);
    out.put(c.k);
  }
}

void SurfaceCollisionModel::Live::load(StateReader& in) {
  const auto spheres = model->scene().all<SphereCollisionModel>();
  const auto surfaces = model->scene().all<SurfaceCollisionModel>();
  const int nodes = model->mstate().size();
  in.get(penalty);
  const std::int64_t n = in.count();
  if (static_cast<size_t>(n) > in.remaining()) in.mismatch("more contacts than it holds");
  std::vector<Contact> cs(n);
  for (Contact& c : cs) {
    int sphere = -1;
    in.get(sphere);
    if (sphere < -1 || sphere >= static_cast<int>(spheres.size())) in.mismatch("a contact with a sphere it does not have");
    c.sphere = sphere >= 0 ? spheres[sphere] : nullptr;  // -1: a contact between two bodies
    int partner = -1;
    in.get(partner);
    in.get(c.mirror);
    if (partner < -1 || partner >= static_cast<int>(surfaces.size()) || (partner >= 0) == (sphere >= 0) || (partner >= 0 && c.mirror < 0))
      in.mismatch("a contact with a partner it does not have");
    c.partner = partner >= 0 ? surfaces[partner] : nullptr;
    c.surface = model;
    in.get(c.feature);
    in.get(c.count);
    if (c.count < 1 || c.count > kMaxContactNodes) in.mismatch("a contact with " + std::to_string(c.count) + " nodes");
    for (int k = 0; k < c.count; ++k) in.get(c.nodes[k]);
    for (int k = 0; k < c.count; ++k) in.get(c.w[k]);
    for (int k = 0; k < c.count; ++k)
      if (c.nodes[k] < 0 || c.nodes[k] >= nodes) in.mismatch("a contact on node " + std::to_string(c.nodes[k]));
    in.get(c.n);
    in.get(c.p0);
    in.get(c.gap0);
    in.get(c.force);
    in.get(c.active);
    in.get(c.k);
  }
  contacts = std::move(cs);
}

void SurfaceCollisionModel::setContacts(State& st, std::vector<Contact> c, const ContactSettings& s) const {
  Live& l = stateIn<Live>(st);
  l.contacts = std::move(c);
  l.penalty = s.response == ContactSettings::Response::Penalty;
  // SOFA's penalty: each model's contactStiffness factor multiplied, over the distance the contact
  // keeps between the sphere's centre and the surface (contactDistance plus the radius).
  for (Contact& c : l.contacts)
    if (c.sphere) c.k = c.sphere->contactStiffness() * stiffness_ / (s.contactDistance + c.sphere->radius());
}

void SurfaceCollisionModel::addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const {
  Live& l = stateIn<Live>(s);
  if (!l.penalty) return;
  for (Contact& c : l.contacts) {
    // Between two integrated bodies the force is SOFA's: computed once where the step starts and
    // held over the step (an external force for each body's solver); otherwise it follows x.
    const double g = explicitPair(c) ? c.gap0 : c.gap(x);
    c.active = g < 0;
    if (!c.active) continue;
    const Eigen::Vector3d fc = c.k * g * c.n;
    for (int k = 0; k < c.count; ++k) f.col(c.nodes[k]) += c.w[k] * fc;
  }
}

void SurfaceCollisionModel::addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const {
  const Live& l = stateIn<Live>(s);
  if (!l.penalty) return;
  for (const Contact& c : l.contacts) {
    if (!c.active || explicitPair(c)) continue;
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (int k = 0; k < c.count; ++k) d += c.w[k] * dx.col(c.nodes[k]);
    const Eigen::Vector3d fc = -kFactor * c.k * c.n.dot(d) * c.n;
    for (int k = 0; k < c.count; ++k) df.col(c.nodes[k]) += c.w[k] * fc;
  }
}

void SurfaceCollisionModel::stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const {
  // Contacts couple at most the nodes of one boundary triangle; those pairs are fixed. On a mapped
  // surface, the body's nodes its vertices follow.
  if (vertexMap_.empty()) {
    for (const auto& e : edges_) pairs.emplace_back(e[0], e[1]);
    return;
  }
  std::set<std::pair<int, int>> unique;
  for (const auto& t : tris_) {
    std::vector<int> nodes;
    for (int v : t)
      for (const auto& [n, w] : vertexMap_[v]) nodes.push_back(n);
    for (size_t a = 0; a < nodes.size(); ++a)
      for (size_t b = a + 1; b < nodes.size(); ++b)
        if (nodes[a] != nodes[b]) unique.insert({std::min(nodes[a], nodes[b]), std::max(nodes[a], nodes[b])});
  }
  for (const auto& p : verts_)
    for (const auto& [a, wa] : vertexMap_[p])
      for (const auto& [b, wb] : vertexMap_[p])
        if (a < b) unique.insert({a, b});
  pairs.insert(pairs.end(), unique.begin(), unique.end());
}

void SurfaceCollisionModel::addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const {
  const Live& l = stateIn<Live>(s);
  if (!l.penalty) return;
  for (const Contact& c : l.contacts) {
    if (!c.active || explicitPair(c)) continue;
    const Eigen::Matrix3d nn = -kFactor * c.k * c.n * c.n.transpose();
    for (int a = 0; a < c.count; ++a)
      for (int b = 0; b < c.count; ++b) K.addSymmetric(c.nodes[a], c.nodes[b], c.w[a] * c.w[b] * nn);
  }
}

void SurfaceCollisionModel::finishPenalty(State& s, const Eigen::Matrix3Xd& x) const {
  for (Contact& c : stateIn<Live>(s).contacts)
    c.force = c.active ? Eigen::Vector3d(c.k * (explicitPair(c) ? c.gap0 : c.gap(x)) * c.n) : Eigen::Vector3d::Zero();
}

// ---------------------------------------------------------------------------------------------
// Intersection and response settings

void ProximityIntersection::init() {
  // DiscreteIntersection has no distances: contacts are the features that overlap a sphere.
  if (!spec().find("alarmDistance")) {
    alarmDistance = contactDistance = 0.0;
    return;
  }
  alarmDistance = attrs_.real("alarmDistance");
  contactDistance = attrs_.real("contactDistance");
  localMinDistance = attrs_.component() == "LocalMinDistance";  // an alias: the tag as written
  // SOFA calls its validity tests unless useLMDFilters hands them to another component.
  filter = attrs_.boolean("filterIntersection") && !attrs_.boolean("useLMDFilters");
  angleCone = attrs_.real("angleCone");
  coneFactor = attrs_.real("coneFactor");
  if (contactDistance > alarmDistance)
    throw error("contactDistance", "must not exceed alarmDistance (" + attrs_.get("alarmDistance").text + ")");
}

void CollisionResponse::init() {
  const std::string& r = attrs_.str("response");
  response = r == "FrictionContactConstraint" || r == "FrictionContact" || r == "UnilateralContactConstraint"
                 ? ContactSettings::Response::Constraint
                 : ContactSettings::Response::Penalty;
  // SOFA's FrictionContact has mu = 0.8 unless told otherwise; its unilateral contact no friction.
  if (response == ContactSettings::Response::Constraint && r != "UnilateralContactConstraint") mu = 0.8;
  // responseParams: "mu=0.9" (SOFA separates several with '&').
  const std::string& params = attrs_.str("responseParams");
  size_t pos = 0;
  while (pos < params.size()) {
    size_t amp = params.find('&', pos);
    std::string kv = params.substr(pos, amp == std::string::npos ? std::string::npos : amp - pos);
    pos = amp == std::string::npos ? params.size() : amp + 1;
    if (kv.empty()) continue;
    size_t eq = kv.find('=');
    std::string key = kv.substr(0, eq), val = eq == std::string::npos ? "" : kv.substr(eq + 1);
    if (key == "mu") {
      if (!parseNumber(val, mu) || !(mu >= 0) || !std::isfinite(mu))
        throw error("responseParams", "mu must be a number >= 0, got '" + val + "'");
    } else if (key == "tol" || key == "tolerance") {
      // accepted: the constraint solver's tolerance applies
    } else {
      throw error("responseParams", "unknown parameter '" + key + "' (known: mu)");
    }
  }
  if (attrs_.isSet("mu")) mu = attrs_.real("mu");
  if (r == "UnilateralContactConstraint" && mu > 0)
    throw error("responseParams", "UnilateralContactConstraint has no friction; use FrictionContactConstraint for mu > 0");
  if (response == ContactSettings::Response::Penalty && mu > 0)
    throw error("responseParams", "friction (mu) needs the constraint response: response=\"FrictionContactConstraint\"");
  // RuleBasedContactManager's rules: triplets "model model response" (a model by name, group
  // number or *). One response serves every contact here, so each rule must name it.
  if (attrs_.isSet("rules")) {
    std::istringstream in(attrs_.str("rules"));
    std::vector<std::string> t;
    for (std::string w; in >> w;) t.push_back(w);
    if (t.size() % 3 != 0) {
      scene().addNote(loc().str() + ": note: " + typeName() + ".rules '" + attrs_.str("rules") +
                      "' is not a list of (model, model, response) triplets: no rule applies and every contact takes "
                      "the default response, as in SOFA");
    } else {
      for (size_t i = 0; i < t.size(); i += 3)
        if (t[i + 2] != r)
          throw error("rules", "the rule '" + t[i] + " " + t[i + 1] + " " + t[i + 2] + "' asks for " + t[i + 2] +
                                   "; one response (" + r + ") serves every contact here");
    }
  }
}

// ---------------------------------------------------------------------------------------------
// CollisionPipeline

void CollisionPipeline::init() {
  if (scene().all<CollisionPipeline>().size() > 1)
    throw error("a scene has one collision pipeline; this is the second");
  // Intersection method and response: the components of those kinds in the pipeline's node.
  if (auto* ix = node().find<ProximityIntersection>()) {
    scene().initComponent(*ix);
    settings_.alarmDistance = ix->alarmDistance;
    settings_.contactDistance = ix->contactDistance;
    settings_.localMinDistance = ix->localMinDistance;
    settings_.filter = ix->filter;
    settings_.angleCone = ix->angleCone;
    settings_.coneFactor = ix->coneFactor;
  } else {
    scene().addNote(loc().str() + ": note: no MinProximityIntersection/LocalMinDistance beside the pipeline: alarmDistance " +
                    std::to_string(settings_.alarmDistance) + ", contactDistance " + std::to_string(settings_.contactDistance));
  }
  if (auto* r = node().find<CollisionResponse>()) {
    scene().initComponent(*r);
    settings_.response = r->response;
    settings_.mu = r->mu;
  }
  for (SphereCollisionModel* s : scene().all<SphereCollisionModel>()) {
    scene().initComponent(*s);
    spheres_.push_back(s);
  }
  std::map<const MechanicalObject*, SurfaceCollisionModel*> best;
  for (SurfaceCollisionModel* s : scene().all<SurfaceCollisionModel>()) {
    scene().initComponent(*s);
    surfaces_.push_back(s);
    auto [it, fresh] = best.try_emplace(&s->surfaceState(), s);
    if (!fresh && s->kind() > it->second->kind()) it->second = s;
  }
  for (SurfaceCollisionModel* s : surfaces_) {
    if (s->kind() == SurfaceCollisionModel::Kind::Lines) lines_.insert(&s->surfaceState());
    if (s->kind() == SurfaceCollisionModel::Kind::Points) points_.insert(&s->surfaceState());
    SurfaceCollisionModel* b = best[&s->surfaceState()];
    s->setActive(s == b);
    if (s != b)
      scene().addNote(s->loc().str() + ": note: " + s->typeName() + " '" + s->name() + "' is covered by " + b->typeName() +
                      " '" + b->name() + "' on the same body (its edges and vertices are contact features too)");
  }
  if (settings_.localMinDistance)
    for (size_t i = 0; i < surfaces_.size(); ++i)
      for (size_t j = i + 1; j < surfaces_.size(); ++j) {
        const SurfaceCollisionModel *a = surfaces_[i], *b = surfaces_[j];
        if (!a->active() || !b->active() || a->body() == b->body() || (a->isStatic() && b->isStatic())) continue;
        const std::string pair = "'" + a->name() + "' (" + a->node().path() + ") and '" + b->name() + "' (" + b->node().path() + ")";
        if (a->kind() != SurfaceCollisionModel::Kind::Triangles || b->kind() != SurfaceCollisionModel::Kind::Triangles) {
          scene().addNote(loc().str() + ": note: LocalMinDistance between " + pair + ": one has no TriangleCollisionModel, "
                          "so their contacts are Viscera's vertex-against-feature set, not LocalMinDistance's");
          continue;
        }
        const bool pa = points_.count(&a->surfaceState()), pb = points_.count(&b->surfaceState());
        const bool la = lines_.count(&a->surfaceState()), lb = lines_.count(&b->surfaceState());
        if (!pa && !pb && !(la && lb))
          scene().addNote(loc().str() + ": note: LocalMinDistance tests nothing between " + pair + ": it ignores triangle "
                          "against triangle and triangle against line (as SOFA's); add a PointCollisionModel beside a "
                          "surface for its vertices to touch the other");
      }
  // Spheres on a deformable body's nodes can only touch another deformable body, which is not
  // handled: accept them where there is nothing for them to touch.
  nodeSpheres_ = scene().all<NodeSphereCollisionModel>();
  for (NodeSphereCollisionModel* ns : nodeSpheres_) scene().initComponent(*ns);
  if (!nodeSpheres_.empty()) {
    const NodeSphereCollisionModel& ns = *nodeSpheres_.front();
    const size_t others = spheres_.size() + surfaces_.size();
    if (others > 0)
      throw ns.error("puts spheres on the nodes of the deformable body '" + ns.mstate().name() +
                     "'; contact between deformable bodies is not handled (Viscera's contacts are rigid spheres "
                     "against tissue surfaces), and this scene has " + std::to_string(others) + " instrument or surface "
                     "collision model(s)");
    scene().addNote(ns.loc().str() + ": note: " + std::to_string(nodeSpheres_.size()) +
                    " sphere model(s) on deformable bodies and no other collision model: a model does not collide "
                    "with itself, and the run stops if spheres of two bodies touch (contact between deformable "
                    "bodies is not handled)");
    return;
  }
  // Surfaces of two bodies that are not both fixed can meet.
  bool pairs = false;
  for (const SurfaceCollisionModel* a : surfaces_)
    for (const SurfaceCollisionModel* b : surfaces_)
      pairs = pairs || (a->active() && b->active() && a->body() != b->body() && !(a->isStatic() && b->isStatic()));
  if ((spheres_.empty() || surfaces_.empty()) && !pairs) {
    // Nothing can touch (as SOFA's models without a partner or self-collision): no response to set up.
    scene().addNote(loc().str() + ": note: CollisionPipeline has " + std::to_string(spheres_.size()) + " sphere and " +
                    std::to_string(surfaces_.size()) + " surface collision models: no contact can occur");
    return;
  }
  if (pairs && settings_.response == ContactSettings::Response::Penalty)
    for (const SurfaceCollisionModel* s : surfaces_)
      if (!(settings_.contactDistance + s->ownContactDistance() > 0))
        throw s->error("meets another body's surface under the penalty response, whose stiffness is SOFA's k1 k2 / "
                       "contactDistance: give the intersection (or this model) a contactDistance above 0");
  if (settings_.response == ContactSettings::Response::Penalty) {
    for (SurfaceCollisionModel* s : surfaces_)
      if (s->active() && s->contactStiffness() == 0)
        scene().addNote(s->loc().str() + ": note: " + s->typeName() + " '" + s->name() +
                        "' has contactStiffness 0: its penalty contacts push with no force");
  } else if (scene().all<ConstraintSolver>().empty()) {
    throw error("the constraint contact response needs FreeMotionAnimationLoop and GenericConstraintSolver in the root node");
  }
}

std::optional<Diverged> CollisionPipeline::detect(State& s, int stepIndex, double t) const {
  // Spheres on different deformable bodies must stay apart (within contactDistance they would touch).
  for (size_t a = 0; a < nodeSpheres_.size(); ++a)
    for (size_t b = a + 1; b < nodeSpheres_.size(); ++b) {
      const NodeSphereCollisionModel &A = *nodeSpheres_[a], &B = *nodeSpheres_[b];
      if (&A.mstate() == &B.mstate()) continue;
      for (int i = 0; i < A.mstate().size(); ++i)
        for (int j = 0; j < B.mstate().size(); ++j)
          if ((A.mstate().x(s).col(i) - B.mstate().x(s).col(j)).norm() <
              A.radii()[i] + B.radii()[j] + settings_.contactDistance) {
            Diverged d;
            d.step = stepIndex;
            d.time = t;
            d.reason = "spheres of '" + A.name() + "' and '" + B.name() +
                       "' touch: contact between deformable bodies is not handled";
            d.object = A.mstate().name();
            d.nodes = {i};
            return d;
          }
    }
  // Each surface's contacts: with the instruments' spheres, then with the vertices of other bodies'
  // surfaces (both ways, as SOFA's point-triangle tests).
  std::vector<std::vector<Contact>> found(surfaces_.size());
  std::vector<ContactSettings> own(surfaces_.size(), settings_);
  for (size_t i = 0; i < surfaces_.size(); ++i) {
    const SurfaceCollisionModel* m = surfaces_[i];
    if (!m->active()) continue;
    // Broad phase: the hierarchy follows the surface once per step; each sphere then visits only
    // the triangles its inflated box touches.
    m->refit(s, m->surfacePositions(s));
    // A model's own contactDistance widens its contacts' (SOFA adds the models' to the intersection's).
    own[i].contactDistance += m->ownContactDistance();
    own[i].alarmDistance += m->ownContactDistance();
    for (const SphereCollisionModel* sp : spheres_)
      if (&sp->body() != m->rigidBody()) m->detect(s, *sp, m->surfacePositions(s), own[i], found[i]);  // not its own body's
    if (m->rigidBody() && !found[i].empty()) {
      Diverged bad;
      bad.step = stepIndex;
      bad.time = t;
      bad.reason = "the sphere '" + found[i].front().sphere->name() + "' touches the surface '" + m->name() + "' (" +
                   m->node().path() + ") of rigid body '" + m->rigidBody()->name() +
                   "': contact of an instrument with a rigid body is not handled (only with deformable surfaces)";
      bad.object = m->rigidBody()->name();
      return bad;
    }
  }
  for (size_t i = 0; i < surfaces_.size(); ++i)
    for (size_t j = 0; j < surfaces_.size(); ++j) {
      const SurfaceCollisionModel *a = surfaces_[i], *b = surfaces_[j];
      if (a == b || !a->active() || !b->active() || a->body() == b->body() || (a->isStatic() && b->isStatic())) continue;
      // The vertices of b against the features of a (penalty forces on both, or a constraint pair).
      ContactSettings pair = settings_;
      pair.contactDistance += a->ownContactDistance() + b->ownContactDistance();
      pair.alarmDistance += a->ownContactDistance() + b->ownContactDistance();
      if (settings_.localMinDistance && a->kind() == SurfaceCollisionModel::Kind::Triangles &&
          b->kind() == SurfaceCollisionModel::Kind::Triangles) {
        auto features = [&](const SurfaceCollisionModel* m) {
          return SurfaceCollisionModel::Features{lines_.count(&m->surfaceState()) > 0, points_.count(&m->surfaceState()) > 0};
        };
        if (i < j) a->detectLocalMinDistance(s, *b, pair, features(a), features(b), found[i], found[j]);
        continue;
      }
      a->detectVertices(s, *b, pair, found[i], found[j]);
      if (i < j && lines_.count(&a->surfaceState()) && lines_.count(&b->surfaceState()))
        a->detectEdges(s, *b, pair, found[i], found[j]);
    }
  for (size_t i = 0; i < surfaces_.size(); ++i)
    if (surfaces_[i]->active()) surfaces_[i]->setContacts(s, std::move(found[i]), own[i]);
  return std::nullopt;
}

void CollisionPipeline::finish(State& st) const {
  for (const SphereCollisionModel* sp : spheres_) {
    RigidObject::Live& b = sp->body().live(st);
    b.force.setZero();
    b.torque.setZero();
    b.contacts = 0;
  }
  int total = 0;
  for (const SurfaceCollisionModel* s : surfaces_) {
    if (!s->active()) continue;
    if (settings_.response == ContactSettings::Response::Penalty) s->finishPenalty(st, s->mstate().x(st));
    for (const Contact& c : s->contacts(st)) {
      if (c.force.squaredNorm() == 0) continue;
      ++total;
      if (!c.sphere) continue;  // between two bodies: each side holds its own
      RigidObject::Live& b = c.sphere->body().live(st);
      const Eigen::Vector3d onBody = -c.force;
      const Eigen::Vector3d at = c.sphere->centre(st) - c.sphere->radius() * c.n;  // contact point on the sphere
      b.force += onBody;
      b.torque += (at - b.p).cross(onBody);
      ++b.contacts;
    }
  }
  Live& l = stateIn<Live>(st);
  l.maxContacts = std::max(l.maxContacts, total);
  // Penetration of the vertices into the spheres (not the contact distance: the sphere itself).
  l.lastPenetration = -1e300;
  for (const SurfaceCollisionModel* s : surfaces_) {
    for (const SphereCollisionModel* sp : spheres_) {
      if (&sp->body() == s->rigidBody()) continue;  // a body's own sphere sits inside its surface
      const Eigen::Vector3d c = sp->centre(st);
      const double R = sp->radius();
      for (int v : s->vertices()) l.lastPenetration = std::max(l.lastPenetration, R - (s->vertexPosition(st, v) - c).norm());
    }
  }
  l.maxPenetration = std::max(l.maxPenetration, l.lastPenetration);
}

int CollisionPipeline::heldContacts(const State& st, const Node& under, double& largestStiffness) const {
  auto below = [&](const SurfaceCollisionModel* s) {
    for (const Node* n = s->rigidBody() ? &s->rigidBody()->node() : &s->mstate().node(); n; n = n->parent())
      if (n == &under) return true;
    return false;
  };
  int n = 0;
  largestStiffness = 0;
  for (const SurfaceCollisionModel* s : surfaces_)
    if (s->active())
      for (const Contact& c : s->contacts(st))
        if (c.gap0 < 0 && SurfaceCollisionModel::explicitPair(c) && std::less<>{}(s, c.partner) &&  // each pair once
            (below(s) || below(c.partner))) {
          ++n;
          largestStiffness = std::max(largestStiffness, c.k);
        }
  return n;
}

int CollisionPipeline::contactCount(const State& st) const {
  int n = 0;
  for (const SurfaceCollisionModel* s : surfaces_)
    if (s->active())
      for (const Contact& c : s->contacts(st)) n += c.force.squaredNorm() > 0;
  return n;
}

}  // namespace viscera
