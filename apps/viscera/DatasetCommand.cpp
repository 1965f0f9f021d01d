// `viscera dataset make`: runs a (ground-truth) scene with its instrument and a depth camera and
// writes a dataset folder (study/Dataset.h): the instrument's trajectory as it was driven, the
// camera's frames, the camera pose and the contact wrench with sensor-like noise. The folder is
// written under a temporary name and renamed when complete, so a dataset is whole or absent.
// `viscera dataset check`: validates a dataset and prints what it holds.
#include "apps/viscera/CliText.h"
#include "apps/viscera/DatasetCommand.h"

#include <CLI/CLI.hpp>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <random>
#include <sstream>

#include "apps/viscera/CameraCommand.h"
#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "core/Units.h"
#include "engine/Run.h"
#include "engine/Simulation.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "io/scene/Transform.h"
#include "motion/Trajectory.h"
#include "study/Dataset.h"
#include "study/Replay.h"

namespace viscera {
namespace {

namespace fs = std::filesystem;

// Records the instrument's pose at the start and after every step: the trajectory it followed,
// in the scene frame, whatever drove it.
class PoseRecorder : public RunObserver {
 public:
  explicit PoseRecorder(const RigidObject& body) : body_(body) {}
  void begin(const Simulation& sim, int) override { record(sim); }
  void step(const Simulation& sim) override { record(sim); }
  motion::Trajectory trajectory;

 private:
  void record(const Simulation& sim) {
    const RigidObject::Live& b = body_.live(sim.state());
    trajectory.add(sim.time(), b.p, b.q);
  }
  const RigidObject& body_;
};

double quantity(const std::string& text, const Dimension& dim, const UnitSystem& units, const std::string& option) {
  try {
    double v = 0;
    std::string unit;
    const size_t used = parseNumberPrefix(text, v);
    if (used == 0) throw std::invalid_argument("is not a number (e.g. \"0.01 N\")");
    unit = text.substr(used);
    const auto b = unit.find_first_not_of(' ');
    unit = b == std::string::npos ? "" : unit.substr(b);
    if (!unit.empty()) v = units.convert(v, parseUnit(unit), dim);
    if (!(std::isfinite(v) && v >= 0)) throw std::invalid_argument("must be a finite number >= 0");
    return v;
  } catch (const std::invalid_argument& e) {
    throw Error(option + ": " + viscera::quoted(text) + ": " + e.what());
  }
}

std::string exact(double t) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", t);
  return buf;
}

std::string wrenchTable(const RunResult::Instrument& in, double forceSigma, double torqueSigma, unsigned seed) {
  std::mt19937_64 rng(seed ^ 0x5bd1e995u);
  std::normal_distribution<double> n(0.0, 1.0);
  std::ostringstream s;
  s.precision(10);
  s << "t,fx,fy,fz,tx,ty,tz\n";
  for (const WrenchSample& w : in.history) {
    Eigen::Vector3d f = w.force, t = w.torque;
    for (int i = 0; i < 3; ++i) f[i] += forceSigma * n(rng);
    for (int i = 0; i < 3; ++i) t[i] += torqueSigma * n(rng);
    s << exact(w.t) << "," << f.x() << "," << f.y() << "," << f.z() << "," << t.x() << "," << t.y() << "," << t.z() << "\n";
  }
  return s.str();
}

}  // namespace

int makeDataset(const DatasetMakeOptions& o) {
  if (fs::exists(o.out)) throw Error(SourceLoc{o.out}, "--out: already exists; a dataset is written to a new folder (nothing was changed)");
  const fs::path parent = fs::absolute(o.out).parent_path();
  if (!fs::is_directory(parent)) throw Error(SourceLoc{o.out}, "--out: the folder " + parent.string() + " does not exist");

  SceneDesc desc = io::readScene(o.scene);
  for (const auto& a : o.sets) desc.applySetting(a);
  study::removeOutputs(desc.root, false);  // exporters write files of their own; the camera stays
  o.camera.apply(desc, {{"rate", "10"}, {"tissueOnly", "true"}, {"filename", "camera"}});
  if (hasDepthCamera(desc.root) && desc.root.children.back().tag != "DepthCamera") {
    // The scene's own camera: its frames go to the dataset's camera folder.
    std::function<void(ElementDesc&)> place = [&](ElementDesc& el) {
      if (el.tag == "DepthCamera") el.set("filename", "camera", SourceLoc{"dataset make"});
      for (auto& c : el.children) place(c);
    };
    place(desc.root);
  }

  auto scene = buildScene(desc);
  const UnitSystem& units = scene->units();
  const double forceSigma = quantity(o.forceNoise, Dimension::force(), units, "--force-noise");
  const double torqueSigma = quantity(o.torqueNoise, {2, 1, -2}, units, "--torque-noise");
  const fs::path temp = fs::path(o.out).string() + ".tmp-" + std::to_string(::getpid());
  fs::remove_all(temp);
  scene->setOutputDirectory(temp.string());
  Simulation sim(*scene);
  auto bodies = scene->all<RigidObject>();
  if (bodies.size() != 1)
    throw Error(SourceLoc{o.scene}, "a dataset records one instrument; the scene has " + std::to_string(bodies.size()) +
                                        " rigid bodies");
  Component* camera = nullptr;
  int cameras = 0;
  for (Component* c : scene->all<Component>())
    if (c->typeName() == "DepthCamera") camera = c, ++cameras;
  if (cameras != 1) throw Error(SourceLoc{o.scene}, "a dataset has one camera; the scene has " + std::to_string(cameras));
  if (!o.quiet)
    cli::printNotes(scene->notes());

  PoseRecorder poses(*bodies.front());
  ProgressLine progress;
  RunOptions ro;
  if (o.steps >= 0) ro.steps = o.steps;
  else ro.time = o.time;
  ro.observers.push_back(&poses);
  if (!o.quiet) ro.observers.push_back(&progress);
  fs::create_directories(temp);
  const RunResult r = run(sim, ro);
  if (r.failure) {
    fs::remove_all(temp);
    std::cerr << o.scene << ": " << r.failure->str() << "\nno dataset was written\n";
    return kExitDiverged;
  }

  motion::writeTrajectoryCsv((temp / "trajectory.csv").string(), poses.trajectory);
  FieldValue pose, sceneFrame;
  camera->field("cameraToScene", pose);
  camera->field("sceneFrame", sceneFrame);
  if (sceneFrame.values.at(0) == 0) {
    RigidTransform T = RigidTransform::Identity();
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) T.matrix()(i, j) = pose.values.at(4 * i + j);
    writeTransform((temp / "camera_to_scene.txt").string(), T, "camera -> scene, written by viscera dataset make");
  }
  if (!o.noWrench) writeFileAtomic((temp / "wrench.csv").string(), wrenchTable(r.instruments.front(), forceSigma, torqueSigma, o.seed));
  std::ostringstream readme;
  readme << "Dataset written by viscera dataset make from " << fs::absolute(o.scene).string() << "\n";
  for (const auto& a : o.sets) readme << "  --set " << a << "\n";
  readme << "Units: " << units.str() << " (lengths and forces), times in seconds.\n"
         << "Simulated " << formatNumber(r.simulatedTime()) << " s in " << r.steps << " steps of " << formatNumber(r.dt) << " s.\n";
  if (!o.noWrench)
    readme << "wrench.csv: contact wrench on the instrument plus Gaussian noise, sigma " << formatNumber(forceSigma)
           << " (force), " << formatNumber(torqueSigma) << " (torque), seed " << o.seed << ".\n";
  writeFileAtomic((temp / "README.txt").string(), readme.str());

  // The dataset is checked as any other would be before it is given its name.
  const study::DatasetReport check = study::checkDataset(temp.string());
  if (!check.ok()) {
    for (const auto& p : check.problems) std::cerr << p << "\n";
    throw Error(SourceLoc{o.out}, "the dataset written does not pass its own check (kept at " + temp.string() + ")");
  }
  std::error_code ec;
  fs::rename(temp, o.out, ec);
  if (ec) throw Error(SourceLoc{o.out}, "cannot move the dataset into place: " + ec.message() + " (kept at " + temp.string() + ")");
  if (!o.quiet)
    for (const auto& l : check.lines) std::cerr << l << "\n";
  if (!o.quiet) std::cerr << "wrote the dataset " << o.out << "\n";
  return kExitOk;
}

namespace {

int check(const std::string& folder) {
  const study::DatasetReport r = study::checkDataset(folder);
  for (const auto& l : r.lines) std::cout << l << "\n";
  for (const auto& w : r.warnings) std::cerr << "warning: " << printable(w) << "\n";
  for (const auto& p : r.problems) std::cerr << p << "\n";
  if (!r.ok()) {
    std::cerr << folder << ": not a usable dataset (" << r.problems.size() << " problem" << (r.problems.size() == 1 ? "" : "s")
              << ")\n";
    return kExitInvalidInput;
  }
  std::cout << folder << ": ok\n";
  return kExitOk;
}

}  // namespace

void addDatasetCommand(CLI::App& app, std::function<int()>& action) {
  auto* cmd = app.add_subcommand("dataset", "measured datasets: make one from a scene, check one");
  cmd->require_subcommand(1);
  cmd->footer("A dataset is a folder: trajectory.csv, camera/index.csv with the frames, camera_to_scene.txt, optionally\n"
              "wrench.csv and README.txt (docs/user-guide.md, \"Datasets\").");

  auto o = std::make_shared<DatasetMakeOptions>();
  auto* mk = cmd->add_subcommand("make", "run a scene with its instrument and a depth camera and write a dataset");
  mk->footer("The camera options are those of `viscera camera`; the added camera keeps the tissue's points only and takes\n"
             "10 frames per second unless --rate says otherwise. The trajectory is the instrument's pose at every step.");
  mk->add_option("scene", o->scene, "scene file (.xml or SOFA .scn)")->required();
  mk->add_option("--out", o->out, "the dataset folder to create (must not exist)")->required();
  auto* steps = mk->add_option("--steps", o->steps, "number of steps to run")->check(CLI::NonNegativeNumber);
  mk->add_option("--time", o->time, "simulated time to run, in the scene's time unit")->check(CLI::NonNegativeNumber)->excludes(steps);
  mk->add_option("--set", o->sets, "set a scene attribute, ADDRESS=VALUE (the ground truth); repeatable");
  mk->add_option("--force-noise", o->forceNoise, "standard deviation of the noise added to each force component (\"0.01 N\"; 0: none)");
  mk->add_option("--torque-noise", o->torqueNoise, "standard deviation of the noise added to each torque component (\"1 N*mm\")");
  mk->add_option("--wrench-seed", o->seed, "random seed of the wrench noise (1)");
  mk->add_flag("--no-wrench", o->noWrench, "write no wrench.csv (a dataset of clouds only)");
  mk->add_flag("--quiet", o->quiet, "no notes, progress or summary");
  o->camera.declare(*mk);
  mk->callback([o, &action] { action = [o] { return makeDataset(*o); }; });

  auto folder = std::make_shared<std::string>();
  auto* ck = cmd->add_subcommand("check", "validate a dataset folder and print what it holds");
  ck->add_option("data", *folder, "the dataset folder")->required();
  ck->callback([folder, &action] { action = [folder] { return check(*folder); }; });
}

}  // namespace viscera
