#include "engine/mapping/VisualModel.h"

#include <algorithm>
#include <filesystem>
#include <string>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/topology/GridSplit.h"
#include "engine/topology/SurfaceFile.h"
#include "io/scene/InputCache.h"
#include "io/surface/SurfaceMesh.h"

namespace viscera {

namespace {

// Checks that every triangle refers to one of `numPoints` vertices.
void checkTriangles(const Component& c, const std::string& attr, const TriangleList& tris, Eigen::Index numPoints,
                    const std::string& what) {
  for (Eigen::Index t = 0; t < tris.cols(); ++t)
    for (int k = 0; k < 3; ++k)
      if (tris(k, t) < 0 || tris(k, t) >= numPoints)
        throw c.error(attr, what + ": triangle " + std::to_string(t) + " refers to vertex " + std::to_string(tris(k, t)) +
                                ", but there are " + std::to_string(numPoints) + " vertices");
}

Eigen::Matrix3Xd pointsOf(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::Matrix3Xd>(v.data(), 3, static_cast<Eigen::Index>(v.size() / 3));
}

TriangleList trianglesOf(const std::vector<double>& v) {
  TriangleList t(3, static_cast<Eigen::Index>(v.size() / 3));
  for (size_t i = 0; i < v.size(); ++i) t(static_cast<Eigen::Index>(i % 3), static_cast<Eigen::Index>(i / 3)) = static_cast<int>(v[i]);
  return t;
}

}  // namespace

void VisualModel::init() {
  checkVec3Template(*this);
  // With `src`, `position` may replace the source's positions (SOFA's src + position="@engine...").
  const bool moved = attrs_.isSet("src") && attrs_.isSet("position");
  const int sources = attrs_.isSet("filename") + attrs_.isSet("src") + (attrs_.isSet("position") && !moved);
  if (sources > 1) throw error("give one of `filename`, `src` or `position` (with `triangles`), not several");
  const bool faces = attrs_.isSet("triangles") || attrs_.isSet("quads");
  if (faces && sources > 0 && (!attrs_.isSet("position") || moved))
    throw error(attrs_.isSet("triangles") ? "triangles" : "quads", "goes with `position`, or alone (indexing the nodes of the body above)");
  if (attrs_.isSet("filename")) fromFile();
  else if (attrs_.isSet("src")) fromSource();
  else if (attrs_.isSet("position") || faces) fromAttributes();
  else fromContextBoundary();
  if (x0.cols() == 0) throw error("has no vertices");
  applyPlacement(attrs_, x0);
}

void VisualModel::fromFile() {
  const io::SurfaceMesh& s = *readSurfaceAttribute(*this, "filename");
  x0 = s.points;
  triangles = s.triangles;
  checkTriangles(*this, "filename", triangles, x0.cols(), scene().resolvePath(attrs_.str("filename")));
}

void VisualModel::fromSource() {
  Component* src = linkedComponent("src");
  FieldValue pos, tri;
  if (!src->field("position", pos) || pos.values.empty())
    throw error("src", "'" + src->name() + "' (" + src->typeName() + ") has no positions");
  x0 = pointsOf(pos.values);
  if (attrs_.isSet("position")) {
    const Eigen::Matrix3Xd given = pointsOf(linkedReals("position"));
    if (given.cols() != x0.cols())
      throw error("position", "gives " + std::to_string(given.cols()) + " vertices, but '" + src->name() + "' has " +
                                  std::to_string(x0.cols()));
    x0 = given;
  }
  if (src->field("triangles", tri) && !tri.values.empty()) {
    triangles = trianglesOf(tri.values);
  } else if (auto* topo = dynamic_cast<Topology*>(src); topo && topo->tetrahedra().cols() > 0) {
    triangles = boundaryTriangles(topo->tetrahedra(), x0);
  } else {
    throw error("src", "'" + src->name() + "' (" + src->typeName() + ") has neither triangles nor tetrahedra");
  }
  checkTriangles(*this, "src", triangles, x0.cols(), "'" + src->name() + "'");
}

void VisualModel::fromAttributes() {
  if (!attrs_.isSet("triangles") && !attrs_.isSet("quads")) throw error("triangles", "(or `quads`) is required with `position`");
  // Faces without positions index the nodes of the body above, as SOFA's OglModel quads="@grid.quads".
  x0 = attrs_.isSet("position") ? pointsOf(linkedReals("position")) : contextState(*this).x0;
  std::vector<double> tri = attrs_.isSet("triangles") ? linkedReals("triangles") : std::vector<double>{};
  if (attrs_.isSet("quads")) {
    const std::vector<double> q = linkedReals("quads");
    for (size_t i = 0; i + 3 < q.size(); i += 4) tri.insert(tri.end(), {q[i], q[i + 1], q[i + 2], q[i], q[i + 2], q[i + 3]});
  }
  triangles = trianglesOf(tri);
  checkTriangles(*this, attrs_.isSet("quads") ? "quads" : "triangles", triangles, x0.cols(), "faces");
}

void VisualModel::fromContextBoundary() {
  // As SOFA's OglModel without a file: the surface of the topology above, the nearest one with
  // triangles (a container a topological mapping filled), tetrahedra or hexahedra (their
  // boundary). All of the body's nodes are kept (the interior ones belong to no triangle) so that
  // vertex i is node i.
  MechanicalObject& state = contextState(*this);
  x0 = state.x0;
  for (const Node* n = &node(); n && triangles.cols() == 0; n = n->parent()) {
    const auto& comps = n->components();
    for (auto it = comps.rbegin(); it != comps.rend() && triangles.cols() == 0; ++it) {
      const auto* topo = dynamic_cast<const Topology*>(it->get());
      if (!topo || it->get() == this) continue;
      scene().initComponent(**it);
      FieldValue tris;
      auto check = [&](int node) {
        if (node < 0 || node >= x0.cols())
          throw error("the elements above refer to node " + std::to_string(node) + ", but MechanicalObject '" +
                      state.name() + "' has " + std::to_string(x0.cols()) + " nodes");
      };
      if (topo->tetrahedra().cols() > 0) {
        check(topo->tetrahedra().maxCoeff());
        check(topo->tetrahedra().minCoeff());
        triangles = boundaryTriangles(topo->tetrahedra(), x0);
      } else if (!topo->hexahedra().empty()) {
        for (const auto& h : topo->hexahedra())
          for (int v : h) check(v);
        triangles = hexahedronBoundaryTriangles(topo->hexahedra(), x0);
      } else if ((*it)->field("triangles", tris) && !tris.values.empty()) {
        triangles.resize(3, static_cast<Eigen::Index>(tris.values.size() / 3));
        for (Eigen::Index i = 0; i < triangles.size(); ++i) triangles.data()[i] = static_cast<int>(tris.values[i]);
      }
    }
  }
  if (triangles.cols() == 0)
    throw error("has no `filename`, `src` or `position`, and no topology in its node or above gives a surface "
                "(triangles, or the boundary of tetrahedra or hexahedra)");
  if (triangles.maxCoeff() >= state.size() || triangles.minCoeff() < 0)
    throw error("the surface above refers to node " + std::to_string(triangles.maxCoeff()) + ", but MechanicalObject '" +
                state.name() + "' has " + std::to_string(state.size()) + " nodes");
}

bool VisualModel::field(const std::string& name, FieldValue& out) const {
  if (name == "position") out.values.assign(x0.data(), x0.data() + x0.size());
  else if (name == "restPosition") out.values.assign(x0.data(), x0.data() + x0.size());
  else if (name == "triangles") out.values.assign(triangles.data(), triangles.data() + triangles.size());
  else return false;
  return true;
}

void VisualModel::setDriver(const Component& mapping) {
  if (driver_ && driver_ != &mapping)
    throw mapping.error("output", "'" + name() + "' is already the output of " + driver_->typeName() + " '" +
                                      driver_->name() + "'; give each visual model one mapping");
  driver_ = &mapping;
}

namespace {
// The nearest topology in `from` or above (later ones in a node first) that `has` accepts.
template <class Has>
const Topology* topologyAbove(Scene& scene, const Node& from, Has has) {
  for (const Node* n = &from; n; n = n->parent()) {
    const auto& comps = n->components();
    for (auto it = comps.rbegin(); it != comps.rend(); ++it) {
      auto* t = dynamic_cast<Topology*>(it->get());
      if (!t) continue;
      scene.initComponent(**it);
      if (has(*t)) return t;
    }
  }
  return nullptr;
}
}  // namespace

const TetList* tetrahedraAbove(Scene& scene, const Node& from) {
  const Topology* t = topologyAbove(scene, from, [](const Topology& t) { return t.tetrahedra().cols() > 0; });
  return t ? &t->tetrahedra() : nullptr;
}

const Topology* hexahedraAbove(Scene& scene, const Node& from) {
  return topologyAbove(scene, from, [](const Topology& t) { return !t.hexahedra().empty(); });
}

const Topology* volumeAbove(Scene& scene, const Node& from) {
  for (const Node* n = &from; n; n = n->parent()) {
    const Topology* grid = nullptr;
    const auto& comps = n->components();
    for (auto it = comps.rbegin(); it != comps.rend(); ++it) {
      auto* t = dynamic_cast<Topology*>(it->get());
      if (!t) continue;
      scene.initComponent(**it);
      if (t->tetrahedra().cols() > 0) return t;
      if (!grid && !t->hexahedra().empty()) grid = t;
    }
    if (grid) return grid;
  }
  return nullptr;
}

void checkVec3Template(const Component& c) {
  const std::string& t = c.attrs().str("template");
  std::vector<std::string> parts;
  for (size_t start = 0;;) {
    const size_t comma = t.find(',', start);
    parts.push_back(t.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  static const std::vector<std::string> known = {"Vec3d", "Vec3f", "Vec3", "ExtVec3f", "ExtVec3d", "ExtVec3"};
  for (const auto& p : parts)
    if (parts.size() > 2 || std::find(known.begin(), known.end(), p) == known.end())
      throw c.error("template", "'" + t + "' is not supported (vector types Vec3d, Vec3f, ExtVec3f; as a pair "
                                "input,output for a mapping)");
}

void registerVisualModel(Registry& r) {
  ComponentSpec s;
  s.name = "OglModel";
  s.aliases = {"VisualModel"};
  s.category = "visual";
  s.doc = "A visual surface: triangles moved every step by a BarycentricMapping or IdentityMapping in the same node "
          "(usually a child of the deformable body's node), written by a VTKExporter in that node as a .vtp series. "
          "Vertices and triangles come from `filename` (.obj, .stl, .off, .ply), `src` (a loader's position and "
          "triangles; a tetrahedral one gives its boundary; `position` beside it replaces the positions), `position` and `triangles` or `quads` (without `position`: indexing the body's nodes), or else the boundary "
          "surface of the tetrahedra above (all nodes of the MechanicalObject there, vertex i = node i). "
          "Placement: scale3d, then rotation, then translation. No effect on the mechanics.";
  s.add(AttrSpec::string("template").def("Vec3d").help("coordinate type (Vec3d, Vec3f, ExtVec3f); computed in double precision"));
  s.add(AttrSpec::file("filename").alias("fileMesh").help("surface file (.obj, .stl, .off, .ply), relative to the scene file"));
  s.add(AttrSpec::link("src").help("a loader (or other component) with position and triangles fields"));
  s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("vertex positions x y z ..."));
  s.add(AttrSpec::ints("triangles").multipleOf(3).atLeast(0).linked().help(
      "vertex indices, three per triangle (with `position`, or alone: the nodes of the body above)"));
  s.add(AttrSpec::ints("quads").multipleOf(4).atLeast(0).linked().help(
      "vertex indices, four per quad, drawn as two triangles (as `triangles`)"));
  addPointPlacementAttributes(s, "the vertices");
  const char* drawingOnly = "accepted for SOFA scenes; drawing only, not used";
  s.add(AttrSpec::string("color").help(drawingOnly));
  s.add(AttrSpec::string("material").help(drawingOnly));
  s.add(AttrSpec::string("texturename").help(drawingOnly));
  s.add(AttrSpec::reals("scaleTex").help(drawingOnly));
  s.add(AttrSpec::reals("translationTex").help(drawingOnly));
  s.add(AttrSpec::reals("normals").alias("normal").linked().help(drawingOnly));
  // SOFA draws from `vertices` when texture seams split a position into several drawn vertices.
  s.add(AttrSpec::reals("vertices").linked().help(drawingOnly));
  s.add(AttrSpec::boolean("putOnlyTexCoords").help(drawingOnly));
  for (const char* flag : {"useNormals", "updateNormals", "computeTangents", "handleDynamicTopology"})
    s.add(AttrSpec::boolean(flag).help(drawingOnly));
  s.factory = [](BuildContext& c) { return std::make_unique<VisualModel>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
