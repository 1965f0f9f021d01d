// Mappings from a deformable body to a visual surface: BarycentricMapping (the surface embedded
// in the tetrahedra) and IdentityMapping (the surface's vertices are the body's nodes).
#include <cstdio>
#include <string>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mapping/Embedding.h"
#include "engine/mapping/VisualModel.h"
#include "engine/mechanics/MechanicalObject.h"

namespace viscera {

namespace {

// Four significant digits, for messages.
std::string formatNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

// The node a link names, for SOFA's node links ("@..": the parent, "@.": this node,
// "@/root/body", "@child/"); nullptr if the path does not name a node.
const Node* nodeAt(const Node& from, const std::string& link) {
  std::string path = !link.empty() && link[0] == '@' ? link.substr(1) : link;
  const Node* node = &from;
  if (!path.empty() && path[0] == '/') {
    while (node->parent()) node = node->parent();
    path.erase(0, 1);
    // An absolute path may name the root node first.
    const size_t slash = path.find('/');
    if (path.substr(0, slash) == node->name()) path.erase(0, slash == std::string::npos ? path.size() : slash + 1);
  }
  size_t start = 0;
  while (start < path.size()) {
    size_t end = path.find('/', start);
    if (end == std::string::npos) end = path.size();
    const std::string part = path.substr(start, end - start);
    start = end + 1;
    if (part.empty() || part == ".") continue;
    if (part == "..") {
      node = node->parent();
    } else {
      const Node* next = nullptr;
      for (const auto& child : node->children())
        if (child->name() == part) next = child.get();
      node = next;
    }
    if (!node) return nullptr;
  }
  return node;
}

// What a mapping's link names: a component or, as SOFA allows, a node.
struct LinkTarget {
  Component* component = nullptr;
  const Node* node = nullptr;
};

// Base of the mappings onto a visual model: resolves `input` (a Vec3d MechanicalObject) and
// `output` (an OglModel/VisualModel) with SOFA's defaults.
class VisualMapping : public Component, public Mapping {
 public:
  using Component::Component;

 protected:
  void resolveEnds() {
    checkVec3Template(*this);
    input_ = &inputState();
    output_ = &outputModel();
  }

  MechanicalObject* input_ = nullptr;
  VisualModel* output_ = nullptr;

 private:
  LinkTarget target(const std::string& attr) {
    const AttrValue& v = attrs_.get(attr);
    try {
      return {&scene().resolve(*this, v.text, v.loc, attrs_.component() + "." + attr), nullptr};
    } catch (const Error&) {
      if (const Node* n = nodeAt(node(), v.text)) return {nullptr, n};
      throw;
    }
  }

  MechanicalObject& inputState() {
    MechanicalObject* m = nullptr;
    if (attrs_.isSet("input")) {
      const LinkTarget t = target("input");
      if (t.node) {
        m = t.node->find<MechanicalObject>();
        if (!m) throw error("input", "node " + t.node->path() + " has no MechanicalObject (Vec3d)");
      } else {
        m = dynamic_cast<MechanicalObject*>(t.component);
        if (!m)
          throw error("input", "'" + t.component->name() + "' (" + t.component->typeName() +
                                   ") is not a MechanicalObject with Vec3d nodes");
      }
    } else {
      // SOFA's default input is the state of the parent node ("@../").
      for (const Node* n = node().parent(); n && !m; n = n->parent()) m = n->find<MechanicalObject>();
      if (!m) throw error("input", "is not set and no node above holds a MechanicalObject (Vec3d)");
    }
    scene().initComponent(*m);
    return *m;
  }

  VisualModel& outputModel() {
    VisualModel* v = nullptr;
    if (attrs_.isSet("output")) {
      const LinkTarget t = target("output");
      if (t.node) {
        v = t.node->find<VisualModel>();
        if (!v) throw error("output", "node " + t.node->path() + " has no OglModel/VisualModel");
      } else {
        v = dynamic_cast<VisualModel*>(t.component);
        if (!v)
          throw error("output", "'" + t.component->name() + "' (" + t.component->typeName() +
                                    ") is not a visual model: the output must be an OglModel/VisualModel");
      }
    } else {
      v = node().find<VisualModel>();
      if (!v) throw error("output", "is not set and there is no OglModel/VisualModel in the node");
    }
    scene().initComponent(*v);
    v->setDriver(*this);
    return *v;
  }
};

class BarycentricMapping : public VisualMapping {
 public:
  using VisualMapping::VisualMapping;

  void init() override {
    resolveEnds();
    const TetList* tets = tetrahedraAbove(scene(), input_->node());
    if (!tets)
      throw error("input", "MechanicalObject '" + input_->name() +
                               "' has no tetrahedra in its node or above to embed the surface in");
    if (tets->maxCoeff() >= input_->size())
      throw error("input", "the tetrahedra refer to node " + std::to_string(tets->maxCoeff()) + ", but MechanicalObject '" +
                               input_->name() + "' has " + std::to_string(input_->size()) + " nodes");
    // SOFA embeds in the positions at the start unless useRestPosition is set; the two differ only
    // when the MechanicalObject gives both `position` and `rest_position`.
    const Eigen::Matrix3Xd& nodes = attrs_.boolean("useRestPosition") ? input_->x0 : input_->x;
    const double reach = attrs_.isSet("maxDistance") ? attrs_.real("maxDistance") : meanEdgeLength(nodes, *tets);
    embedding_ = embedInTetrahedra(nodes, *tets, output_->x0, reach);

    const std::string units = scene().units().str();
    const std::string unit = units.substr(0, units.find(' '));  // the length unit, for messages
    if (const int unplaced = embedding_.unplacedCount()) {
      int first = 0;
      while (embedding_.element[first] >= 0) ++first;
      const Eigen::Vector3d p = output_->x0.col(first);
      const double nearest = nearestTetrahedron(nodes, *tets, p).second;
      const std::string limit = formatNumber(reach) + " " + unit +
                                (attrs_.isSet("maxDistance") ? "" : " (the default: the mean edge length)");
      const std::string where = "(" + formatNumber(p.x()) + ", " + formatNumber(p.y()) + ", " + formatNumber(p.z()) + ")";
      throw error("maxDistance", std::to_string(unplaced) + " of " + std::to_string(output_->size()) + " points of '" +
                                     output_->name() + "' are farther than " + limit + " from every tetrahedron of '" +
                                     input_->name() + "'; point " + std::to_string(first) + " at " + where + " is " +
                                     formatNumber(nearest) + " " + unit +
                                     " from the nearest. Check the surface's units and placement (scale3d, rotation, "
                                     "translation), or raise maxDistance");
    }
    if (const int outside = embedding_.extrapolatedCount()) {
      scene().addNote(loc().str() + ": note: BarycentricMapping '" + name() + "': " + std::to_string(outside) + " of " +
                      std::to_string(output_->size()) + " points of '" + output_->name() +
                      "' lie outside the tetrahedra (up to " + formatNumber(embedding_.distance.maxCoeff()) + " " + unit +
                      " away); they follow the nearest tetrahedron, extrapolated");
    }
  }

  void apply() override { applyEmbedding(embedding_, input_->x, output_->x); }

 private:
  TetEmbedding embedding_;
};

class IdentityMapping : public VisualMapping {
 public:
  using VisualMapping::VisualMapping;

  void init() override {
    resolveEnds();
    if (output_->size() != input_->size())
      throw error("output", "'" + output_->name() + "' has " + std::to_string(output_->size()) + " vertices but '" +
                                input_->name() + "' has " + std::to_string(input_->size()) +
                                " nodes; IdentityMapping needs as many (BarycentricMapping embeds a different surface)");
  }

  void apply() override { output_->x = input_->x; }
};

// The attributes every mapping declares (SOFA's BaseMapping and Mapping data).
void addMappingAttributes(ComponentSpec& s) {
  s.add(AttrSpec::string("template").def("Vec3d,Vec3d").help(
      "input,output coordinate types (Vec3d, Vec3f, ExtVec3f); computed in double precision"));
  s.add(AttrSpec::link("input").alias("object1").help(
      "the MechanicalObject (Vec3d) that moves the surface, or its node (\"@..\"); default: the MechanicalObject of the "
      "nearest node above"));
  s.add(AttrSpec::link("output").alias("object2").help(
      "the OglModel/VisualModel it moves, or its node; default: the one in this node"));
  const char* noEffect = "accepted for SOFA scenes; a visual surface carries no forces, constraints, masses or matrices";
  s.add(AttrSpec::boolean("mapForces").def("true").help(noEffect));
  s.add(AttrSpec::boolean("mapConstraints").def("true").help(noEffect));
  s.add(AttrSpec::boolean("mapMasses").def("true").help(noEffect));
  s.add(AttrSpec::boolean("mapMatrices").def("false").help(noEffect));
  s.add(AttrSpec::boolean("applyRestPosition").def("false").help(
      "accepted for SOFA scenes; the surface's rest positions are its own"));
}

}  // namespace

void registerMappings(Registry& r) {
  registerVisualModel(r);
  {
    ComponentSpec s;
    s.name = "BarycentricMapping";
    s.category = "mapping";
    s.doc = "Moves a visual surface with the tetrahedra of a deformable body. At init each surface point gets the "
            "tetrahedron that contains it (found through a bounding-volume hierarchy) and its barycentric coordinates "
            "there; every step x_point = sum w_i x_i over that tetrahedron's four nodes. A point outside every "
            "tetrahedron but within maxDistance follows the nearest one with unclamped coordinates (extrapolation, "
            "exact for affine motion; counted in a note); a point farther away is an error.";
    addMappingAttributes(s);
    s.add(AttrSpec::boolean("useRestPosition").def("false").help(
        "embed in the input's rest positions (true) or its positions at the start (false); they differ only when the "
        "MechanicalObject gives both position and rest_position"));
    s.add(AttrSpec::real("maxDistance").above(0).unit(Dimension::length()).help(
        "farthest a surface point may lie outside the tetrahedra (default: their mean edge length)"));
    s.factory = [](BuildContext& c) { return std::make_unique<BarycentricMapping>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "IdentityMapping";
    s.category = "mapping";
    s.doc = "Moves a visual surface whose vertex i is node i of a deformable body (an OglModel without a file, or a "
            "surface with the same vertices): x_vertex = x_node every step. The counts must match.";
    addMappingAttributes(s);
    s.factory = [](BuildContext& c) { return std::make_unique<IdentityMapping>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
