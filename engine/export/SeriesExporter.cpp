#include "engine/export/SeriesExporter.h"

#include <algorithm>
#include <filesystem>
#include <sstream>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/mapping/VisualModel.h"
#include "engine/mechanics/MechanicalObject.h"

namespace viscera {

void SeriesExporter::init() {
  every_ = static_cast<int>(attrs_.integer("exportEveryNumberOfSteps"));
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
    if (f != "displacement" && f != "velocity" && f != "vonMises" && f != "force" && f != "plasticStrain")
      throw error("fields", "unknown field '" + f + "' (choose from displacement, velocity, force, vonMises, plasticStrain)");
    if (f == "vonMises" && !fem_) {
      if (!attrs_.isSet("fields")) continue;  // the default list has it only beside a tetrahedral FEM
      throw error("fields", "vonMises needs a TetrahedronFEMForceField in the node");
    }
    if (f == "plasticStrain" && !(fem_ && fem_->plasticity().on()))
      throw error("fields", "plasticStrain needs a TetrahedronFEMForceField with plasticity (plasticMaxThreshold > 0) in the node");
    fields_.push_back(f);
  }
  // SOFA's form: "object.data" names a data field of the exported state.
  std::istringstream data(attrs_.str("pointsDataFields"));
  for (std::string entry; data >> entry;) {
    const auto dot = entry.rfind('.');
    const std::string object = dot == std::string::npos ? state_->name() : entry.substr(0, dot);
    const std::string field = dot == std::string::npos ? entry : entry.substr(dot + 1);
    if (object != state_->name())
      throw error("pointsDataFields", "'" + entry + "': only fields of the exported MechanicalObject '" + state_->name() +
                                          "' can be written");
    if (field != "position" && field != "velocity" && field != "force" && field != "rest_position")
      throw error("pointsDataFields", "'" + entry + "': unknown field '" + field +
                                          "' (choose from position, velocity, force, rest_position)");
    if (std::find(fields_.begin(), fields_.end(), field) == fields_.end()) fields_.push_back(field);
  }
  // Only the arrays a frame needs are copied from the state.
  needV_ = std::find(fields_.begin(), fields_.end(), "velocity") != fields_.end();
  needF_ = std::find(fields_.begin(), fields_.end(), "force") != fields_.end();
  needP_ = std::find(fields_.begin(), fields_.end(), "plasticStrain") != fields_.end();
}

void SeriesExporter::begin(const State& s, double t) {
  // The frames an earlier run left queued (one that ended with an exception) are written first:
  // the writer reads the members set below.
  queue_.reset();
  // Unnamed, a surface exporter takes the visual model's name so that it does not share its
  // series with the body's exporter.
  const std::string fallback = visual_ ? visual_->name() : name();
  std::string file = attrs_.isSet("filename") ? attrs_.str("filename") : fallback;
  // SOFA's scenes name the files with an extension that the step number and .vtu follow.
  for (const char* ext : {".vtk", ".vtu", ".vtp", ".exo"})
    if (file.size() > 4 && file.compare(file.size() - 4, 4, ext) == 0) file.resize(file.size() - 4);
  if (scene().escapesOutputFolder(file))
    throw error("filename", "'" + file + "' would be written outside the output folder (--out); give a name inside it");
  base_ = scene().outputPath(file);
  std::filesystem::path dir = std::filesystem::path(base_).parent_path();
  std::error_code ec;
  if (!dir.empty()) std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(loc(), typeName() + ".filename: cannot create folder '" + dir.string() + "': " + ec.message());
  // What every frame shares, kept here: the writer thread reads nothing of other components
  // (they may be gone when it finishes the frames of a run that failed), the FEM's stresses
  // included.
  if (visual_) {
    rest_ = visual_->x0;
    triangles_ = visual_->triangles;
  } else {
    rest_ = state_->x0;
    tets_ = fem_ ? fem_->tetrahedra() : TetList();
    if (fem_) vonMises_ = fem_->vonMisesFunction();
  }
  lastStep_ = -1;
  kept_ = Frame{};
  startSeries();
  queue_ = std::make_unique<BackgroundQueue>();
  if (attrs_.boolean("exportAtBegin")) write(t, 0, current(s));
  else keep(s, 0);
}

void SeriesExporter::observe(const State& s, double t, int step) {
  if (!queue_) return;  // begin() failed
  if (every_ > 0 && step % every_ == 0) write(t, step, current(s));
  else keep(s, step);
}

void SeriesExporter::diverged(const State&, double t, int step) {
  // The state now holds the failed step: the last good one is written from its copy.
  if (queue_ && lastStep_ != step && kept_.step == step) write(t, step, kept_);
}

void SeriesExporter::end(const State& s, double t, int step) {
  if (!queue_) return;  // begin() failed, or this run has ended already
  if (attrs_.boolean("exportAtEnd") && lastStep_ != step) write(t, step, current(s));
  // The queue goes with this run: a later end() without a begin() writes nothing.
  const std::unique_ptr<BackgroundQueue> queue = std::move(queue_);
  queue->submit([this] { finishSeries(); });
  queue->flush();  // every frame on disk, or the first write error
}

SeriesExporter::Frame SeriesExporter::current(const State& s) const {
  Frame fr;
  fr.x = visual_ ? visual_->x(s) : state_->x(s);
  if (needV_) fr.v = state_->v(s);
  if (needF_) fr.f = state_->live(s).f;
  if (needP_) fr.plastic = fem_->plasticStrains(s).colwise().norm().transpose();
  return fr;
}

// A step not written is kept, so that a divergence on the next one can still export it (a copy
// of the node's arrays a step: small beside the step itself).
void SeriesExporter::keep(const State& s, int step) {
  if (every_ == 1) return;
  // Assigned in place: same sizes every step, so no allocation after the first.
  kept_.x = visual_ ? visual_->x(s) : state_->x(s);
  if (needV_) kept_.v = state_->v(s);
  if (needF_) kept_.f = state_->live(s).f;
  if (needP_) kept_.plastic = fem_->plasticStrains(s).colwise().norm().transpose();
  kept_.step = step;
}

// Frames are encoded, compressed and written beside the run, in order (a run's step goes on
// meanwhile); a write error comes back at the next frame or at the end.
void SeriesExporter::write(double t, int step, Frame fr) {
  if (!queue_) return;  // begin() failed
  lastStep_ = step;
  queue_->submit([this, t, step, fr = std::move(fr)] { writeFrame(t, step, fr); });
}

std::vector<SeriesExporter::Field> SeriesExporter::fieldsOf(const Frame& fr) const {
  std::vector<Field> out;
  for (const auto& f : fields_) {
    Field field;
    field.name = f;
    if (f == "vonMises") {
      field.onCells = true;
      field.cells = vonMises_(fr.x);
    } else if (f == "plasticStrain") {
      field.onCells = true;
      field.cells = fr.plastic;
    } else {
      field.points = f == "displacement"    ? Eigen::Matrix3Xd(fr.x - rest_)
                     : f == "position"      ? fr.x
                     : f == "rest_position" ? rest_
                     : f == "velocity"      ? fr.v
                                            : fr.f;
    }
    out.push_back(std::move(field));
  }
  return out;
}

void SeriesExporter::addCommonAttributes(ComponentSpec& s) {
  s.add(AttrSpec::integer("exportEveryNumberOfSteps").def("1").atLeast(0).help("write every N steps (0: only at begin/end)"));
  s.add(AttrSpec::boolean("exportAtBegin").def("true").help("write the initial state"));
  s.add(AttrSpec::boolean("exportAtEnd").def("false").help("write the final state"));
  s.add(AttrSpec::string("fields").def("displacement velocity vonMises").help("point fields displacement, velocity, force; cell fields vonMises (by default only beside a TetrahedronFEMForceField) and plasticStrain (the norm of each element's plastic strain, engineering shears, with SOFA's plasticity on); a visual surface: displacement only, its default"));
  s.add(AttrSpec::string("pointsDataFields").def("").help(
      "SOFA's form of extra point fields: object.field entries of the exported MechanicalObject (position, velocity, "
      "force, rest_position), written under the field's name"));
  s.add(AttrSpec::choice("precision", {"float32", "float64"}).def("float32").help(
      "how points and fields are stored: float32 (7 significant digits, half the size, as ParaView and SOFA write "
      "them) or float64 (every bit of the simulation's doubles)"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
}

}  // namespace viscera
