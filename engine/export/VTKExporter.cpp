// VTKExporter: writes the MechanicalObject of its node as a .vtu series with a .pvd index
// (ParaView), with point fields displacement and velocity and the cell field vonMises; in a node
// with a visual model (OglModel/VisualModel), that surface as a .vtp series with displacement.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>

#include "core/Background.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/mapping/VisualModel.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/mesh/Mesh.h"

namespace viscera {

namespace {

class VTKExporter : public Component, public Observer {
 public:
  using Component::Component;
  void init() override {
    every_ = static_cast<int>(attrs_.integer("exportEveryNumberOfSteps"));
    // Compressed frames also store connectivity and offsets as Int32; uncompressed ones keep the
    // plain Int64 layout.
    options_.compress = options_.int32Indices = attrs_.boolean("compress");
    options_.float32 = attrs_.str("precision") == "float32";
    // Placed beside a visual model in a node without a MechanicalObject (SOFA's visual child
    // node), the exporter writes that surface, unless `mstate` names a MechanicalObject to write.
    if (!attrs_.isSet("mstate") && !node().find<MechanicalObject>()) visual_ = node().find<VisualModel>();
    if (visual_) {
      scene().initComponent(*visual_);
      if (!attrs_.str("pointsDataFields").empty())
        throw error("pointsDataFields", "a visual surface '" + visual_->name() + "' is written with its displacement only");
      // The surface's points carry only their displacement (the default for it).
      std::istringstream in(attrs_.isSet("fields") ? attrs_.str("fields") : "displacement");
      for (std::string f; in >> f;) {
        if (f != "displacement")
          throw error("fields", "'" + f + "' is not a field of the visual surface '" + visual_->name() +
                                    "' (it has displacement only)");
        fields_.push_back(f);
      }
      return;
    }
    state_ = &contextState(*this);
    fem_ = node().find<TetrahedronFEMForceField>();
    if (fem_) scene().initComponent(*fem_);
    std::istringstream in(attrs_.str("fields"));
    for (std::string f; in >> f;) {
      if (f != "displacement" && f != "velocity" && f != "vonMises" && f != "force")
        throw error("fields", "unknown field '" + f + "' (choose from displacement, velocity, force, vonMises)");
      if (f == "vonMises" && !fem_) {
        if (!attrs_.isSet("fields")) continue;  // the default list has it only beside a tetrahedral FEM
        throw error("fields", "vonMises needs a TetrahedronFEMForceField in the node");
      }
      fields_.push_back(f);
    }
    // SOFA's form: "object.data" names a data field of the exported state.
    std::istringstream data(attrs_.str("pointsDataFields"));
    for (std::string entry; data >> entry;) {
      const auto dot = entry.rfind('.');
      const std::string object = dot == std::string::npos ? state_->name() : entry.substr(0, dot);
      const std::string field = dot == std::string::npos ? entry : entry.substr(dot + 1);
      if (object != state_->name())
        throw error("pointsDataFields", "'" + entry + "': only fields of the exported MechanicalObject '" +
                                            state_->name() + "' can be written");
      if (field != "position" && field != "velocity" && field != "force" && field != "rest_position")
        throw error("pointsDataFields", "'" + entry + "': unknown field '" + field +
                                            "' (choose from position, velocity, force, rest_position)");
      if (std::find(fields_.begin(), fields_.end(), field) == fields_.end()) fields_.push_back(field);
    }
  }
  void begin(const State& s, double t) override {
    // Unnamed, a surface exporter takes the visual model's name so that it does not share its
    // .pvd with the body's exporter.
    const std::string fallback = visual_ ? visual_->name() : name();
    std::string name = attrs_.isSet("filename") ? attrs_.str("filename") : fallback;
    // SOFA's scenes name the files with an extension that the step number and .vtu follow.
    for (const char* ext : {".vtk", ".vtu", ".vtp"})
      if (name.size() > 4 && name.compare(name.size() - 4, 4, ext) == 0) name.resize(name.size() - 4);
    if (scene().escapesOutputFolder(name))
      throw error("filename", "'" + name + "' would be written outside the output folder (--out); give a name inside it");
    base_ = scene().outputPath(name);
    std::filesystem::path dir = std::filesystem::path(base_).parent_path();
    std::error_code ec;
    if (!dir.empty()) std::filesystem::create_directories(dir, ec);
    if (ec) throw Error(loc(), "VTKExporter.filename: cannot create folder '" + dir.string() + "': " + ec.message());
    // What every frame shares, kept here: the writer thread reads nothing of other components
    // (they may be gone when it finishes the frames of a run that failed), the FEM's stresses
    // included. A volume's tetrahedra are encoded and compressed once.
    if (visual_) {
      rest_ = visual_->x0;
      triangles_ = visual_->triangles;
    } else {
      rest_ = state_->x0;
      static const TetList none;
      tets_ = fem_ ? fem_->tetrahedra() : none;
      if (fem_) vonMises_ = fem_->vonMisesFunction();
      cells_ = io::encodeVtuCells(tets_, options_);
      options_.encodedCells = &cells_;
    }
    queue_ = std::make_unique<BackgroundQueue>();
    if (attrs_.boolean("exportAtBegin")) write(t, 0, current(s));
    else keep(s, 0);
  }
  void observe(const State& s, double t, int step) override {
    if (every_ > 0 && step % every_ == 0) write(t, step, current(s));
    else keep(s, step);
  }
  void diverged(const State&, double t, int step) override {
    // The state now holds the failed step: the last good one is written from its copy.
    if (lastStep_ != step && kept_.step == step) write(t, step, kept_);
  }
  void end(const State& s, double t, int step) override {
    if (attrs_.boolean("exportAtEnd") && lastStep_ != step) write(t, step, current(s));
    if (queue_) queue_->flush();  // every frame on disk, or the first write error
  }

 private:
  // What a frame is written from: positions (and, for a volume, velocities and forces).
  struct Frame {
    int step = -1;
    Eigen::Matrix3Xd x, v, f;
  };
  Frame current(const State& s) const {
    Frame fr;
    fr.x = visual_ ? visual_->x(s) : state_->x(s);
    if (!visual_) fr.v = state_->v(s), fr.f = state_->live(s).f;
    return fr;
  }
  // A step not written is kept, so that a divergence on the next one can still export it
  // (a copy of the node's arrays a step: small beside the step itself).
  void keep(const State& s, int step) {
    if (every_ == 1) return;
    // Assigned in place: same sizes every step, so no allocation after the first.
    kept_.x = visual_ ? visual_->x(s) : state_->x(s);
    if (!visual_) kept_.v = state_->v(s), kept_.f = state_->live(s).f;
    kept_.step = step;
  }

  // Frames are encoded, compressed and written beside the run, in order (a run's step goes on
  // meanwhile); a write error comes back at the next frame or at the end.
  void write(double t, int step, Frame fr) {
    lastStep_ = step;
    queue_->submit([this, t, step, fr = std::move(fr)] { writeNow(t, step, fr); });
  }
  void writeNow(double t, int step, const Frame& fr) {
    char num[32];
    std::snprintf(num, sizeof num, visual_ ? "_%06d.vtp" : "_%06d.vtu", step);
    const std::string file = base_ + num;
    if (visual_) writeSurface(file, fr);
    else writeVolume(file, fr);
    written_.push_back({t, std::filesystem::path(file).filename().string()});
    // The index is rewritten each time so that an interrupted run still opens in ParaView.
    io::writePvd(base_ + ".pvd", written_);
  }

  void writeSurface(const std::string& file, const Frame& fr) {
    std::vector<io::DataArray> pd;
    if (!fields_.empty()) {
      const Eigen::Matrix3Xd d = fr.x - rest_;
      pd.push_back({"displacement", 3, std::vector<double>(d.data(), d.data() + d.size())});
    }
    io::writeVtp(file, fr.x, triangles_, false, pd, options_);
  }

  void writeVolume(const std::string& file, const Frame& fr) {
    std::vector<io::DataArray> pd, cd;
    for (const auto& f : fields_) {
      if (f == "vonMises") {
        const Eigen::VectorXd vm = vonMises_(fr.x);
        cd.push_back({"vonMises", 1, std::vector<double>(vm.data(), vm.data() + vm.size())});
        continue;
      }
      const Eigen::Matrix3Xd m = f == "displacement"    ? Eigen::Matrix3Xd(fr.x - rest_)
                                 : f == "position"      ? fr.x
                                 : f == "rest_position" ? rest_
                                 : f == "velocity"      ? fr.v
                                                        : fr.f;
      pd.push_back({f, 3, std::vector<double>(m.data(), m.data() + m.size())});
    }
    io::writeVtu(file, fr.x, tets_, pd, cd, options_);
  }

  MechanicalObject* state_ = nullptr;
  TetrahedronFEMForceField* fem_ = nullptr;
  VisualModel* visual_ = nullptr;  // set when writing a visual surface instead of the state
  int every_ = 1;
  io::VtuWriteOptions options_;
  Eigen::Matrix3Xd rest_;  // the rest positions displacements are measured from
  TetList tets_;           // a volume's tetrahedra
  TriangleList triangles_; // a surface's triangles
  std::string cells_;      // the encoded <Cells> of every volume frame
  std::function<Eigen::VectorXd(const Eigen::Matrix3Xd&)> vonMises_;  // stresses, from a copy of the FEM's rest data
  int lastStep_ = -1;  // the last step handed to the writer
  std::vector<std::string> fields_;
  std::string base_;
  std::vector<std::pair<double, std::string>> written_;  // by the writer
  Frame kept_;
  std::unique_ptr<BackgroundQueue> queue_;  // last: finishes its frames before the rest goes
};

}  // namespace

void registerVTKExporter(Registry& r) {
  ComponentSpec s;
  s.name = "VTKExporter";
  s.category = "output";
  s.doc = "Writes the node's MechanicalObject (with the tetrahedra of its FEM force field) as a .vtu series "
          "and a .pvd index for ParaView. Files are <filename>_<step>.vtu in the output folder (--out). In a node "
          "with an OglModel/VisualModel and no MechanicalObject (a visual child node; `mstate` not set), writes that "
          "surface instead: <filename>_<step>.vtp with its triangles and the point field displacement. A run that "
          "diverges between export steps still writes its last good step.";
  s.add(AttrSpec::string("filename").help("base name of the files (default: the component's name; beside a visual model, that model's name); an extension .vtk, .vtu or .vtp is dropped"));
  s.add(AttrSpec::integer("exportEveryNumberOfSteps").def("1").atLeast(0).help("write every N steps (0: only at begin/end)"));
  s.add(AttrSpec::boolean("exportAtBegin").def("true").help("write the initial state"));
  s.add(AttrSpec::boolean("exportAtEnd").def("false").help("write the final state"));
  s.add(AttrSpec::string("fields").def("displacement velocity vonMises").help("point fields displacement, velocity, force; cell field vonMises (by default only beside a TetrahedronFEMForceField; a visual surface: displacement only, its default)"));
  s.add(AttrSpec::string("pointsDataFields").def("").help(
      "SOFA's form of extra point fields: object.field entries of the exported MechanicalObject (position, velocity, "
      "force, rest_position), written under the field's name"));
  s.add(AttrSpec::boolean("compress").def("true").help(
      "zlib-compress the arrays (vtkZLibDataCompressor, read by ParaView and VTK) with Int32 connectivity; "
      "false: plain base64 binary with Int64 connectivity"));
  s.add(AttrSpec::choice("precision", {"float32", "float64"}).def("float32").help(
      "how points and fields are stored: float32 (7 significant digits, half the size, as ParaView and SOFA write "
      "them) or float64 (every bit of the simulation's doubles)"));
  s.add(AttrSpec::boolean("XMLformat").def("true").help("accepted for SOFA compatibility; output is always VTK XML (.vtu, .vtp for a visual surface)"));
  s.add(AttrSpec::string("position").def("").help("accepted for SOFA compatibility; the node's positions are written"));
  s.add(AttrSpec::boolean("edges").def("false").help("accepted for SOFA compatibility"));
  s.add(AttrSpec::boolean("quads").def("false").help("accepted for SOFA compatibility; a visual surface is written with its triangles"));
  s.add(AttrSpec::boolean("triangles").def("false").help("accepted for SOFA compatibility; a visual surface is written with its triangles"));
  s.add(AttrSpec::boolean("tetras").def("true").help("accepted for SOFA compatibility; tetrahedra are written"));
  s.add(AttrSpec::boolean("overwrite").def("false").help("accepted for SOFA compatibility"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
  s.factory = [](BuildContext& c) { return std::make_unique<VTKExporter>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
