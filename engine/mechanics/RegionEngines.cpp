// SphereROI (the nodes and tetrahedra inside spheres), PairBoxROI and IndexValueMapper (a value written at
// those indices): with them a scene gives a region of the tissue its own Young's modulus, as SOFA
// scenes do, e.g. youngModulus="@young.outputValues".
#include <algorithm>
#include <cmath>
#include <Eigen/Geometry>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/topology/GridSplit.h"

namespace viscera {

namespace {

// The points a region selects from: its `position` if given, else the rest positions of the
// node's MechanicalObject, as SOFA tests them.
Eigen::Matrix3Xd testedPoints(Component& c) {
  if (!c.attrs().isSet("position")) return contextState(c).x0;
  const auto p = c.linkedReals("position");
  return Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, static_cast<Eigen::Index>(p.size() / 3));
}

class SphereROI : public Component {
 public:
  using Component::Component;
  void init() override {
    const Eigen::Matrix3Xd X = testedPoints(*this);
    const auto& c = attrs_.reals("centers");
    const auto& r = attrs_.reals("radii");
    if (r.size() != c.size() / 3 && r.size() != 1)
      throw error("radii", "expected one radius or one per centre (" + std::to_string(c.size() / 3) + "), got " +
                               std::to_string(r.size()));
    auto inside = [&](const Eigen::Vector3d& p) {
      for (size_t k = 0; k + 3 <= c.size(); k += 3) {
        const double rad = r.size() == 1 ? r[0] : r[k / 3];
        if ((p - Eigen::Vector3d(c[k], c[k + 1], c[k + 2])).squaredNorm() <= rad * rad) return true;
      }
      return false;
    };
    std::vector<char> in(static_cast<size_t>(X.cols()), 0);
    for (Eigen::Index i = 0; i < X.cols(); ++i)
      if (inside(X.col(i))) {
        in[static_cast<size_t>(i)] = 1;
        nodes_.push_back(static_cast<int>(i));
      }
    // A tetrahedron is inside when its four vertices are (SOFA's rule). Its indices follow the
    // tetrahedra a TetrahedronFEMForceField in the same node builds.
    if (attrs_.boolean("computeTetrahedra")) {
      const TetList tets = elementTetrahedra(contextTopology(*this));
      for (Eigen::Index e = 0; e < tets.cols(); ++e) {
        bool all = true;
        for (int k = 0; k < 4; ++k) {
          const int v = tets(k, e);
          if (v < 0 || v >= X.cols()) throw error("tetrahedron " + std::to_string(e) + " refers to node " + std::to_string(v) + ", outside the positions tested");
          all = all && in[static_cast<size_t>(v)];
        }
        if (all) tetrahedra_.push_back(static_cast<int>(e));
      }
    }
    if (nodes_.empty() && attrs_.boolean("strict"))
      throw error("centers", "the spheres select no point (set strict=\"false\" to allow an empty selection)");
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "indices") {
      out.values.assign(nodes_.begin(), nodes_.end());
      return true;
    }
    if (name == "tetrahedronIndices") {
      if (!attrs_.boolean("computeTetrahedra")) return false;
      out.values.assign(tetrahedra_.begin(), tetrahedra_.end());
      return true;
    }
    return false;
  }

 private:
  std::vector<int> nodes_, tetrahedra_;
};

// SOFA's PairBoxROI: the points inside one box and not inside another (a frame of the region's
// boundary, as the patch tests use it). Both boxes are closed.
class PairBoxROI : public Component {
 public:
  using Component::Component;
  void init() override {
    const Eigen::Matrix3Xd X = testedPoints(*this);
    auto box = [&](const char* name) {
      const auto& b = attrs_.reals(name);
      Eigen::AlignedBox3d B;
      B.extend(Eigen::Vector3d(b[0], b[1], b[2]));
      B.extend(Eigen::Vector3d(b[3], b[4], b[5]));  // corners in either order, as SOFA swaps them
      return B;
    };
    const Eigen::AlignedBox3d outer = box("inclusiveBox"), inner = box("includedBox");
    for (Eigen::Index i = 0; i < X.cols(); ++i)
      if (outer.contains(X.col(i)) && !inner.contains(X.col(i))) {
        nodes_.push_back(static_cast<int>(i));
        for (int a = 0; a < 3; ++a) points_.push_back(X(a, i));
      }
    if (nodes_.empty() && attrs_.boolean("strict"))
      throw error("inclusiveBox", "the boxes select no point (set strict=\"false\" to allow an empty selection)");
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "indices") out.values.assign(nodes_.begin(), nodes_.end());
    else if (name == "pointsInROI" || name == "pointsInBox") out.values = points_;
    else return false;
    return true;
  }

 private:
  std::vector<int> nodes_;
  std::vector<double> points_;
};

class IndexValueMapper : public Component {
 public:
  using Component::Component;
  void init() override {
    out_ = attrs_.isSet("inputValues") ? linkedReals("inputValues") : std::vector<double>{};
    const std::vector<int> idx = linkedInts("indices");
    int top = 0;
    for (int i : idx) top = std::max(top, i + 1);
    if (static_cast<int>(out_.size()) < top) out_.resize(static_cast<size_t>(top), attrs_.real("defaultValue"));
    const double v = attrs_.real("value");
    for (int i : idx) out_[static_cast<size_t>(i)] = v;
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name != "outputValues") return false;
    out.values = out_;
    return true;
  }

 private:
  std::vector<double> out_;
};

}  // namespace

void registerRegionEngines(Registry& r) {
  {
    ComponentSpec s;
    s.name = "SphereROI";
    s.category = "engine";
    s.doc = "Selects the nodes inside one or more spheres (rest positions), output field `indices`, and the "
            "tetrahedra whose four vertices are inside, output field `tetrahedronIndices` (numbered as the "
            "node's TetrahedronFEMForceField numbers them).";
    s.add(AttrSpec::reals("centers").def("0 0 0").multipleOf(3).unit(Dimension::length()).help("centre of each sphere"));
    s.add(AttrSpec::reals("radii").def("1").atLeast(0).unit(Dimension::length()).help("one radius, or one per centre"));
    s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("points to test (default: rest positions of the node's MechanicalObject)"));
    s.add(AttrSpec::boolean("computeTetrahedra").def("true").help("also select tetrahedra (needs a topology in the node)"));
    s.add(AttrSpec::boolean("strict").def("false").help("fail if the spheres select nothing"));
    s.add(AttrSpec::link("topology").help("tetrahedral topology (default: the last one in the node, or the grid)"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<SphereROI>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "PairBoxROI";
    s.category = "engine";
    s.doc = "Selects the points inside `inclusiveBox` and not inside `includedBox` (both closed; rest positions): "
            "output fields `indices` and `pointsInROI` (their positions).";
    s.add(AttrSpec::reals("inclusiveBox", 6).req().unit(Dimension::length()).help("xmin ymin zmin xmax ymax zmax of the box the points are in"));
    s.add(AttrSpec::reals("includedBox", 6).req().unit(Dimension::length()).help("xmin ymin zmin xmax ymax zmax of the box they are not in"));
    s.add(AttrSpec::reals("position").alias("rest_position").multipleOf(3).unit(Dimension::length()).linked().help(
        "points to test (default: rest positions of the node's MechanicalObject)"));
    s.add(AttrSpec::boolean("strict").def("false").help("fail if the boxes select nothing"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<PairBoxROI>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "IndexValueMapper";
    s.category = "engine";
    s.doc = "Writes `value` at `indices` of `inputValues` (grown with `defaultValue` to reach the largest index); "
            "output field `outputValues`. Chained, it gives regions of a mesh their own per-element values, e.g. "
            "youngModulus=\"@young.outputValues\" on a TetrahedronFEMForceField. Values are numbers in the scene's "
            "units of the attribute that reads them.";
    s.add(AttrSpec::ints("indices").def("").atLeast(0).linked().help("indices to set (or a link such as @roi.tetrahedronIndices)"));
    s.add(AttrSpec::real("value").def("0").help("the value written at the indices"));
    s.add(AttrSpec::reals("inputValues").linked().help("values to start from (or a link such as @other.outputValues)"));
    s.add(AttrSpec::real("defaultValue").def("1").help("value of entries added to reach the largest index"));
    s.factory = [](BuildContext& c) { return std::make_unique<IndexValueMapper>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
