// Mappings from a deformable body to points that follow it, a visual surface or a mapped state:
// BarycentricMapping (the points embedded in the tetrahedra) and IdentityMapping (the points are
// the body's nodes).
#include <algorithm>
#include <cstdio>
#include <limits>
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

// Where a mapping writes: a visual surface's vertices, or the nodes of a Vec3d MechanicalObject
// that no solver integrates (SOFA's mapped state, e.g. collision spheres), whose velocities are
// mapped too.
struct MappedPoints {
  Component* component = nullptr;
  const VisualModel* visual = nullptr;     // a visual surface, or
  const MechanicalObject* state = nullptr;  // a mapped state (positions and velocities)
  Eigen::Matrix3Xd initial;                // the points where the mapping is set up
  int size() const { return static_cast<int>(initial.cols()); }
  const std::string& name() const { return component->name(); }
};

// Base of the mappings from a deformable body: resolves `input` (a Vec3d MechanicalObject) and
// `output` (an OglModel/VisualModel or a mapped MechanicalObject) with SOFA's defaults.
class PointMapping : public Component, public Mapping {
 public:
  using Component::Component;

 protected:
  void resolveEnds() {
    checkVec3Template(*this);
    input_ = &inputState();
    output_ = outputPoints();
  }
  MechanicalObject* inputState() const override { return input_; }

  // Writes map(input positions) and, for a MechanicalObject, map(input velocities).
  template <class Map>
  void write(State& s, const Map& map) const {
    if (output_.visual) {
      map(input_->x(s), output_.visual->x(s));
      return;
    }
    map(input_->x(s), output_.state->x(s));
    map(input_->v(s), output_.state->v(s));
  }

  MechanicalObject* input_ = nullptr;
  MappedPoints output_;

 private:
  MechanicalObject& inputState() {
    MechanicalObject* m = nullptr;
    if (attrs_.isSet("input")) {
      const LinkTarget t = linkTarget(*this, "input");
      if (t.node) {
        // A node stands for its state, its own or, as SOFA's context lookup, the nearest above.
        m = t.node->findInContext<MechanicalObject>();
        if (!m) throw error("input", "node " + t.node->path() + " has no MechanicalObject (Vec3d) in it or above");
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

  MappedPoints outputPoints() {
    Component* out = nullptr;
    if (attrs_.isSet("output")) {
      const LinkTarget t = linkTarget(*this, "output");
      if (t.node) {
        out = t.node->find<VisualModel>();
        if (!out) out = t.node->find<MechanicalObject>();
        if (!out) throw error("output", "node " + t.node->path() + " has no OglModel/VisualModel or MechanicalObject");
      } else {
        out = t.component;
      }
    } else {
      // SOFA's default output is the state of this node: its MechanicalObject, else its visual model.
      out = node().find<MechanicalObject>();
      if (!out) out = node().find<VisualModel>();
      if (!out) throw error("output", "is not set and there is no OglModel/VisualModel or MechanicalObject in the node");
    }
    scene().initComponent(*out);
    MappedPoints p;
    p.component = out;
    if (auto* v = dynamic_cast<VisualModel*>(out)) {
      v->setDriver(*this);
      p.visual = v;
      p.initial = v->x0;
    } else if (auto* m = dynamic_cast<MechanicalObject*>(out)) {
      if (m == input_) throw error("output", "is the input itself");
      if (auto* solver = m->node().find<OdeSolver>())
        throw error("output", "MechanicalObject '" + m->name() + "' is integrated by the " +
                                  dynamic_cast<Component&>(*solver).typeName() + " in its node; a mapped state must be "
                                  "in a node without an ODE solver");
      m->setMappedBy(*this);
      p.state = m;
      p.initial = m->xInit;
    } else {
      throw error("output", "'" + out->name() + "' (" + out->typeName() +
                                ") is neither a visual model (OglModel/VisualModel) nor a MechanicalObject (Vec3d)");
    }
    return p;
  }
};

class BarycentricMapping : public PointMapping {
 public:
  using PointMapping::PointMapping;

  void init() override {
    resolveEnds();
    // SOFA's barycentric mappers: on tetrahedra, or on a grid's hexahedra (trilinear).
    const Topology* volume = volumeAbove(scene(), input_->node());
    const TetList* tets = volume && volume->tetrahedra().cols() > 0 ? &volume->tetrahedra() : nullptr;
    const Topology* grid = tets ? nullptr : volume;
    const HexList* hexa = grid ? &grid->hexahedra() : nullptr;
    if (!tets && !hexa)
      throw error("input", "MechanicalObject '" + input_->name() +
                               "' has no tetrahedra or hexahedra in its node or above to embed the points in");
    const int maxNode = tets ? tets->maxCoeff() : maxNodeOf(*hexa);
    if (maxNode >= input_->size())
      throw error("input", "the elements refer to node " + std::to_string(maxNode) + ", but MechanicalObject '" +
                               input_->name() + "' has " + std::to_string(input_->size()) + " nodes");
    // SOFA embeds in the positions at the start unless useRestPosition is set; the two differ only
    // when the MechanicalObject gives both `position` and `rest_position`.
    // On a grid, as SOFA's grid mapper, the points are located in the grid's own geometry, before
    // any placement of the MechanicalObject (dx, rx, ...), which then carries them along.
    const bool gridGeometry = grid && grid->points().cols() == input_->size();
    const Eigen::Matrix3Xd& nodes = gridGeometry                        ? grid->points()
                                    : attrs_.boolean("useRestPosition") ? input_->x0
                                                                        : input_->xInit;
    const double reach = attrs_.isSet("maxDistance") ? attrs_.real("maxDistance")
                         : tets                      ? meanEdgeLength(nodes, *tets)
                                                     : meanHexahedronEdge(nodes, *hexa);
    Eigen::VectorXd distance;
    if (tets) {
      embedding_ = embedInTetrahedra(nodes, *tets, output_.initial, reach);
      distance = embedding_.distance;
    } else {
      hexEmbedding_ = embedInHexahedra(nodes, *hexa, output_.initial);
      distance = hexEmbedding_.distance;
      hexa_ = true;
      // A cell holding separate parts (a ramified grid) has one hexahedron per part over the
      // same corners: a point follows the part it lies in, with the same local coordinates.
      for (int p = 0; p < hexEmbedding_.size(); ++p) {
        const int part = grid->partAt(output_.initial.col(p));
        if (part < 0) continue;
        const auto& h = (*hexa)[static_cast<size_t>(part)];
        bool sameCell = true;
        for (int k = 0; k < 8 && sameCell; ++k)
          sameCell = (nodes.col(h[k]) - nodes.col(hexEmbedding_.nodes(k, p))).norm() <= 1e-12 * (1 + nodes.col(h[k]).norm());
        if (sameCell)
          for (int k = 0; k < 8; ++k) hexEmbedding_.nodes(k, p) = h[k];
      }
    }

    const std::string units = scene().units().str();
    const std::string unit = units.substr(0, units.find(' '));  // the length unit, for messages
    int unplaced = 0, first = -1, outside = 0;
    for (int p = 0; p < distance.size(); ++p) {
      if (!(distance[p] <= reach)) {
        ++unplaced;
        if (first < 0) first = p;
      } else if (distance[p] > 0) {
        ++outside;
      }
    }
    if (unplaced) {
      const Eigen::Vector3d p = output_.initial.col(first);
      const double nearest = tets ? nearestTetrahedron(nodes, *tets, p).second : distance[first];
      const std::string limit = formatNumber(reach) + " " + unit +
                                (attrs_.isSet("maxDistance") ? "" : " (the default: the mean edge length)");
      const std::string where = "(" + formatNumber(p.x()) + ", " + formatNumber(p.y()) + ", " + formatNumber(p.z()) + ")";
      throw error("maxDistance", std::to_string(unplaced) + " of " + std::to_string(output_.size()) + " points of '" +
                                     output_.name() + "' are farther than " + limit + " from every " +
                                     (tets ? "tetrahedron" : "hexahedron") + " of '" + input_->name() + "'; point " +
                                     std::to_string(first) + " at " + where + " is " + formatNumber(nearest) + " " + unit +
                                     " from the nearest. Check the surface's units and placement (scale3d, rotation, "
                                     "translation), or raise maxDistance");
    }
    if (outside) {
      scene().addNote(loc().str() + ": note: BarycentricMapping '" + name() + "': " + std::to_string(outside) + " of " +
                      std::to_string(output_.size()) + " points of '" + output_.name() + "' lie outside the " +
                      (tets ? "tetrahedra" : "hexahedra") + " (up to " + formatNumber(distance.maxCoeff()) + " " + unit +
                      " away); they follow the nearest one, extrapolated");
    }
  }

  void apply(State& s) const override {
    if (hexa_) write(s, [this](const Eigen::Matrix3Xd& in, Eigen::Matrix3Xd& out) { applyEmbedding(hexEmbedding_, in, out); });
    else write(s, [this](const Eigen::Matrix3Xd& in, Eigen::Matrix3Xd& out) { applyEmbedding(embedding_, in, out); });
  }
  bool pointWeights(int p, std::vector<std::pair<int, double>>& out) const override {
    out.clear();
    if (hexa_) {
      if (p < 0 || p >= hexEmbedding_.size()) return false;
      for (int k = 0; k < 8; ++k) out.push_back({hexEmbedding_.nodes(k, p), hexEmbedding_.weights(k, p)});
    } else {
      if (p < 0 || p >= embedding_.size() || embedding_.element[p] < 0) return false;
      for (int k = 0; k < 4; ++k) out.push_back({embedding_.nodes(k, p), embedding_.weights(k, p)});
    }
    return true;
  }

 private:
  static int maxNodeOf(const HexList& hexa) {
    int m = -1;
    for (const auto& h : hexa)
      for (int v : h) m = std::max(m, v);
    return m;
  }
  // Mean length of the three edges at each hexahedron's first corner.
  static double meanHexahedronEdge(const Eigen::Matrix3Xd& x, const HexList& hexa) {
    double sum = 0;
    for (const auto& h : hexa)
      sum += (x.col(h[1]) - x.col(h[0])).norm() + (x.col(h[3]) - x.col(h[0])).norm() + (x.col(h[4]) - x.col(h[0])).norm();
    return hexa.empty() ? 0.0 : sum / (3.0 * hexa.size());
  }

  TetEmbedding embedding_;
  HexEmbedding hexEmbedding_;
  bool hexa_ = false;
};

class IdentityMapping : public PointMapping {
 public:
  using PointMapping::PointMapping;

  void init() override {
    resolveEnds();
    if (output_.size() != input_->size())
      throw error("output", "'" + output_.name() + "' has " + std::to_string(output_.size()) + " vertices but '" +
                                input_->name() + "' has " + std::to_string(input_->size()) +
                                " nodes; IdentityMapping needs as many (BarycentricMapping embeds a different surface)");
  }

  void apply(State& s) const override {
    write(s, [](const Eigen::Matrix3Xd& in, Eigen::Matrix3Xd& out) { out = in; });
  }
  bool pointWeights(int p, std::vector<std::pair<int, double>>& out) const override {
    out.assign(1, {p, 1.0});
    return p >= 0 && p < input_->size();
  }
};

// SOFA's SubsetMapping: output point i is input node indices[i]. Without indices, each output
// point is the input node at its place (within `radius`), as SOFA pairs them at init.
class SubsetMapping : public PointMapping {
 public:
  using PointMapping::PointMapping;

  void init() override {
    resolveEnds();
    const int n = input_->size();
    if (attrs_.isSet("indices")) {
      index_ = linkedInts("indices");
      if (static_cast<int>(index_.size()) != output_.size())
        throw error("indices", "has " + std::to_string(index_.size()) + " nodes for the " + std::to_string(output_.size()) +
                                   " points of '" + output_.name() + "'");
      for (int i : index_)
        if (i < 0 || i >= n) throw error("indices", "node " + std::to_string(i) + " is not a node of '" + input_->name() + "'");
      return;
    }
    const double radius = attrs_.real("radius");
    const Eigen::Matrix3Xd& X = input_->xInit;
    index_.resize(output_.size());
    for (int p = 0; p < output_.size(); ++p) {
      int best = -1;
      double bestD = std::numeric_limits<double>::infinity();
      for (int i = 0; i < n; ++i)
        if (const double d = (X.col(i) - output_.initial.col(p)).norm(); d < bestD) bestD = d, best = i;
      if (!(bestD <= radius))
        throw error("radius", "point " + std::to_string(p) + " of '" + output_.name() + "' is " + formatNumber(bestD) +
                                  " from the nearest node of '" + input_->name() + "' (radius " + formatNumber(radius) +
                                  "): a subset's points must be nodes of the input; give `indices`, or map it with "
                                  "BarycentricMapping");
      index_[p] = best;
    }
  }

  void apply(State& s) const override {
    write(s, [this](const Eigen::Matrix3Xd& in, Eigen::Matrix3Xd& out) {
      for (size_t p = 0; p < index_.size(); ++p) out.col(p) = in.col(index_[p]);
    });
  }
  bool pointWeights(int p, std::vector<std::pair<int, double>>& out) const override {
    if (p < 0 || p >= static_cast<int>(index_.size())) return false;
    out.assign(1, {index_[p], 1.0});
    return true;
  }

 private:
  std::vector<int> index_;
};

// The attributes every mapping declares (SOFA's BaseMapping and Mapping data).
void addMappingAttributes(ComponentSpec& s) {
  s.add(AttrSpec::string("template").def("Vec3d,Vec3d").help(
      "input,output coordinate types (Vec3d, Vec3f, ExtVec3f); computed in double precision"));
  s.add(AttrSpec::link("input").alias("object1").help(
      "the MechanicalObject (Vec3d) that moves the surface, or its node (\"@..\"); default: the MechanicalObject of the "
      "nearest node above"));
  s.add(AttrSpec::link("output").alias("object2").help(
      "the OglModel/VisualModel or Vec3d MechanicalObject (in a node without an ODE solver) it moves, or its node; "
      "default: the MechanicalObject of this node, else its visual model"));
  const char* noEffect = "accepted for SOFA scenes; nothing acts on a mapped output (force fields, masses and "
                         "constraints beside it are refused), so there is nothing to map back";
  s.add(AttrSpec::boolean("mapForces").def("true").help(noEffect));
  s.add(AttrSpec::boolean("mapConstraints").def("true").help(noEffect));
  s.add(AttrSpec::boolean("mapMasses").def("true").help(noEffect));
  s.add(AttrSpec::boolean("mapMatrices").def("false").help(noEffect));
  s.add(AttrSpec::boolean("isMechanical").def("true").help(noEffect));
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
    s.doc = "Moves a visual surface, or a mapped MechanicalObject (positions and velocities), with the tetrahedra of a "
            "deformable body, or with the hexahedra of a grid (trilinear coordinates; SOFA's free-form deformation). At "
            "init each point gets the "
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
    s.doc = "Moves a visual surface or a mapped MechanicalObject whose point i is node i of a deformable body (an "
            "OglModel without a file, or a surface with the same vertices): x_point = x_node (and v_point = v_node) "
            "every step. The counts must match.";
    addMappingAttributes(s);
    s.factory = [](BuildContext& c) { return std::make_unique<IdentityMapping>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "SubsetMapping";
    s.category = "mapping";
    s.doc = "Moves a visual surface or a mapped MechanicalObject whose points are some of a body's nodes (SOFA's "
            "SubsetMapping): point i follows node indices[i]; without indices each point follows the node at its place "
            "at init (within radius).";
    addMappingAttributes(s);
    s.add(AttrSpec::ints("indices").atLeast(0).linked().help("the input node of each output point"));
    s.add(AttrSpec::real("radius").def("1e-5").atLeast(0).unit(Dimension::length()).help(
        "without indices: how far a point may be from the node it is paired with"));
    s.factory = [](BuildContext& c) { return std::make_unique<SubsetMapping>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
