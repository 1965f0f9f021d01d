// SOFA's surface exporters: STLExporter (a surface given by position and triangle links, or the
// visual model in its node) and VisualModelOBJExporter (the visual models of its node and below,
// merged). Frames <filename>_<step>.stl / .obj are written whole (atomically) in the output folder,
// at the start, every N steps and at the end as asked.
#include <cstdio>
#include <filesystem>
#include <memory>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mapping/VisualModel.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/surface/SurfaceMesh.h"

namespace viscera {

namespace {

class SurfaceExporter : public Component, public Observer {
 public:
  using Component::Component;
  void init() override {
    every_ = static_cast<int>(attrs_.integer("exportEveryNumberOfSteps"));
    stl_ = typeName() == "STLExporter";
    if (stl_ && attrs_.isSet("position")) {
      // A fixed surface from links (a loader's points and triangles): a state or a visual model
      // moves, and is exported from beside it instead.
      const AttrValue& link = attrs_.get("position");
      if (link.link) {
        Component& source = scene().resolve(*this, link.text, link.loc, "STLExporter.position");
        if (dynamic_cast<MechanicalObject*>(&source) || dynamic_cast<VisualModel*>(&source))
          throw error("position", "links to '" + source.name() + "', which moves; put the exporter beside that visual model "
                                  "(without position and triangle) to export its surface as it moves");
      }
      const auto p = linkedReals("position");
      fixed_.points = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, static_cast<Eigen::Index>(p.size() / 3));
      if (!attrs_.isSet("triangle")) throw error("triangle", "goes with `position`: the surface's triangles");
      const auto t = linkedInts("triangle");
      fixed_.triangles.resize(3, static_cast<Eigen::Index>(t.size() / 3));
      for (size_t k = 0; k < t.size(); ++k) {
        if (t[k] < 0 || t[k] >= fixed_.points.cols())
          throw error("triangle", "refers to point " + std::to_string(t[k]) + ", but there are " +
                                      std::to_string(fixed_.points.cols()) + " points");
        fixed_.triangles(static_cast<Eigen::Index>(k % 3), static_cast<Eigen::Index>(k / 3)) = t[k];
      }
      hasFixed_ = true;
      return;
    }
    if (stl_ && attrs_.isSet("triangle")) throw error("triangle", "goes with `position`");
    // The visual models: the node's (STL) or those of the node and below (OBJ).
    std::vector<Component*> all;
    if (stl_) {
      if (auto* v = node().find<VisualModel>()) all.push_back(v);
    } else {
      node().collect(all);
    }
    for (Component* c : all)
      if (auto* v = dynamic_cast<VisualModel*>(c)) {
        scene().initComponent(*v);
        visuals_.push_back(v);
      }
    if (visuals_.empty())
      throw error(stl_ ? "no surface: give position and triangle, or put it beside an OglModel/VisualModel"
                       : "no OglModel/VisualModel in its node or below");
  }
  void begin(const State& s, double) override {
    std::string name = attrs_.isSet("filename") ? attrs_.str("filename") : this->name();
    if (scene().escapesOutputFolder(name))
      throw error("filename", "'" + name + "' would be written outside the output folder (--out); give a name inside it");
    base_ = scene().outputPath(name);
    last_ = -1;
    std::error_code ec;
    const std::filesystem::path dir = std::filesystem::path(base_).parent_path();
    if (!dir.empty()) std::filesystem::create_directories(dir, ec);
    if (ec) throw error("filename", "cannot create folder '" + dir.string() + "': " + ec.message());
    if (attrs_.boolean("exportAtBegin")) write(s, 0);
  }
  void observe(const State& s, double, int step) override {
    if (every_ > 0 && step % every_ == 0) write(s, step);
  }
  void end(const State& s, double, int step) override {
    if (attrs_.boolean("exportAtEnd") && last_ != step) write(s, step);
  }

 private:
  void write(const State& s, int step) {
    io::SurfaceMesh mesh = hasFixed_ ? fixed_ : io::SurfaceMesh{};
    if (!hasFixed_) {
      Eigen::Index points = 0, tris = 0;
      for (const VisualModel* v : visuals_) points += v->x(s).cols(), tris += v->triangles.cols();
      mesh.points.resize(3, points);
      mesh.triangles.resize(3, tris);
      Eigen::Index p = 0, t = 0;
      for (const VisualModel* v : visuals_) {
        mesh.points.middleCols(p, v->x(s).cols()) = v->x(s);
        mesh.triangles.middleCols(t, v->triangles.cols()) = v->triangles.array() + static_cast<int>(p);
        p += v->x(s).cols();
        t += v->triangles.cols();
      }
    }
    char num[32];
    std::snprintf(num, sizeof num, stl_ ? "_%06d.stl" : "_%06d.obj", step);
    try {
      io::writeSurface(base_ + num, mesh, stl_ && attrs_.boolean("binaryformat"));
    } catch (const Error& e) {
      throw error(e.what());
    }
    last_ = step;
  }

  bool stl_ = true, hasFixed_ = false;
  int every_ = 0, last_ = -1;
  io::SurfaceMesh fixed_;
  std::vector<const VisualModel*> visuals_;
  std::string base_;
};

void addExportAttributes(ComponentSpec& s) {
  s.add(AttrSpec::string("filename").help("base name of the files (default: the component's name)"));
  s.add(AttrSpec::integer("exportEveryNumberOfSteps").def("0").atLeast(0).help("write every N steps (0: only at begin/end)"));
  s.add(AttrSpec::boolean("exportAtBegin").def("false").help("write the initial surface"));
  s.add(AttrSpec::boolean("exportAtEnd").def("false").help("write the final surface"));
}

}  // namespace

void registerSurfaceExporters(Registry& r) {
  {
    ComponentSpec s;
    s.name = "STLExporter";
    s.category = "output";
    s.doc = "Writes a surface as STL frames <filename>_<step>.stl in the output folder (SOFA's STLExporter): the "
            "points and triangles its links give (fixed), or the visual model beside it as it moves.";
    addExportAttributes(s);
    s.add(AttrSpec::boolean("binaryformat").def("true").help("binary STL (false: ASCII)"));
    s.add(AttrSpec::reals("position").multipleOf(3).unit(Dimension::length()).linked().help("the surface's points (e.g. @loader.position)"));
    s.add(AttrSpec::ints("triangle").multipleOf(3).atLeast(0).linked().help("its triangles (e.g. @loader.triangles)"));
    s.factory = [](BuildContext& c) { return std::make_unique<SurfaceExporter>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "VisualModelOBJExporter";
    s.aliases = {"OBJExporter"};
    s.category = "output";
    s.doc = "Writes the visual models (OglModel/VisualModel) of its node and below, merged into one surface, as OBJ "
            "frames <filename>_<step>.obj in the output folder (SOFA's VisualModelOBJExporter).";
    addExportAttributes(s);
    s.factory = [](BuildContext& c) { return std::make_unique<SurfaceExporter>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
