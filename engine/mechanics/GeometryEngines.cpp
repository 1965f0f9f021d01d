// Engines that compute geometry from points, as SOFA scenes chain them before a MechanicalObject
// or a visual model: TransformEngine and TransformPosition (placed copies of a point list), and
// VolumeFromTriangles / VolumeFromVolumetricElements (the volume a mesh encloses).
#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"

namespace viscera {

namespace {

Eigen::Matrix3Xd pointsOf(Component& c, const std::string& attr) {
  const auto p = c.linkedReals(attr);
  return Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, static_cast<Eigen::Index>(p.size() / 3));
}

bool putPoints(const Eigen::Matrix3Xd& x, FieldValue& out) {
  out.values.assign(x.data(), x.data() + x.size());
  return true;
}

// SOFA's TransformEngine: scale, then rotate (degrees about x, then y, then z), then translate;
// `inverse` undoes that transform instead.
class TransformEngine : public Component {
 public:
  using Component::Component;
  void init() override {
    out_ = pointsOf(*this, "input_position");
    if (!attrs_.boolean("inverse")) {
      applyPlacement(attrs_, out_);
      return;
    }
    // The inverse of x -> R S x + t is x -> S^-1 R^T (x - t). R and t from the placement of the
    // origin and the unit vectors: p(0) = t, p(e_i) = s_i R e_i + t.
    const auto& s = attrs_.reals("scale3d");
    for (double f : s)
      if (f == 0) throw error("scale3d", "a zero scale has no inverse");
    Eigen::Matrix3Xd probe = Eigen::Matrix3Xd::Zero(3, 4);
    probe.rightCols(3) = Eigen::Matrix3d::Identity();
    applyPlacement(attrs_, probe);
    const Eigen::Vector3d t = probe.col(0);
    Eigen::Matrix3d R;
    for (int i = 0; i < 3; ++i) R.col(i) = (probe.col(i + 1) - t) / s[static_cast<size_t>(i)];
    out_ = (R.transpose() * (out_.colwise() - t)).array().colwise() / Eigen::Array3d(s[0], s[1], s[2]);
  }
  bool field(const std::string& name, FieldValue& out) const override {
    return name == "output_position" && putPoints(out_, out);
  }

 private:
  Eigen::Matrix3Xd out_;
};

// SOFA's TransformPosition with method fromFile: an affine transform read from an ITK transform
// file (.tfm: "Parameters:" the 3x3 matrix row by row and the translation, "FixedParameters:"
// the centre c), applied as y = A (x - c) + t + c.
class TransformPosition : public Component {
 public:
  using Component::Component;
  void init() override {
    out_ = pointsOf(*this, "input_position");
    const std::string method = attrs_.str("method");
    if (method != "fromFile")
      throw error("method", "'" + method + "' is not supported (fromFile: an ITK .tfm affine transform)");
    if (!attrs_.isSet("filename")) throw error("filename", "method fromFile needs a transform file");
    const std::string path = scene().resolvePath(attrs_.str("filename"));
    std::ifstream in(path);
    if (!in) throw error("filename", "cannot read '" + path + "'");
    std::vector<double> params, fixed;
    int lineNo = 0;
    for (std::string line; std::getline(in, line);) {
      ++lineNo;
      const auto colon = line.find(':');
      if (line.empty() || line[0] == '#' || colon == std::string::npos) continue;
      const std::string key = line.substr(0, colon);
      if (key != "Parameters" && key != "FixedParameters") continue;
      std::istringstream values(line.substr(colon + 1));
      std::vector<double>& into = key == "Parameters" ? params : fixed;
      for (std::string word; values >> word;) {
        try {
          size_t used = 0;
          into.push_back(std::stod(word, &used));
          if (used != word.size()) throw std::invalid_argument(word);
        } catch (const std::exception&) {
          throw Error(SourceLoc{path, lineNo, static_cast<int>(colon) + 2},
                      "TransformPosition.filename: '" + word + "' is not a number");
        }
      }
    }
    if (params.size() != 12)
      throw error("filename", "'" + path + "' gives " + std::to_string(params.size()) +
                                  " Parameters; an affine transform has 12 (the 3x3 matrix, then the translation)");
    if (!fixed.empty() && fixed.size() != 3)
      throw error("filename", "'" + path + "' gives " + std::to_string(fixed.size()) + " FixedParameters; the centre has 3");
    Eigen::Matrix3d A;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) A(r, c) = params[static_cast<size_t>(3 * r + c)];
    const Eigen::Vector3d t(params[9], params[10], params[11]);
    const Eigen::Vector3d c = fixed.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(fixed[0], fixed[1], fixed[2]);
    out_ = (A * (out_.colwise() - c)).colwise() + (t + c);
  }
  bool field(const std::string& name, FieldValue& out) const override {
    return name == "output_position" && putPoints(out_, out);
  }

 private:
  Eigen::Matrix3Xd out_;
};

// The volume enclosed by a closed, consistently oriented surface (divergence theorem: the sum of
// the signed volumes of the tetrahedra each face makes with the origin), or the sum of the
// volumes of tetrahedra and hexahedra (each hexahedron as six tetrahedra).
class VolumeEngine : public Component {
 public:
  using Component::Component;
  void init() override {
    if (attrs_.boolean("update")) throw error("update", "the volume is computed once, at the start; set it to false");
    const MechanicalObject& mo = contextState(*this, "mstate");
    const Eigen::Matrix3Xd& X = mo.xInit;
    const bool surface = typeName() == "VolumeFromTriangles";
    // The nearest topology that has the elements measured.
    FieldValue f;
    Component* topo = nullptr;
    for (const Node* n = &node(); n && !topo; n = n->parent())
      for (auto it = n->components().rbegin(); it != n->components().rend() && !topo; ++it)
        if (auto* t = dynamic_cast<Topology*>(it->get())) {
          scene().initComponent(**it);
          FieldValue tri, quad;
          const bool faces = ((*it)->field("triangles", tri) && !tri.values.empty()) || ((*it)->field("quads", quad) && !quad.values.empty());
          if (surface ? faces : (t->tetrahedra().cols() > 0 || !t->hexahedra().empty())) topo = it->get();
        }
    if (!topo)
      throw error(surface ? "no topology with triangles or quads in its node or above"
                          : "no topology with tetrahedra or hexahedra in its node or above");
    auto node = [&](double v) -> Eigen::Vector3d {
      const int i = static_cast<int>(v);
      if (i < 0 || i >= X.cols())
        throw error("the mesh refers to node " + std::to_string(i) + ", but the MechanicalObject has " +
                    std::to_string(X.cols()));
      return X.col(i);
    };
    auto tet = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
      return (b - a).dot((c - a).cross(d - a)) / 6.0;
    };
    double v = 0;
    if (surface) {
      if (topo->field("triangles", f)) {
        for (size_t k = 0; k + 3 <= f.values.size(); k += 3)
          v += tet(Eigen::Vector3d::Zero(), node(f.values[k]), node(f.values[k + 1]), node(f.values[k + 2]));
      }
      if (topo->field("quads", f)) {
        for (size_t k = 0; k + 4 <= f.values.size(); k += 4) {
          const Eigen::Vector3d a = node(f.values[k]), b = node(f.values[k + 1]), c = node(f.values[k + 2]), d = node(f.values[k + 3]);
          v += tet(Eigen::Vector3d::Zero(), a, b, c) + tet(Eigen::Vector3d::Zero(), a, c, d);
        }
      }
    } else {
      const auto* t = dynamic_cast<Topology*>(topo);
      const TetList& tets = t->tetrahedra();
      for (Eigen::Index e = 0; e < tets.cols(); ++e)
        v += std::abs(tet(node(tets(0, e)), node(tets(1, e)), node(tets(2, e)), node(tets(3, e))));
      // A hexahedron (SOFA's corner order) as six tetrahedra around its 0-6 diagonal.
      static const int split[6][4] = {{0, 5, 1, 6}, {0, 1, 3, 6}, {1, 3, 6, 2}, {6, 3, 0, 7}, {6, 7, 0, 5}, {7, 5, 4, 0}};
      for (const auto& h : t->hexahedra())
        for (const auto& s : split) v += std::abs(tet(node(h[s[0]]), node(h[s[1]]), node(h[s[2]]), node(h[s[3]])));
    }
    volume_ = std::abs(v);
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name != "volume") return false;
    out.values = {volume_};
    return true;
  }

 private:
  double volume_ = 0;
};

}  // namespace

void registerGeometryEngines(Registry& r) {
  {
    ComponentSpec s;
    s.name = "TransformEngine";
    s.category = "engine";
    s.doc = "Output field `output_position`: `input_position` scaled (scale3d), rotated (degrees about x, then y, then "
            "z) and translated, as a loader places its points; with `inverse` the inverse of that transform.";
    s.add(AttrSpec::reals("input_position").req().multipleOf(3).unit(Dimension::length()).linked().help("the points (a link such as @loader.position)"));
    addPointPlacementAttributes(s, "the points");
    s.add(AttrSpec::boolean("inverse").def("false").help("apply the inverse transform"));
    s.factory = [](BuildContext& c) { return std::make_unique<TransformEngine>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "TransformPosition";
    s.category = "engine";
    s.doc = "Output field `output_position`: `input_position` under the affine transform of an ITK transform file "
            "(method fromFile; .tfm with Parameters: the 3x3 matrix row by row, then the translation t, and "
            "FixedParameters: the centre c), y = A (x - c) + t + c.";
    s.add(AttrSpec::reals("input_position").req().multipleOf(3).unit(Dimension::length()).linked().help("the points"));
    s.add(AttrSpec::string("method").def("fromFile").help("how the transform is given: fromFile"));
    s.add(AttrSpec::file("filename").help("the transform file"));
    s.factory = [](BuildContext& c) { return std::make_unique<TransformPosition>(c); };
    r.add(std::move(s));
  }
  for (const bool surface : {true, false}) {
    ComponentSpec s;
    s.name = surface ? "VolumeFromTriangles" : "VolumeFromVolumetricElements";
    s.category = "engine";
    s.doc = surface ? "Output field `volume`: the volume the mesh's triangles and quads enclose (closed and consistently "
                      "oriented; divergence theorem), at the MechanicalObject's initial positions."
                    : "Output field `volume`: the summed volume of the mesh's tetrahedra and hexahedra, at the "
                      "MechanicalObject's initial positions.";
    s.add(AttrSpec::boolean("update").alias("doUpdate").def("false").help("SOFA's recomputation every step; only false (once, at the start)"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<VolumeEngine>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
