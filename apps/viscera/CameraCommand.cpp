// `viscera camera`: runs a scene and writes the frames of its DepthCamera(s). A scene without one
// gets a camera from the command-line options, added to its description as a DepthCamera element
// so that the options are validated by the component's own declarations.
#include "core/Files.h"
#include "builtin/Builtins.h"
#include "apps/viscera/CliText.h"
#include "apps/viscera/CameraCommand.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "engine/Run.h"
#include "engine/Simulation.h"
#include "core/Error.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "io/scene/SceneReader.h"

namespace viscera {
namespace {

const char* const kCameraTag = "DepthCamera";

struct CameraOptions {
  std::string scene, out;
  std::vector<std::string> sets;  // --set ADDRESS=VALUE edits of the scene
  double time = 0;
  int steps = -1;
  bool quiet = false;
  CameraOptionSet camera;
};

// Blanks for commas, so that "1,2,3" reads as "1 2 3".
std::string listText(std::string s) {
  std::replace(s.begin(), s.end(), ',', ' ');
  return s;
}


// Removes the scene's other outputs (exporters): this command writes camera frames only.
void dropOtherOutputs(ElementDesc& el, std::vector<std::string>& dropped) {
  auto& c = el.children;
  c.erase(std::remove_if(c.begin(), c.end(),
                         [&](const ElementDesc& e) {
                           const ComponentSpec* s = builtinRegistry().find(e.tag);
                           if (!s || s->category != "output") return false;
                           const AttrDesc* n = e.find("name");
                           dropped.push_back(e.loc.str() + ": note: " + e.tag + (n ? " '" + n->value + "'" : "") +
                                             " is not run: `viscera camera` writes camera frames only");
                           return true;
                         }),
          c.end());
  for (auto& ch : c) dropOtherOutputs(ch, dropped);
}


// "3 frames to out/camera (points per frame: min 1200, mean 1234.5, max 1300)".
std::string frameSummary(Component& camera, const Scene& scene) {
  FieldValue frames, points, empty;
  camera.field("frames", frames);
  camera.field("points", points);
  camera.field("emptyFrames", empty);
  // The folder rule of the DepthCamera component: `filename`, else the component's name.
  const std::string folder =
      scene.outputPath(camera.attrs().isSet("filename") ? camera.attrs().str("filename") : camera.name());
  const long n = std::lround(frames.values.at(0));
  std::ostringstream s;
  s << "camera '" << camera.name() << "': wrote " << n << " frame" << (n == 1 ? "" : "s") << " to " << folder;
  if (!points.values.empty()) {
    const auto [lo, hi] = std::minmax_element(points.values.begin(), points.values.end());
    double sum = 0;
    for (double p : points.values) sum += p;
    s << " (points per frame: min " << *lo << ", mean " << sum / static_cast<double>(points.values.size()) << ", max "
      << *hi << ")";
  }
  const long e = std::lround(empty.values.at(0));
  if (e > 0) s << "; " << e << " frame" << (e == 1 ? "" : "s") << " without points not written";
  return s.str();
}

int runCamera(const CameraOptions& o) {
  SceneDesc desc = io::readScene(o.scene);
  for (const auto& a : o.sets) desc.applySetting(a);
  std::vector<std::string> notes;
  dropOtherOutputs(desc.root, notes);
  o.camera.apply(desc);

  auto scene = buildScene(desc);
  scene->setOutputDirectory(o.out);
  Simulation sim(*scene);  // initialises: every input error surfaces before anything is written
  if (!o.quiet) {
    for (const auto& n : notes) std::cerr << n << "\n";
    cli::printNotes(scene->notes());
  }
  const FolderLock lock(o.out);  // the cameras' frames: one run at a time
  RunOptions ro;
  if (o.steps >= 0) ro.steps = o.steps;
  else ro.time = o.time;
  ro.recordWrench = false;
  ProgressLine progress;
  if (!o.quiet) ro.observers.push_back(&progress);
  const RunResult r = run(sim, ro);

  for (Component* c : scene->all<Component>())
    if (c->typeName() == kCameraTag) std::cerr << frameSummary(*c, *scene) << "\n";
  if (r.failure) {
    std::cerr << o.scene << ": " << r.failure->str() << "\n";
    return kExitDiverged;
  }
  if (!o.quiet)
    std::cerr << "ran " << sim.steps() << " step" << (sim.steps() == 1 ? "" : "s") << " to t = " << sim.time() << "\n";
  return kExitOk;
}

}  // namespace

bool hasDepthCamera(const ElementDesc& el) {
  if (el.tag == kCameraTag) return true;
  return std::any_of(el.children.begin(), el.children.end(), hasDepthCamera);
}

CameraOptionSet::CameraOptionSet() {
  attributes_ = {
      {"--position", "position", "camera centre \"x y z\" (scene frame, scene units)"},
      {"--look-at", "lookAt", "point the camera looks at \"x y z\""},
      {"--up", "up", "scene direction that is up in the image (default \"0 0 1\")"},
      {"--transform", "transform", "camera -> scene transform file, instead of --position/--look-at/--up"},
      {"--width", "width", "image width in pixels (640)"},
      {"--height", "height", "image height in pixels (480)"},
      {"--fov", "fov", "horizontal field of view in degrees (60)"},
      {"--fx", "fx", "focal length in pixels, instead of --fov"},
      {"--fy", "fy", "vertical focal length in pixels (default fx)"},
      {"--cx", "cx", "principal point column (default (width - 1) / 2)"},
      {"--cy", "cy", "principal point row (default (height - 1) / 2)"},
      {"--near", "near", "nearest depth measured (0.2 m)"},
      {"--far", "far", "farthest depth measured (1.5 m)"},
      {"--rate", "rate", "frames per unit of simulated time (30 Hz)"},
      {"--sigma0", "sigma0", "depth noise standard deviation at z0 (2 mm; 0: none)"},
      {"--z0", "z0", "distance at which the depth noise is sigma0 (400 mm)"},
      {"--dropout", "dropout", "probability that a pixel gives no point (0.01)"},
      {"--grazing-angle", "grazingAngle", "largest incidence angle giving a point, degrees (80)"},
      {"--depth-unit", "depthUnit", "depth quantisation step (0.125 mm; 0: none)"},
      {"--seed", "seed", "random seed of the noise (1)"},
      {"--stride", "stride", "keep every stride-th pixel of every stride-th row (1)"},
      {"--frame", "frame", "frame of the points: camera or scene (camera)"},
      {"--format", "format", "file format of the frames: pcd or ply (pcd)"},
      {"--table", "table", "infinite table plane \"nx ny nz d\" (n . x = d)"},
  };
}

void CameraOptionSet::declare(CLI::App& cmd) {
  nameOption_ = cmd.add_option("--name", name, "name of the added camera, and its folder under --out (camera)");
  for (AttributeOption& a : attributes_) a.option = cmd.add_option(a.flag, a.value, a.help);
  asciiFlag_ = cmd.add_flag("--ascii", ascii_, "ASCII files instead of binary");
  tissueFlag_ = cmd.add_flag("--tissue-only", tissueOnly, "keep only the points on the tissue");
}

void CameraOptionSet::apply(SceneDesc& desc, const std::map<std::string, std::string>& defaults) const {
  std::vector<std::string> given;
  // Options never declared (a set used from code, not a command line) count as not given.
  for (const AttributeOption& a : attributes_)
    if (a.option && a.option->count() > 0) given.push_back(a.flag);
  for (const CLI::Option* f : {asciiFlag_, tissueFlag_, nameOption_})
    if (f && f->count() > 0) given.push_back(f->get_name());
  if (hasDepthCamera(desc.root)) {
    if (!given.empty())
      throw Error(SourceLoc{desc.file}, "the scene has its own DepthCamera; camera options (" + given.front() +
                                            (given.size() > 1 ? ", ..." : "") + ") apply only to scenes without one");
    return;
  }
  const bool placed = std::any_of(attributes_.begin(), attributes_.end(), [](const AttributeOption& a) {
    const std::string attr = a.attribute;
    return (attr == "position" || attr == "lookAt" || attr == "transform") && a.option && a.option->count() > 0;
  });
  if (!placed)
    throw Error(SourceLoc{desc.file}, "the scene has no DepthCamera; place one with --position and --look-at (or --transform)");
  // Each attribute's location names its option, so that errors read "--fov: DepthCamera.fov: ...".
  ElementDesc el;
  el.tag = kCameraTag;
  el.loc = SourceLoc{"camera options"};
  el.attrs.push_back({"name", name, SourceLoc{"--name"}});
  for (const AttributeOption& a : attributes_) {
    if (!a.option || a.option->count() == 0) continue;
    std::string value = listText(a.value);
    // A transform file given on the command line is relative to the working folder, not the scene.
    if (std::string(a.attribute) == "transform") value = std::filesystem::absolute(a.value).string();
    el.attrs.push_back({a.attribute, value, SourceLoc{a.flag}});
  }
  if (ascii_) el.attrs.push_back({"binary", "false", SourceLoc{"--ascii"}});
  if (tissueOnly) el.attrs.push_back({"tissueOnly", "true", SourceLoc{"--tissue-only"}});
  for (const auto& [attr, value] : defaults)
    if (!el.find(attr)) el.attrs.push_back({attr, value, SourceLoc{"default of this command"}});
  desc.root.children.push_back(std::move(el));
}

void addCameraCommand(CLI::App& app, std::function<int()>& action) {
  auto o = std::make_shared<CameraOptions>();
  auto* cmd = app.add_subcommand("camera", "run a scene and write the point clouds of its depth camera(s)");
  cmd->footer(
      "Frames go to OUT/<camera name>/frame_<k>.pcd with an index.csv (time in seconds, file). A scene without a\n"
      "DepthCamera gets one from the camera options (--position and --look-at, or --transform); the others default\n"
      "to a RealSense SR300-like camera. Lengths are plain numbers in the scene's units or carry a unit (\"2 mm\");\n"
      "vectors are \"x y z\" or x,y,z. The scene's exporters are not run.");
  cmd->add_option("scene", o->scene, "scene file (.xml or SOFA .scn)")->required();
  cmd->add_option("--out", o->out, "output folder")->required();
  auto* steps = cmd->add_option("--steps", o->steps, "number of steps to run")->check(CLI::NonNegativeNumber);
  cmd->add_option("--time", o->time, "simulated time to run, in the scene's time unit (default 0: the rest state only)")
      ->check(CLI::NonNegativeNumber)
      ->excludes(steps);
  cmd->add_flag("--quiet", o->quiet, "no notes or run summary (the frame summary is still printed)");
  cmd->add_option("--set", o->sets, "set a scene attribute, ADDRESS=VALUE (node/path/component.attribute); repeatable");
  o->camera.declare(*cmd);
  cmd->callback([o, &action] { action = [o] { return runCamera(*o); }; });
}

}  // namespace viscera
