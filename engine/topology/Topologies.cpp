// Topologies: regular and sparse grids, the tetrahedron, triangle and quad containers, SOFA's general
// MeshTopology, the topological mappings that fill them, and the mesh, surface and sphere loaders.
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <set>
#include <sstream>

#include "core/Registry.h"
#include "core/Text.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/topology/GridSplit.h"
#include "engine/topology/SurfaceFile.h"
#include "io/mesh/Spheres.h"
#include "io/mesh/Mesh.h"
#include "io/scene/InputCache.h"
#include "io/surface/SurfaceMesh.h"

namespace viscera {

namespace {

// The most nodes a RegularGridTopology may have (about 20 GB of state and stiffness at ~2 kB a
// node): a limit against typing mistakes, far above any tissue model run here.
constexpr long long kMaxGridNodes = 10'000'000;

const TetList kNoTets;

class RegularGridTopology : public Component, public Topology {
 public:
  using Component::Component;
  void init() override {
    auto n = attrs_.ints("n");
    // Counted in 64 bits before anything is allocated: a grid's node count overflows an int long
    // before memory runs out, and memory runs out long before an int overflows.
    const long double nodes = static_cast<long double>(n[0]) * n[1] * n[2];
    if (nodes > kMaxGridNodes) {
      std::ostringstream m;
      m << "n = " << n[0] << " " << n[1] << " " << n[2] << " makes " << static_cast<double>(nodes)
        << " nodes (about " << static_cast<double>(nodes) * 2e3 / 1e9
        << " GB for their state and stiffness); a grid may have at most " << kMaxGridNodes << " nodes";
      throw error("n", m.str());
    }
    for (int a = 0; a < 3; ++a) n_[a] = n[a];
    hexa_ = gridHexahedra(n_);
    if (typeName() != "RegularGridTopology") return roundGrid();
    const auto& lo = attrs_.reals("min");
    const auto& hi = attrs_.reals("max");
    Eigen::Vector3d p0;
    if (attrs_.isSet("p0")) p0 = Eigen::Vector3d(attrs_.reals("p0")[0], attrs_.reals("p0")[1], attrs_.reals("p0")[2]);
    points_ = gridPoints(n_, Eigen::Vector3d(lo[0], lo[1], lo[2]), Eigen::Vector3d(hi[0], hi[1], hi[2]),
                         attrs_.isSet("p0") ? &p0 : nullptr);
    // A grid one node thick along one axis is SOFA's two-dimensional grid: its cells are quads.
    const int flat = n_[0] == 1 ? 0 : n_[1] == 1 ? 1 : n_[2] == 1 ? 2 : -1;
    if (flat >= 0 && n_[(flat + 1) % 3] > 1 && n_[(flat + 2) % 3] > 1) {
      const int a = flat == 0 ? 1 : 0, b = flat == 2 ? 1 : 2;
      auto id = [&](int i, int j) {
        std::array<int, 3> c{0, 0, 0};
        c[a] = i, c[b] = j;
        return c[0] + n_[0] * (c[1] + n_[1] * c[2]);
      };
      for (int j = 0; j + 1 < n_[b]; ++j)
        for (int i = 0; i + 1 < n_[a]; ++i)
          for (int v : {id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)}) quads_.push_back(v);
    }
    if (attrs_.isSet("position")) {
      // SOFA's scenes link the grid's positions to the state's (position="@dofs.position") so
      // that a MechanicalObject without positions takes the grid's; that is what happens here.
      const AttrValue& v = attrs_.get("position");
      Component& target = scene().resolve(*this, v.text, v.loc, "RegularGridTopology.position");
      const auto dot = v.text.rfind('.');
      if (!dynamic_cast<MechanicalObject*>(&target) || &target.node() != &node() || dot == std::string::npos ||
          v.text.substr(dot + 1) != "position" || target.attrs().get("position").set)
        throw error("position", "only a link to the positions of this node's MechanicalObject, which has none of its "
                                "own, is accepted (the grid gives it its positions)");
    }
  }
  const Eigen::Matrix3Xd& points() const override { return points_; }
  const TetList& tetrahedra() const override { return kNoTets; }
  const HexList& hexahedra() const override { return hexa_; }
  std::array<int, 3> gridCells() const override {
    return {std::max(n_[0] - 1, 1), std::max(n_[1] - 1, 1), std::max(n_[2] - 1, 1)};
  }

 private:
  // SOFA's CylinderGridTopology and SphereGridTopology: the grid's square cross-section (or cube)
  // of half-width r pushed onto the circle (sphere) through its centre, each point scaled by
  // max(|p_i|) / |p|; the cylinder's third index runs along the axis over its length.
  void roundGrid() {
    const bool sphere = typeName() == "SphereGridTopology";
    for (int a = 0; a < (sphere ? 3 : 2); ++a)
      if (n_[a] < 2) throw error("n", "needs at least 2 nodes across (axis " + std::to_string(a) + ")");
    const auto& ax = attrs_.reals("axis");
    Eigen::Vector3d z(ax[0], ax[1], ax[2]);
    if (!(z.norm() > 0)) throw error("axis", "must not be zero");
    z.normalize();
    // SOFA takes x across the axis, y when the axis is x (either way along it here).
    Eigen::Vector3d x = std::abs(z.x()) > 1 - 1e-6 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitX();
    const Eigen::Vector3d y = z.cross(x).normalized();
    x = y.cross(z).normalized();
    const double r = attrs_.real("radius");
    const auto& c = attrs_.reals("center");
    const Eigen::Vector3d centre(c[0], c[1], c[2]);
    points_.resize(3, static_cast<Eigen::Index>(n_[0]) * n_[1] * n_[2]);
    for (int k = 0; k < n_[2]; ++k)
      for (int j = 0; j < n_[1]; ++j)
        for (int i = 0; i < n_[0]; ++i) {
          Eigen::Vector3d p(i * 2 * r / (n_[0] - 1) - r, j * 2 * r / (n_[1] - 1) - r, 0);
          if (sphere) p.z() = k * 2 * r / (n_[2] - 1) - r;
          if (p.norm() > 1e-7) p *= p.cwiseAbs().maxCoeff() / p.norm();
          if (!sphere && n_[2] > 1) p.z() = k * attrs_.real("length") / (n_[2] - 1);
          points_.col(i + n_[0] * (j + n_[1] * k)) = centre + x * p.x() + y * p.y() + z * p.z();
        }
  }

 public:
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "position") out.values.assign(points_.data(), points_.data() + points_.size());
    else if (name == "quads" && !quads_.empty()) out.values.assign(quads_.begin(), quads_.end());
    else return false;
    return true;
  }

 private:
  std::array<int, 3> n_{};
  Eigen::Matrix3Xd points_;
  HexList hexa_;
  std::vector<double> quads_;  // a flat grid's cells, four nodes each
};

// Initialises the topological mappings that fill `container`, so that it holds their elements
// before anything reads it.
void initFillersOf(Component& container) {
  for (auto* m : container.scene().all<TopologyFiller>())
    if (m->fills(container)) container.scene().initComponent(dynamic_cast<Component&>(*m));
}

// A topological mapping: writes the elements it derives from `input` into the container `output`.
class TopologicalMapping : public Component, public TopologyFiller {
 public:
  using Component::Component;
  bool fills(const Component& c) const override { return attrs_.get("output").set && &output() == &c; }

 protected:
  Component& output() const {
    const AttrValue& o = attrs_.get("output");
    return scene().resolve(*this, o.text, o.loc, typeName() + ".output");
  }
};

// A container a topological mapping writes tetrahedra into.
class TetrahedraSink {
 public:
  virtual ~TetrahedraSink() = default;
  virtual void fill(const TetList& t) = 0;
};

class TetrahedronSetTopologyContainer : public Component, public Topology, public TetrahedraSink {
 public:
  using Component::Component;
  void init() override {
    initFillersOf(*this);  // a topological mapping may fill this container
    // Filled, it keeps the mapping's tetrahedra; its points may still come from `position`.
    if (!filled_ && attrs_.isSet("src")) {
      auto* t = dynamic_cast<Topology*>(linkedComponent("src"));
      if (!t) throw error("src", "does not link to a loader or topology");
      points_ = t->points();
      tets_ = t->tetrahedra();
    }
    if (attrs_.isSet("position")) {
      auto p = linkedReals("position");
      points_ = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, p.size() / 3);
    }
    if (filled_) return;
    if (attrs_.isSet("tetrahedra")) {
      auto t = linkedInts("tetrahedra");
      tets_ = Eigen::Map<const TetList>(t.data(), 4, t.size() / 4);
    }
    if (tets_.cols() > 0 && points_.cols() > 0) {
      io::VolumeMesh m;
      m.points = points_;
      m.tets = tets_;
      try {
        io::checkTetMesh(m, name());
      } catch (const Error& e) {
        throw error(e.what());
      }
    }
  }
  void fill(const TetList& t) override {
    tets_ = t;
    filled_ = true;
  }
  const Eigen::Matrix3Xd& points() const override { return points_; }
  const TetList& tetrahedra() const override { return tets_; }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "position") out.values.assign(points_.data(), points_.data() + points_.size());
    else if (name == "tetrahedra") out.values.assign(tets_.data(), tets_.data() + tets_.size());
    else return false;
    return true;
  }

 private:
  Eigen::Matrix3Xd points_;
  TetList tets_;
  bool filled_ = false;
};

// Faces of a surface, K corners each (triangles or quads): from a loader (`src`), explicit lists,
// or a topological mapping (the boundary of a volume: SOFA's collision and visual surfaces). It
// carries no tetrahedra, so components that need a volume look past it.
template <int K>
class SurfaceSetContainer : public Component, public Topology {
 public:
  using Faces = Eigen::Matrix<int, K, Eigen::Dynamic>;
  using Component::Component;
  static const char* facesName() { return K == 3 ? "triangles" : "quads"; }
  void init() override {
    initFillersOf(*this);
    if (filled_) return;
    if constexpr (K == 3) {
      if (attrs_.isSet("fileTopology") && !attrs_.str("fileTopology").empty()) {
        const auto surface = readSurfaceAttribute(*this, "fileTopology");
        points_ = surface->points;
        faces_ = surface->triangles;
      }
    }
    if (attrs_.isSet("src")) {
      auto* c = linkedComponent("src");
      FieldValue p, f;
      if (!c || !c->field("position", p)) throw error("src", "does not link to a loader or topology with positions");
      points_ = Eigen::Map<const Eigen::Matrix3Xd>(p.values.data(), 3, static_cast<Eigen::Index>(p.values.size() / 3));
      if (c->field(facesName(), f)) setFaces(f.values);
    }
    if (attrs_.isSet("position")) {
      auto p = linkedReals("position");
      points_ = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, static_cast<Eigen::Index>(p.size() / 3));
    }
    if (attrs_.isSet(facesName())) {
      auto t = linkedInts(facesName());
      setFaces(std::vector<double>(t.begin(), t.end()));
    }
    // Without points of its own the faces index the body's nodes (checked where they are used).
    for (Eigen::Index i = 0; i < faces_.size(); ++i)
      if (points_.cols() > 0 && faces_.data()[i] >= points_.cols())
        throw error(facesName(), "refer to node " + std::to_string(faces_.data()[i]) + ", but there are " +
                                     std::to_string(points_.cols()) + " points");
  }
  void fill(const Eigen::Matrix3Xd& points, const Faces& faces) {
    points_ = points;
    faces_ = faces;
    filled_ = true;
  }
  const Eigen::Matrix3Xd& points() const override { return points_; }
  const TetList& tetrahedra() const override { return kNoTets; }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "position") out.values.assign(points_.data(), points_.data() + points_.size());
    else if (name == facesName()) out.values.assign(faces_.data(), faces_.data() + faces_.size());
    else return false;
    return true;
  }

 private:
  void setFaces(const std::vector<double>& v) {
    faces_.resize(K, static_cast<Eigen::Index>(v.size() / K));
    for (size_t i = 0; i < K * static_cast<size_t>(faces_.cols()); ++i) {
      if (!(v[i] >= 0 && v[i] < 2147483647.0)) throw error(facesName(), "node index " + formatNumber(v[i]) + " is out of range");
      faces_.data()[i] = static_cast<int>(v[i]);
    }
  }
  Eigen::Matrix3Xd points_;
  Faces faces_;
  bool filled_ = false;
};
using TriangleSetTopologyContainer = SurfaceSetContainer<3>;
using QuadSetTopologyContainer = SurfaceSetContainer<4>;

// Writes the boundary triangles of a tetrahedral topology (outward, as io::boundaryTriangles) into
// a TriangleSetTopologyContainer: SOFA's way of giving a volume its collision or visual surface.
class Tetra2TriangleTopologicalMapping : public TopologicalMapping {
 public:
  using TopologicalMapping::TopologicalMapping;
  void init() override {
    auto* in = dynamic_cast<Topology*>(linkedComponent("input"));
    if (!in) throw error("input", "does not link to a topology");
    scene().initComponent(dynamic_cast<Component&>(*in));
    if (in->tetrahedra().cols() == 0) throw error("input", "links to a topology without tetrahedra");
    auto* out = dynamic_cast<TriangleSetTopologyContainer*>(&output());
    if (!out) throw error("output", "does not link to a TriangleSetTopologyContainer");
    // A container filled by a mapping holds elements only: the points are the body's rest positions.
    const Eigen::Matrix3Xd points = in->points().cols() > 0 ? in->points() : contextState(*this).x0;
    const TetList& T = in->tetrahedra();
    if (T.maxCoeff() >= points.cols() || T.minCoeff() < 0)
      throw error("input", "has tetrahedra that refer to node " + std::to_string(T.maxCoeff()) + ", but there are " +
                               std::to_string(points.cols()) + " points");
    io::TriangleList tris = io::boundaryTriangles(T, points);
    if (attrs_.boolean("flipNormals")) tris.row(1).swap(tris.row(2));
    out->fill(points, tris);
  }
};

// Writes the boundary quads of a hexahedral topology (a grid) into a QuadSetTopologyContainer.
class Hexa2QuadTopologicalMapping : public TopologicalMapping {
 public:
  using TopologicalMapping::TopologicalMapping;
  void init() override {
    auto* in = dynamic_cast<Topology*>(linkedComponent("input"));
    if (!in || in->hexahedra().empty()) throw error("input", "does not link to a topology with hexahedra");
    auto* out = dynamic_cast<QuadSetTopologyContainer*>(&output());
    if (!out) throw error("output", "does not link to a QuadSetTopologyContainer");
    const Eigen::Matrix3Xd points = in->points().cols() > 0 ? in->points() : contextState(*this).x0;
    for (const auto& h : in->hexahedra())
      for (int v : h)
        if (v < 0 || v >= points.cols())
          throw error("input", "has hexahedra that refer to node " + std::to_string(v) + ", but there are " +
                                   std::to_string(points.cols()) + " points");
    Eigen::Matrix<int, 4, Eigen::Dynamic> quads = hexahedronBoundaryQuads(in->hexahedra(), points);
    if (attrs_.boolean("flipNormals")) quads.row(1).swap(quads.row(3));
    out->fill(points, quads);
  }
};

// Writes the quads of a QuadSetTopologyContainer as two triangles each, (a b c) and (a c d), into a
// TriangleSetTopologyContainer (SOFA's split).
class Quad2TriangleTopologicalMapping : public TopologicalMapping {
 public:
  using TopologicalMapping::TopologicalMapping;
  void init() override {
    auto* in = dynamic_cast<QuadSetTopologyContainer*>(linkedComponent("input"));
    if (!in) throw error("input", "does not link to a QuadSetTopologyContainer");
    auto* out = dynamic_cast<TriangleSetTopologyContainer*>(&output());
    if (!out) throw error("output", "does not link to a TriangleSetTopologyContainer");
    FieldValue q;
    in->field("quads", q);
    io::TriangleList tris(3, static_cast<Eigen::Index>(q.values.size() / 4 * 2));
    for (Eigen::Index k = 0; 4 * k + 3 < static_cast<Eigen::Index>(q.values.size()); ++k) {
      const auto v = [&](int i) { return static_cast<int>(q.values[4 * k + i]); };
      tris.col(2 * k) << v(0), v(1), v(2);
      tris.col(2 * k + 1) << v(0), v(2), v(3);
    }
    const Eigen::Matrix3Xd points = in->points().cols() > 0 ? in->points() : contextState(*this).x0;
    if (tris.size() && tris.maxCoeff() >= points.cols())
      throw error("input", "has quads that refer to node " + std::to_string(tris.maxCoeff()) + ", but there are " +
                               std::to_string(points.cols()) + " points");
    out->fill(points, tris);
  }
};

class Hexa2TetraTopologicalMapping : public TopologicalMapping {
 public:
  using TopologicalMapping::TopologicalMapping;
  void init() override {
    // The input: a topology, or (SOFA's "@../") a node whose topology has hexahedra.
    Topology* in = nullptr;
    const LinkTarget target = linkTarget(*this, "input");
    if (target.node) {
      for (const auto& c : target.node->components())
        if (auto* t = dynamic_cast<Topology*>(c.get())) {
          scene().initComponent(*c);
          if (!t->hexahedra().empty()) in = t;
        }
    } else {
      scene().initComponent(*target.component);
      in = dynamic_cast<Topology*>(target.component);
    }
    if (!in || in->hexahedra().empty()) throw error("input", "does not link to a topology with hexahedra");
    auto* out = dynamic_cast<TetrahedraSink*>(&output());
    if (!out) throw error("output", "does not link to a TetrahedronSetTopologyContainer or MeshTopology");
    auto cells = in->gridCells();
    // SOFA uses nx = 2, ny = 1 when the input is not a grid.
    if (cells[0] == 0) cells = {2, 1, 1};
    out->fill(splitHexahedra(in->hexahedra(), cells[0], cells[1], attrs_.boolean("swapping")));
  }
};

class MeshLoader : public Component, public Topology {
 public:
  using Component::Component;
  void init() override {
    std::string path = scene().resolvePath(attrs_.str("filename"));
    if (!std::filesystem::exists(path)) throw error("filename", "mesh file '" + path + "' does not exist");
    try {
      mesh_ = *io::cachedRead<io::VolumeMesh>(path, [](const std::string& p) {
        io::VolumeMesh m = io::readVolumeMesh(p);
        if (m.tets.cols() > 0) io::checkTetMesh(m, p);
        return m;
      });
    } catch (const Error& e) {
      throw error("filename", e.what());
    }
    applyPlacement(attrs_, mesh_.points);
    if (attrs_.boolean("flipNormals")) {
      mesh_.triangles.row(1).swap(mesh_.triangles.row(2));
      mesh_.quads.row(1).swap(mesh_.quads.row(3));
    }
    hexa_.resize(mesh_.hexahedra.cols());
    for (Eigen::Index e = 0; e < mesh_.hexahedra.cols(); ++e)
      for (int k = 0; k < 8; ++k) hexa_[e][k] = mesh_.hexahedra(k, e);
  }
  const Eigen::Matrix3Xd& points() const override { return mesh_.points; }
  const TetList& tetrahedra() const override { return mesh_.tets; }
  const HexList& hexahedra() const override { return hexa_; }
  bool field(const std::string& name, FieldValue& out) const override {
    auto put = [&](const auto& m) { out.values.assign(m.data(), m.data() + m.size()); };
    if (name == "position") put(mesh_.points);
    else if (name == "tetrahedra") put(mesh_.tets);
    else if (name == "triangles") put(mesh_.triangles);
    else if (name == "hexahedra") put(mesh_.hexahedra);
    else if (name == "quads") put(mesh_.quads);
    else return false;
    return true;
  }

 private:
  io::VolumeMesh mesh_;
  HexList hexa_;
};

class SurfaceLoader : public Component, public Topology {
 public:
  using Component::Component;
  void init() override {
    surface_ = *readSurfaceAttribute(*this, "filename");
    applyPlacement(attrs_, surface_.points);
    if (attrs_.boolean("flipNormals")) io::flipSurface(surface_);
  }
  const Eigen::Matrix3Xd& points() const override { return surface_.points; }
  const TetList& tetrahedra() const override { return kNoTets; }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "position") out.values.assign(surface_.points.data(), surface_.points.data() + surface_.points.size());
    else if (name == "triangles") out.values.assign(surface_.triangles.data(), surface_.triangles.data() + surface_.triangles.size());
    else return false;
    return true;
  }

 private:
  io::SurfaceMesh surface_;
};

// SOFA's GridMeshCreator: a grid of resolution[0] x resolution[1] points over the unit square
// (x fastest), cut into quads or triangles by trianglePattern (0: quads, 1: alternate diagonals,
// 2: upward, 3: downward, each SOFA's), with the edges of those faces, then placed like a loaded
// mesh. No tetrahedra: a surface for springs, triangle containers and visual models.
class GridMeshCreator : public Component, public Topology {
 public:
  using Component::Component;
  void init() override {
    const std::vector<int> res = attrs_.ints("resolution");
    const int nx = res[0], ny = res[1], pattern = static_cast<int>(attrs_.integer("trianglePattern"));
    if (nx < 2 || ny < 2) throw error("resolution", "needs at least 2 points in each direction");
    points_.resize(3, static_cast<Eigen::Index>(nx) * ny);
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) points_.col(y * nx + x) = Eigen::Vector3d(x / double(nx - 1), y / double(ny - 1), 0);
    applyPlacement(attrs_, points_);
    auto v = [&](int x, int y) { return y * nx + x; };
    std::set<std::array<int, 2>> edges;  // the first orientation met, in SOFA's order
    auto edge = [&](int a, int b) {
      if (!edges.count({b, a})) edges.insert({a, b});
    };
    auto triangle = [&](int a, int b, int c) {
      triangles_.insert(triangles_.end(), {a, b, c});
      edge(a, b), edge(b, c), edge(c, a);
    };
    for (int y = 0; y + 1 < ny; ++y)
      for (int x = 0; x + 1 < nx; ++x) {
        const bool up = pattern == 2 || (pattern == 1 && (x + y) % 2 == 0);
        if (pattern == 0) {
          quads_.insert(quads_.end(), {v(x, y), v(x + 1, y), v(x + 1, y + 1), v(x, y + 1)});
          edge(v(x, y), v(x + 1, y)), edge(v(x + 1, y), v(x + 1, y + 1));
          edge(v(x + 1, y + 1), v(x, y + 1)), edge(v(x, y + 1), v(x, y));
        } else if (up) {
          triangle(v(x, y), v(x + 1, y), v(x + 1, y + 1));
          triangle(v(x, y), v(x + 1, y + 1), v(x, y + 1));
        } else {
          triangle(v(x, y), v(x + 1, y), v(x, y + 1));
          triangle(v(x + 1, y), v(x + 1, y + 1), v(x, y + 1));
        }
      }
    for (const auto& e : edges) edges_.insert(edges_.end(), {e[0], e[1]});
  }
  const Eigen::Matrix3Xd& points() const override { return points_; }
  const TetList& tetrahedra() const override { return kNoTets; }
  bool field(const std::string& name, FieldValue& out) const override {
    auto put = [&](const std::vector<int>& list) { out.values.assign(list.begin(), list.end()); };
    if (name == "position") out.values.assign(points_.data(), points_.data() + points_.size());
    else if (name == "edges") put(edges_);
    else if (name == "triangles") put(triangles_);
    else if (name == "quads") put(quads_);
    else return false;
    return true;
  }

 private:
  Eigen::Matrix3Xd points_;
  std::vector<int> edges_, triangles_, quads_;
};

// Spheres from a .sph file: their centres (`position`) and radii (`listRadius`), for a
// MechanicalObject and a SphereCollisionModel beside it (SOFA links them with "@[-1].position").
class SphereLoader : public Component {
 public:
  using Component::Component;
  void init() override {
    const std::string path = scene().resolvePath(attrs_.str("filename"));
    if (!std::filesystem::exists(path)) throw error("filename", "sphere file '" + path + "' does not exist");
    try {
      spheres_ = *io::cachedRead<io::SphereSet>(path, [](const std::string& p) { return io::readSpheres(p); });
    } catch (const Error& e) {
      throw error("filename", e.what());
    }
    const auto& k = attrs_.reals("scale3d");
    if (k[0] != k[1] || k[1] != k[2])
      throw error("scale3d", "spheres stay spheres only under a uniform scale (one factor for x, y and z)");
    applyPlacement(attrs_, spheres_.centres);
    for (double& r : spheres_.radii) r *= std::abs(k[0]);
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "position") out.values.assign(spheres_.centres.data(), spheres_.centres.data() + spheres_.centres.size());
    else if (name == "listRadius") out.values = spheres_.radii;
    else return false;
    return true;
  }

 private:
  io::SphereSet spheres_;
};

// SOFA's MeshTopology (and HexahedronSetTopologyContainer): any of points, triangles, quads,
// tetrahedra and hexahedra, from a file, a loader or grid (`src`), or explicit lists.
class GeneralMeshTopology : public Component, public Topology, public TetrahedraSink {
 public:
  using Component::Component;
  void fill(const TetList& t) override {
    tets_ = t;
    filled_ = true;
  }
  void init() override {
    initFillersOf(*this);  // a topological mapping may write its tetrahedra
    if (filled_) {
      // The mapping's tetrahedra index the nodes of the body they were split from.
      if (attrs_.isSet("position")) {
        const auto p = linkedReals("position");
        points_ = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, static_cast<Eigen::Index>(p.size() / 3));
      }
      return;
    }
    if (spec().find("filename") && attrs_.isSet("filename")) readFile(scene().resolvePath(attrs_.str("filename")));
    if (attrs_.isSet("src")) {
      Component* c = linkedComponent("src");
      FieldValue f;
      if (auto* t = dynamic_cast<Topology*>(c)) {
        points_ = t->points();
        tets_ = t->tetrahedra();
        hexa_ = t->hexahedra();
      } else if (c->field("position", f)) {
        points_ = Eigen::Map<const Eigen::Matrix3Xd>(f.values.data(), 3, static_cast<Eigen::Index>(f.values.size() / 3));
      } else {
        throw error("src", "does not link to a loader or topology");
      }
      if (c->field("triangles", f)) tris_ = faces<3>("src", f.values);
      if (c->field("quads", f)) quads_ = faces<4>("src", f.values);
    }
    if (attrs_.isSet("position")) {
      const auto p = linkedReals("position");
      points_ = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, static_cast<Eigen::Index>(p.size() / 3));
    }
    if (spec().find("triangles") && attrs_.isSet("triangles")) tris_ = faces<3>("triangles", linkedReals("triangles"));
    if (spec().find("quads") && attrs_.isSet("quads")) quads_ = faces<4>("quads", linkedReals("quads"));
    if (spec().find("tetrahedra") && attrs_.isSet("tetrahedra")) tets_ = faces<4>("tetrahedra", linkedReals("tetrahedra"));
    if (attrs_.isSet("hexahedra")) {
      const auto h = faces<8>("hexahedra", linkedReals("hexahedra"));
      hexa_.resize(h.cols());
      for (Eigen::Index e = 0; e < h.cols(); ++e)
        for (int k = 0; k < 8; ++k) hexa_[e][k] = h(k, e);
    }
    if (points_.cols() > 0 && tets_.cols() > 0) {
      io::VolumeMesh m;
      m.points = points_;
      m.tets = tets_;
      try {
        io::checkTetMesh(m, name());
      } catch (const Error& e) {
        throw error(e.what());
      }
    }
  }
  const Eigen::Matrix3Xd& points() const override { return points_; }
  const TetList& tetrahedra() const override { return tets_; }
  const HexList& hexahedra() const override { return hexa_; }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "position") out.values.assign(points_.data(), points_.data() + points_.size());
    else if (name == "triangles" && tris_.cols() > 0) out.values.assign(tris_.data(), tris_.data() + tris_.size());
    else if (name == "quads" && quads_.cols() > 0) out.values.assign(quads_.data(), quads_.data() + quads_.size());
    else if (name == "tetrahedra") out.values.assign(tets_.data(), tets_.data() + tets_.size());
    else if (name == "hexahedra") {
      out.values.clear();
      for (const auto& h : hexa_) out.values.insert(out.values.end(), h.begin(), h.end());
    } else return false;
    return true;
  }

 private:
  template <int K>
  Eigen::Matrix<int, K, Eigen::Dynamic> faces(const std::string& attr, const std::vector<double>& v) const {
    if (v.size() % K) throw error(attr, "expects " + std::to_string(K) + " node indices per element, got " + std::to_string(v.size()) + " values");
    Eigen::Matrix<int, K, Eigen::Dynamic> f(K, static_cast<Eigen::Index>(v.size() / K));
    for (size_t i = 0; i < v.size(); ++i) {
      if (!(v[i] >= 0 && v[i] < 2147483647.0) || v[i] != std::floor(v[i]))
        throw error(attr, "node index " + formatNumber(v[i]) + " is not a valid index");
      if (points_.cols() > 0 && v[i] >= points_.cols())
        throw error(attr, "refers to node " + formatNumber(v[i]) + ", but there are " + std::to_string(points_.cols()) + " points");
      f.data()[i] = static_cast<int>(v[i]);
    }
    return f;
  }
  void readFile(const std::string& path) {
    if (!std::filesystem::exists(path)) throw error("filename", "mesh file '" + path + "' does not exist");
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    try {
      if (ext == ".obj" || ext == ".stl" || ext == ".off" || ext == ".ply") {
        const auto surface = io::cachedRead<io::SurfaceMesh>(path, [](const std::string& p) { return io::readSurface(p); });
        points_ = surface->points;
        tris_ = surface->triangles;
      } else {
        const auto mesh = io::cachedRead<io::VolumeMesh>(path, [](const std::string& p) { return io::readVolumeMesh(p); });
        points_ = mesh->points;
        tets_ = mesh->tets;
        tris_ = mesh->triangles;
      }
    } catch (const Error& e) {
      throw error("filename", e.what());
    }
  }

  Eigen::Matrix3Xd points_;
  TetList tets_;
  HexList hexa_;
  Eigen::Matrix<int, 3, Eigen::Dynamic> tris_;
  Eigen::Matrix<int, 4, Eigen::Dynamic> quads_;
  bool filled_ = false;
};

// SOFA's SparseGridTopology: the cells of a regular grid over a closed surface's bounding box (grown
// by 1 % of its size on each side, as SOFA does) that the surface crosses or encloses, as
// hexahedra. A cell is on the boundary when a triangle meets it (separating-axis test), outside
// when it connects to the grid's border through cells the surface does not meet, inside otherwise.
// The plain grid is numbered as SOFA numbers it, so that indices in a SOFA scene name the same
// nodes: nodes are the kept cells' corners sorted by position (x, then y, then z); hexahedra are
// the boundary cells, then the inside cells, each in grid order. (The Ramification variant numbers
// its nodes by hexahedron; see ramified().)
class SparseGridTopology : public Component, public Topology {
 public:
  using Component::Component;
  void init() override {
    const io::SurfaceMesh& surface = *readSurfaceAttribute(*this, "fileTopology");
    const auto& nn = attrs_.ints("n");
    const std::array<int, 3> n{nn[0], nn[1], nn[2]};
    for (int a = 0; a < 3; ++a)
      if (n[a] < 2) throw error("n", "needs at least 2 nodes per axis (one cell)");
    if (static_cast<long double>(n[0]) * n[1] * n[2] > kMaxGridNodes) throw error("n", "makes more than " + std::to_string(kMaxGridNodes) + " nodes");
    const Eigen::Vector3d bbLo = surface.points.rowwise().minCoeff(), bbHi = surface.points.rowwise().maxCoeff();
    const Eigen::Vector3d lo = bbLo - (bbHi - bbLo) / 100, hi = bbHi + (bbHi - bbLo) / 100;
    const Eigen::Matrix3Xd grid = gridPoints(n, lo, hi);
    const HexList cells = gridHexahedra(n);
    if (typeName() == "SparseGridRamificationTopology") return ramified(surface, n, lo, hi, grid, cells);
    const std::vector<char> type = cellTypes(surface, {n[0] - 1, n[1] - 1, n[2] - 1}, lo, hi);
    // The kept cells' corners, numbered by position: grid node (i, j, k) in order of i, then j, then k.
    std::vector<int> newIndex(grid.cols(), -1);
    for (size_t e = 0; e < cells.size(); ++e)
      if (type[e] != Outside)
        for (int v : cells[e]) newIndex[v] = 0;
    int count = 0;
    for (int i = 0; i < n[0]; ++i)
      for (int j = 0; j < n[1]; ++j)
        for (int k = 0; k < n[2]; ++k)
          if (int& v = newIndex[static_cast<size_t>(i + n[0] * (j + n[1] * k))]; v == 0) v = count++;
    if (count == 0) throw error("fileTopology", "the surface encloses no cell of the grid");
    points_.resize(3, count);
    for (Eigen::Index v = 0; v < grid.cols(); ++v)
      if (newIndex[v] >= 0) points_.col(newIndex[v]) = grid.col(v);
    for (char kind : {Boundary, Inside})
      for (size_t e = 0; e < cells.size(); ++e)
        if (type[e] == kind) {
          std::array<int, 8> h{};
          for (int k = 0; k < 8; ++k) h[k] = newIndex[cells[e][k]];
          hexa_.push_back(h);
        }
  }
  const Eigen::Matrix3Xd& points() const override { return points_; }
  const TetList& tetrahedra() const override { return kNoTets; }
  const HexList& hexahedra() const override { return hexa_; }
  int partAt(const Eigen::Vector3d& p) const override {
    if (finePart_.empty()) return -1;
    std::array<int, 3> i{};
    for (int a = 0; a < 3; ++a)
      i[a] = std::clamp(static_cast<int>(std::floor((p[a] - fineLo_[a]) / fineStep_[a])), 0, fineCells_[a] - 1);
    return finePart_[static_cast<size_t>(i[0] + fineCells_[0] * (i[1] + fineCells_[1] * i[2]))];  // hexahedron = part
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "position") {
      out.values.assign(points_.data(), points_.data() + points_.size());
    } else if (name == "hexahedra") {
      out.values.clear();
      for (const auto& h : hexa_) out.values.insert(out.values.end(), h.begin(), h.end());
    } else {
      return false;
    }
    return true;
  }

 private:
  enum CellType : char { Inside, Boundary, Outside };

  // The cells of a grid of c cells per axis over [lo, hi], in grid order: those a triangle meets
  // are on the boundary, those cut off from the grid's border by them inside; the others are
  // flooded from the border cells the surface does not meet.
  static std::vector<char> cellTypes(const io::SurfaceMesh& surface, const std::array<int, 3>& c, const Eigen::Vector3d& lo,
                                     const Eigen::Vector3d& hi) {
    const Eigen::Vector3d step((hi - lo).cwiseQuotient(Eigen::Vector3d(c[0], c[1], c[2])));
    auto cellIndex = [&](int i, int j, int k) { return i + c[0] * (j + c[1] * k); };
    constexpr char Unknown = Inside;  // until the flood reaches it
    std::vector<char> type(static_cast<size_t>(c[0]) * c[1] * c[2], Unknown);
    for (Eigen::Index t = 0; t < surface.triangles.cols(); ++t) {
      const Eigen::Vector3d v0 = surface.points.col(surface.triangles(0, t)), v1 = surface.points.col(surface.triangles(1, t)),
                            v2 = surface.points.col(surface.triangles(2, t));
      const Eigen::Vector3d tlo = v0.cwiseMin(v1).cwiseMin(v2), thi = v0.cwiseMax(v1).cwiseMax(v2);
      std::array<int, 3> from{}, to{};
      for (int a = 0; a < 3; ++a) {
        from[a] = std::clamp(static_cast<int>(std::floor((tlo[a] - lo[a]) / step[a])) - 1, 0, c[a] - 1);
        to[a] = std::clamp(static_cast<int>(std::floor((thi[a] - lo[a]) / step[a])) + 1, 0, c[a] - 1);
      }
      for (int k = from[2]; k <= to[2]; ++k)
        for (int j = from[1]; j <= to[1]; ++j)
          for (int i = from[0]; i <= to[0]; ++i) {
            const Eigen::Vector3d cmin = lo + Eigen::Vector3d(i * step[0], j * step[1], k * step[2]);
            if (triangleMeetsBox(v0, v1, v2, cmin + 0.5 * step, 0.5 * step)) type[cellIndex(i, j, k)] = Boundary;
          }
    }
    std::vector<int> stack;
    for (int k = 0; k < c[2]; ++k)
      for (int j = 0; j < c[1]; ++j)
        for (int i = 0; i < c[0]; ++i)
          if ((i == 0 || j == 0 || k == 0 || i == c[0] - 1 || j == c[1] - 1 || k == c[2] - 1) && type[cellIndex(i, j, k)] == Unknown) {
            type[cellIndex(i, j, k)] = Outside;
            stack.push_back(cellIndex(i, j, k));
          }
    while (!stack.empty()) {
      const int id = stack.back();
      stack.pop_back();
      const int i = id % c[0], j = (id / c[0]) % c[1], k = id / (c[0] * c[1]);
      const int next[6][3] = {{i - 1, j, k}, {i + 1, j, k}, {i, j - 1, k}, {i, j + 1, k}, {i, j, k - 1}, {i, j, k + 1}};
      for (const auto& q : next) {
        if (q[0] < 0 || q[1] < 0 || q[2] < 0 || q[0] >= c[0] || q[1] >= c[1] || q[2] >= c[2]) continue;
        const int nid = cellIndex(q[0], q[1], q[2]);
        if (type[nid] != Unknown) continue;
        type[nid] = Outside;
        stack.push_back(nid);
      }
    }
    return type;
  }

  static std::vector<char> keptCells(const io::SurfaceMesh& surface, const std::array<int, 3>& c, const Eigen::Vector3d& lo,
                                     const Eigen::Vector3d& hi) {
    std::vector<char> kept = cellTypes(surface, c, lo, hi);
    for (char& k : kept) k = k != Outside;
    return kept;
  }

  // SOFA's SparseGridRamificationTopology: the surface is voxelised 2^L times finer (L =
  // nbVirtualFinerLevels); a coarse cell whose fine cells fall into several face-connected groups
  // is one hexahedron per group, and two hexahedra of neighbouring cells share the corners of
  // their common face, edge or corner only where their fine cells touch across it. Separate parts
  // of the shape that pass through one cell (the prongs of a fork) so stay separate.
  void ramified(const io::SurfaceMesh& surface, const std::array<int, 3>& n, const Eigen::Vector3d& lo,
                const Eigen::Vector3d& hi, const Eigen::Matrix3Xd& grid, const HexList& cells) {
    const int levels = static_cast<int>(attrs_.integer("nbVirtualFinerLevels"));
    if (attrs_.boolean("finestConnectivity"))
      throw error("finestConnectivity", "connectivity through the surface's triangles is not supported; set it to 0 "
                                        "(the fine cells' faces decide)");
    const int r = 1 << levels;
    const std::array<int, 3> c{n[0] - 1, n[1] - 1, n[2] - 1}, f{c[0] * r, c[1] * r, c[2] * r};
    if (static_cast<long double>(f[0]) * f[1] * f[2] > kMaxGridNodes)
      throw error("nbVirtualFinerLevels", "makes more than " + std::to_string(kMaxGridNodes) + " fine cells");
    const std::vector<char> fine = keptCells(surface, f, lo, hi);
    auto fineIndex = [&](int i, int j, int k) { return i + f[0] * (j + f[1] * k); };
    // Groups: per coarse cell, its kept fine cells by face-connected component.
    std::vector<int> group(fine.size(), -1);  // fine cell -> group
    std::vector<int> groupCell;                // group -> coarse cell
    for (int K = 0; K < c[2]; ++K)
      for (int J = 0; J < c[1]; ++J)
        for (int I = 0; I < c[0]; ++I)
          for (int a = 0; a < r * r * r; ++a) {
            const int i0 = I * r + a % r, j0 = J * r + (a / r) % r, k0 = K * r + a / (r * r);
            const int seed = fineIndex(i0, j0, k0);
            if (!fine[seed] || group[seed] >= 0) continue;
            const int g = static_cast<int>(groupCell.size());
            groupCell.push_back(I + c[0] * (J + c[1] * K));
            std::vector<std::array<int, 3>> stack{{i0, j0, k0}};
            group[seed] = g;
            while (!stack.empty()) {
              const auto q = stack.back();
              stack.pop_back();
              for (int d = 0; d < 6; ++d) {
                std::array<int, 3> p = q;
                p[d / 2] += d % 2 ? 1 : -1;
                if (p[0] < I * r || p[0] >= (I + 1) * r || p[1] < J * r || p[1] >= (J + 1) * r || p[2] < K * r || p[2] >= (K + 1) * r)
                  continue;
                const int id = fineIndex(p[0], p[1], p[2]);
                if (!fine[id] || group[id] >= 0) continue;
                group[id] = g;
                stack.push_back(p);
              }
            }
          }
    if (groupCell.empty()) throw error("fileTopology", "the surface encloses no cell of the grid");
    // What partAt needs: the fine grid and, for cells of several parts, each fine cell's part.
    std::vector<int> parts(static_cast<size_t>(c[0]) * c[1] * c[2], 0);
    for (int cell : groupCell) ++parts[static_cast<size_t>(cell)];
    fineLo_ = lo;
    fineStep_ = (hi - lo).cwiseQuotient(Eigen::Vector3d(f[0], f[1], f[2]));
    fineCells_ = f;
    finePart_.assign(fine.size(), -1);
    for (size_t e = 0; e < fine.size(); ++e)
      if (group[e] >= 0 && parts[static_cast<size_t>(groupCell[static_cast<size_t>(group[e])])] > 1) finePart_[e] = group[e];
    // Corner slots (group, corner) joined by union-find where fine cells of two groups touch
    // across the face, edge or corner their coarse cells share.
    std::vector<int> parent(groupCell.size() * 8);
    for (size_t k = 0; k < parent.size(); ++k) parent[k] = static_cast<int>(k);
    std::function<int(int)> root = [&](int x) { return parent[x] == x ? x : parent[x] = root(parent[x]); };
    // The offsets of a cell's corners, as gridHexahedra numbers them.
    static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    for (size_t a = 0; a < fine.size(); ++a) {
      if (!fine[a]) continue;
      const int ia = static_cast<int>(a % f[0]), ja = static_cast<int>((a / f[0]) % f[1]), ka = static_cast<int>(a / (f[0] * f[1]));
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int ib = ia + dx, jb = ja + dy, kb = ka + dz;
            if ((dx | dy | dz) == 0 || ib < 0 || jb < 0 || kb < 0 || ib >= f[0] || jb >= f[1] || kb >= f[2]) continue;
            const int b = fineIndex(ib, jb, kb);
            if (!fine[b] || group[b] <= group[a]) continue;
            const int ga = group[a], gb = group[b];
            const int ca = groupCell[ga], cb = groupCell[gb];
            if (ca == cb) continue;
            // Fine cells join their coarse cells' shared face, edge or corner when they touch
            // straight across it: their step is the coarse cells' offset.
            const std::array<int, 3> A{ca % c[0], (ca / c[0]) % c[1], ca / (c[0] * c[1])}, B{cb % c[0], (cb / c[0]) % c[1], cb / (c[0] * c[1])};
            if (B[0] - A[0] != dx || B[1] - A[1] != dy || B[2] - A[2] != dz) continue;
            // The shared corners: those of A at the side of B along every axis where they differ.
            for (int k = 0; k < 8; ++k) {
              bool shared = true;
              std::array<int, 3> other{};
              for (int ax = 0; ax < 3; ++ax) {
                const int d = B[ax] - A[ax];
                if (d != 0 && corner[k][ax] != (d > 0 ? 1 : 0)) shared = false;
                other[ax] = corner[k][ax] - d;
              }
              if (!shared) continue;
              int kb2 = 0;
              while (kb2 < 8 && !(corner[kb2][0] == other[0] && corner[kb2][1] == other[1] && corner[kb2][2] == other[2])) ++kb2;
              parent[root(8 * ga + k)] = root(8 * gb + kb2);
            }
          }
    }
    // Nodes: one per class of slots, at the grid corner the slots stand for.
    std::vector<int> node(parent.size(), -1);
    std::vector<int> position;  // node -> grid point
    for (size_t g = 0; g < groupCell.size(); ++g) {
      std::array<int, 8> h{};
      for (int k = 0; k < 8; ++k) {
        const int rt = root(static_cast<int>(8 * g + k));
        if (node[rt] < 0) {
          node[rt] = static_cast<int>(position.size());
          position.push_back(cells[static_cast<size_t>(groupCell[g])][k]);
        }
        h[k] = node[rt];
      }
      hexa_.push_back(h);
    }
    points_.resize(3, static_cast<Eigen::Index>(position.size()));
    for (size_t v = 0; v < position.size(); ++v) points_.col(static_cast<Eigen::Index>(v)) = grid.col(position[v]);
  }

  // Separating-axis test of a triangle against an axis-aligned box (centre, half sizes).
  static bool triangleMeetsBox(Eigen::Vector3d a, Eigen::Vector3d b, Eigen::Vector3d c, const Eigen::Vector3d& centre,
                               const Eigen::Vector3d& half) {
    a -= centre;
    b -= centre;
    c -= centre;
    const Eigen::Vector3d e[3] = {b - a, c - b, a - c};
    auto separated = [&](const Eigen::Vector3d& axis) {
      if (axis.squaredNorm() < 1e-30) return false;
      const double pa = a.dot(axis), pb = b.dot(axis), pc = c.dot(axis);
      const double r = half.x() * std::abs(axis.x()) + half.y() * std::abs(axis.y()) + half.z() * std::abs(axis.z());
      return std::min({pa, pb, pc}) > r || std::max({pa, pb, pc}) < -r;
    };
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (separated(Eigen::Vector3d::Unit(i).cross(e[j]))) return false;
    for (int i = 0; i < 3; ++i)
      if (separated(Eigen::Vector3d::Unit(i))) return false;
    return !separated(e[0].cross(e[1]));
  }

  Eigen::Matrix3Xd points_;
  HexList hexa_;
  // A ramified grid's fine cells (origin, size, counts) and, in cells of several parts, the
  // part (hexahedron) each fine cell belongs to; -1 elsewhere. Empty otherwise.
  Eigen::Vector3d fineLo_ = Eigen::Vector3d::Zero(), fineStep_ = Eigen::Vector3d::Ones();
  std::array<int, 3> fineCells_{};
  std::vector<int> finePart_;
};

// SOFA's PointSetTopologyContainer and EdgeSetTopologyContainer: points (from `src` or
// `position`) and, for the second, edges between them.
class PointEdgeContainer : public Component, public Topology {
 public:
  using Component::Component;
  void init() override {
    if (attrs_.isSet("src")) {
      FieldValue p, e;
      Component* c = linkedComponent("src");
      if (!c || !c->field("position", p)) throw error("src", "does not link to a loader or topology with positions");
      points_ = Eigen::Map<const Eigen::Matrix3Xd>(p.values.data(), 3, static_cast<Eigen::Index>(p.values.size() / 3));
      if (spec().find("edges") && c->field("edges", e)) edges_ = e.values;
    }
    if (attrs_.isSet("position")) {
      const auto p = linkedReals("position");
      points_ = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, static_cast<Eigen::Index>(p.size() / 3));
    }
    if (spec().find("edges") && attrs_.isSet("edges")) {
      const auto e = linkedInts("edges");
      edges_.assign(e.begin(), e.end());
    }
    for (double v : edges_)
      if (points_.cols() > 0 && v >= points_.cols())
        throw error("edges", "refer to node " + std::to_string(static_cast<int>(v)) + ", but there are " +
                                 std::to_string(points_.cols()) + " points");
  }
  const Eigen::Matrix3Xd& points() const override { return points_; }
  const TetList& tetrahedra() const override { return kNoTets; }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "position") out.values.assign(points_.data(), points_.data() + points_.size());
    else if (name == "edges" && !edges_.empty()) out.values = edges_;
    else return false;
    return true;
  }

 private:
  Eigen::Matrix3Xd points_;
  std::vector<double> edges_;  // node pairs
};

// What every mesh loader declares: the file, its placement and SOFA's normal flip.
void addLoaderAttributes(ComponentSpec& s) {
  s.add(AttrSpec::file("filename").req().help("mesh file, relative to the scene file or found along the data search path"));
  addPointPlacementAttributes(s, "the points");
  s.add(AttrSpec::boolean("flipNormals").def("false").help("reverse the orientation of the surface triangles"));
}

}  // namespace

void registerTopologies(Registry& r) {
  {
    ComponentSpec s;
    s.name = "RegularGridTopology";
    s.category = "topology";
    s.doc = "A regular grid of n[0] x n[1] x n[2] nodes over [min, max] (x fastest, then y, then z) and its hexahedra; "
            "a grid one node thick along one axis has quads (output field `quads`) instead.";
    s.add(AttrSpec::ints("n", 3).def("2 2 2").atLeast(1).help("nodes per axis (at most 10 million nodes in all)"));
    s.add(AttrSpec::reals("min", 3).def("0 0 0").unit(Dimension::length()).help("lower corner"));
    s.add(AttrSpec::reals("max", 3).def("1 1 1").unit(Dimension::length()).help("upper corner"));
    s.add(AttrSpec::reals("p0", 3).unit(Dimension::length()).help(
        "the first node, in place of `min` (SOFA's p0: the grid keeps the spacing of [min, max] and starts here)"));
    s.add(AttrSpec::link("position").help(
        "SOFA's link to the positions of the node's MechanicalObject (\"@dofs.position\"), which then takes the grid's"));
    s.factory = [](BuildContext& c) { return std::make_unique<RegularGridTopology>(c); };
    r.add(std::move(s));
  }
  for (const bool sphere : {false, true}) {
    ComponentSpec s;
    s.name = sphere ? "SphereGridTopology" : "CylinderGridTopology";
    s.category = "topology";
    s.doc = sphere ? "SOFA's sphere grid: a grid of n[0] x n[1] x n[2] nodes whose cube of half-width `radius` is pushed "
                     "onto the ball about `center` (each point scaled by its largest coordinate over its length), and its "
                     "hexahedra. `axis` is the grid's third direction."
                   : "SOFA's cylinder grid: a grid of n[0] x n[1] x n[2] nodes whose square cross-section of half-width "
                     "`radius` is pushed onto the disc (each point scaled by its largest coordinate over its length), the "
                     "third index running along `axis` over `length` from `center`, and its hexahedra.";
    s.add(AttrSpec::ints("n", 3).def("2 2 2").atLeast(1).help("nodes per direction (at most 10 million in all)"));
    s.add(AttrSpec::reals("center", 3).def("0 0 0").unit(Dimension::length()).help(sphere ? "the centre" : "the centre of the first disc"));
    s.add(AttrSpec::reals("axis", 3).def("0 0 1").help(sphere ? "the grid's third direction" : "the cylinder's axis"));
    s.add(AttrSpec::real("radius").def("1").above(0).unit(Dimension::length()).help("the radius"));
    if (!sphere) s.add(AttrSpec::real("length").def("1").above(0).unit(Dimension::length()).help("the length along the axis"));
    s.factory = [](BuildContext& c) { return std::make_unique<RegularGridTopology>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "TetrahedronSetTopologyContainer";
    s.aliases = {"TetrahedronSetTopology"};
    s.category = "topology";
    s.doc = "Holds tetrahedra: from a loader (`src`), explicit lists, or a topological mapping writing to it.";
    s.add(AttrSpec::link("src").help("a loader to take points and tetrahedra from"));
    s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("points"));
    s.add(AttrSpec::ints("tetrahedra").multipleOf(4).atLeast(0).linked().help("node indices, four per tetrahedron"));
    s.factory = [](BuildContext& c) { return std::make_unique<TetrahedronSetTopologyContainer>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "SparseGridTopology";
    s.aliases = {"SparseGrid"};
    s.category = "topology";
    s.doc = "The hexahedra of a regular grid of n nodes over a closed surface's bounding box that the surface crosses "
            "or encloses (voxelisation: a cell is kept when a triangle meets it or when it is cut off from the grid's "
            "border by such cells); the bounding box is grown by 1 % of its size on each side, as in SOFA. Numbered as "
            "SOFA numbers them: nodes are the kept cells' corners sorted by position (x, then y, then z), hexahedra "
            "the boundary cells, then the inside cells.";
    s.add(AttrSpec::file("fileTopology").alias("filename").req().help("the closed surface (.obj, .stl, .off, .ply)"));
    s.add(AttrSpec::ints("n", 3).def("2 2 2").atLeast(2).help("grid nodes per axis over the surface's bounding box"));
    s.factory = [](BuildContext& c) { return std::make_unique<SparseGridTopology>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "SparseGridRamificationTopology";
    s.category = "topology";
    s.doc = "SOFA's sparse grid that keeps a shape's separate parts apart: the surface is voxelised 2^L times finer "
            "(L = nbVirtualFinerLevels); a cell of the n-node grid whose fine cells fall into several face-connected "
            "groups becomes one hexahedron per group, and hexahedra of neighbouring cells share the corners of their "
            "common face, edge or corner only where their fine cells touch straight across it. Each such hexahedron "
            "is a whole cell (volume-based masses and stiffness count a cell of two parts twice, as SOFA's), and "
            "nodes are numbered by hexahedron, not in grid order. A BarycentricMapping embeds a point in the "
            "hexahedron of the part it lies in.";
    s.add(AttrSpec::file("fileTopology").alias("filename").req().help("the closed surface (.obj, .stl, .off, .ply)"));
    s.add(AttrSpec::ints("n", 3).def("2 2 2").atLeast(2).help("grid nodes per axis over the surface's bounding box"));
    s.add(AttrSpec::integer("nbVirtualFinerLevels").def("0").atLeast(0).atMost(6).help("how many times the cells are halved to find the parts"));
    s.add(AttrSpec::boolean("finestConnectivity").def("false").help("SOFA's connectivity through the surface's triangles (only false: the fine cells' faces decide)"));
    s.factory = [](BuildContext& c) { return std::make_unique<SparseGridTopology>(c); };
    r.add(std::move(s));
  }
  for (const char* name : {"MeshTopology", "HexahedronSetTopologyContainer"}) {
    const bool hexOnly = std::string(name) == "HexahedronSetTopologyContainer";
    ComponentSpec s;
    s.name = name;
    s.aliases = {hexOnly ? "HexahedronSetTopology" : "Mesh"};
    s.category = "topology";
    s.doc = hexOnly ? "Holds hexahedra: from a grid or loader (`src`), or explicit lists."
                    : "Holds any of a mesh's points, triangles, quads, tetrahedra and hexahedra: from a mesh or surface file "
                      "(`filename`), a loader or grid (`src`), or explicit lists (given lists replace what `src` gives).";
    s.add(AttrSpec::link("src").help("a loader or topology to take points and elements from"));
    if (!hexOnly) s.add(AttrSpec::file("filename").help("a mesh (.msh, .vtk, .vtu) or surface (.obj, .stl, .off, .ply) file"));
    s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("points"));
    if (!hexOnly) {
      s.add(AttrSpec::ints("triangles").multipleOf(3).atLeast(0).linked().help("node indices, three per triangle"));
      s.add(AttrSpec::ints("quads").multipleOf(4).atLeast(0).linked().help("node indices, four per quad"));
      s.add(AttrSpec::ints("tetrahedra").multipleOf(4).atLeast(0).linked().help("node indices, four per tetrahedron"));
    }
    s.add(AttrSpec::ints("hexahedra").multipleOf(8).atLeast(0).linked().help("node indices, eight per hexahedron (SOFA's order)"));
    s.factory = [](BuildContext& c) { return std::make_unique<GeneralMeshTopology>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "TriangleSetTopologyContainer";
    s.aliases = {"TriangleSetTopology"};
    s.category = "topology";
    s.doc = "Holds surface triangles: from a loader (`src`), explicit lists, or a Tetra2TriangleTopologicalMapping writing "
            "the boundary of a tetrahedral body to it (SOFA's collision and visual surface). It has no tetrahedra: "
            "a collision model or force field in its node uses the volume above it.";
    s.add(AttrSpec::link("src").help("a loader to take points and triangles from"));
    s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("points"));
    s.add(AttrSpec::ints("triangles").multipleOf(3).atLeast(0).linked().help("node indices, three per triangle"));
    s.add(AttrSpec::file("fileTopology").help("a surface file (.obj, .stl, .off, .ply) to take points and triangles from"));
    s.factory = [](BuildContext& c) { return std::make_unique<TriangleSetTopologyContainer>(c); };
    r.add(std::move(s));
  }
  for (const bool edges : {false, true}) {
    ComponentSpec s;
    s.name = edges ? "EdgeSetTopologyContainer" : "PointSetTopologyContainer";
    s.aliases = {edges ? "EdgeSetTopology" : "PointSetTopology"};
    s.category = "topology";
    s.doc = edges ? "Holds points and the edges between them (node pairs): from a loader (`src`) or explicit lists. "
                    "Springs on a mesh (MeshSpringForceField) take its edges as lines."
                  : "Holds points: from a loader (`src`) or an explicit list. A MechanicalObject without positions takes "
                    "them.";
    s.add(AttrSpec::link("src").help(edges ? "a loader to take points and edges from" : "a loader to take points from"));
    s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("points"));
    if (edges) s.add(AttrSpec::ints("edges").multipleOf(2).atLeast(0).linked().help("node indices, two per edge"));
    s.factory = [](BuildContext& c) { return std::make_unique<PointEdgeContainer>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "QuadSetTopologyContainer";
    s.aliases = {"QuadSetTopology"};
    s.category = "topology";
    s.doc = "Holds surface quads: from a loader (`src`), explicit lists, or a Hexa2QuadTopologicalMapping writing the "
            "boundary of a hexahedral body to it (e.g. a grid's visual surface). It has no volume elements.";
    s.add(AttrSpec::link("src").help("a loader to take points and quads from"));
    s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("points"));
    s.add(AttrSpec::ints("quads").multipleOf(4).atLeast(0).linked().help("node indices, four per quad"));
    s.factory = [](BuildContext& c) { return std::make_unique<QuadSetTopologyContainer>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "Hexa2QuadTopologicalMapping";
    s.category = "topology";
    s.doc = "Writes the boundary quads of `input`'s hexahedra (outward) into the QuadSetTopologyContainer `output`, "
            "with the same points.";
    s.add(AttrSpec::link("input").req().help("topology with hexahedra (e.g. a RegularGridTopology)"));
    s.add(AttrSpec::link("output").req().help("the QuadSetTopologyContainer to fill"));
    s.add(AttrSpec::boolean("flipNormals").def("false").help("reverse the orientation of the quads (inward)"));
    s.factory = [](BuildContext& c) { return std::make_unique<Hexa2QuadTopologicalMapping>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "Quad2TriangleTopologicalMapping";
    s.category = "topology";
    s.doc = "Writes each quad of the QuadSetTopologyContainer `input` as two triangles, (a b c) and (a c d), into the "
            "TriangleSetTopologyContainer `output`, with the same points (SOFA's split).";
    s.add(AttrSpec::link("input").req().help("the QuadSetTopologyContainer"));
    s.add(AttrSpec::link("output").req().help("the TriangleSetTopologyContainer to fill"));
    s.factory = [](BuildContext& c) { return std::make_unique<Quad2TriangleTopologicalMapping>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "Tetra2TriangleTopologicalMapping";
    s.category = "topology";
    s.doc = "Writes the boundary triangles of `input`'s tetrahedra (outward) into the TriangleSetTopologyContainer "
            "`output`, with the same points.";
    s.add(AttrSpec::link("input").req().help("topology with tetrahedra"));
    s.add(AttrSpec::link("output").req().help("the TriangleSetTopologyContainer to fill"));
    s.add(AttrSpec::boolean("flipNormals").def("false").help("reverse the orientation of the triangles (inward)"));
    s.add(AttrSpec::boolean("noNewTriangles").def("false").help("accepted for SOFA scenes: the topology does not change here"));
    s.add(AttrSpec::boolean("noInitialTriangles").def("false").help("accepted for SOFA scenes: the output holds the boundary only"));
    s.factory = [](BuildContext& c) { return std::make_unique<Tetra2TriangleTopologicalMapping>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "Hexa2TetraTopologicalMapping";
    s.category = "topology";
    s.doc = "Splits every hexahedron of `input` into six tetrahedra written to `output`, in SOFA's order; "
            "`swapping` mirrors alternate cells so that the diagonals match across faces.";
    s.add(AttrSpec::link("input").req().help("topology with hexahedra (e.g. a RegularGridTopology)"));
    s.add(AttrSpec::link("output").req().help("the TetrahedronSetTopologyContainer to fill"));
    s.add(AttrSpec::boolean("swapping").def("false").help("alternate the split between neighbouring cells"));
    s.factory = [](BuildContext& c) { return std::make_unique<Hexa2TetraTopologicalMapping>(c); };
    r.add(std::move(s));
  }
  for (const char* name : {"MeshGmshLoader", "MeshVTKLoader"}) {
    ComponentSpec s;
    s.name = name;
    s.category = "loader";
    s.doc = std::string(name) == "MeshGmshLoader"
                ? "Reads a Gmsh .msh mesh (legacy $NOD/$ELM, v2 and v4 ASCII); fields position, tetrahedra, hexahedra, "
                  "triangles, quads."
                : "Reads a VTK mesh (.vtk legacy ASCII, .vtu); fields position, tetrahedra, triangles.";
    addLoaderAttributes(s);
    s.factory = [](BuildContext& c) { return std::make_unique<MeshLoader>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "SphereLoader";
    s.category = "loader";
    s.doc = "Reads spheres from a SOFA .sph file; fields position (the centres) and listRadius (the radii, times the "
            "scale). Feeds a MechanicalObject and a SphereCollisionModel, as in SOFA's liver scenes.";
    s.add(AttrSpec::file("filename").req().help(".sph file, relative to the scene file or found along the data search path"));
    addPointPlacementAttributes(s, "the centres");
    s.factory = [](BuildContext& c) { return std::make_unique<SphereLoader>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "GridMeshCreator";
    s.category = "loader";
    s.doc = "SOFA's procedural 2-D mesh: resolution[0] x resolution[1] points over the unit square of the xy plane "
            "(x fastest), cut into faces by trianglePattern; fields position, edges, triangles and quads; placed by "
            "scale3d, then rotation, then translation, as a loaded mesh.";
    s.add(AttrSpec::ints("resolution", 2).def("2 2").help("points in x and in y (at least 2 each)"));
    s.add(AttrSpec::integer("trianglePattern").def("2").atLeast(0).atMost(3).help(
        "0: quads; triangles 1: alternating diagonals, 2: upward (each cell cut from (x, y) to (x+1, y+1)), 3: downward"));
    addPointPlacementAttributes(s, "the points");
    s.add(AttrSpec::string("filename").def("").help("accepted for SOFA scenes (its loaders all carry one); the mesh is made, not read"));
    s.factory = [](BuildContext& c) { return std::make_unique<GridMeshCreator>(c); };
    r.add(std::move(s));
  }
  for (const char* name : {"MeshOBJLoader", "MeshSTLLoader", "MeshOffLoader"}) {
    ComponentSpec s;
    s.name = name;
    s.category = "loader";
    s.doc = std::string("Reads a surface (") + (std::string(name) == "MeshOBJLoader" ? ".obj" : std::string(name) == "MeshSTLLoader" ? ".stl, ASCII or binary" : ".off") +
            "; polygons are split into triangles); fields position and triangles. Feeds a MechanicalObject (`src` or its "
            "node), an OglModel or a collision surface.";
    addLoaderAttributes(s);
    s.add(AttrSpec::boolean("triangulate").def("false").help(
        "accepted for SOFA scenes: polygons are always split into triangles here (SOFA splits them only when true)"));
    s.factory = [](BuildContext& c) { return std::make_unique<SurfaceLoader>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
