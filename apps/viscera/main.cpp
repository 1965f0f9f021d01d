// The `viscera` command line: run, check and document scenes.
#include <CLI/CLI.hpp>
#include <tbb/global_control.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

#include "core/Files.h"
#include "core/Text.h"
#include "builtin/Builtins.h"
#include "apps/viscera/AuditCommand.h"
#include "apps/viscera/CameraCommand.h"
#include "apps/viscera/CliText.h"
#include "apps/viscera/CloudCommand.h"
#include "apps/viscera/DatasetCommand.h"
#include "apps/viscera/DistanceCommand.h"
#include "apps/viscera/EspmCommand.h"
#include "apps/viscera/KinematicsCommand.h"
#include "apps/viscera/LearnCommand.h"
#include "apps/viscera/MeshCommand.h"
#include "apps/viscera/RegisterCommand.h"
#include "apps/viscera/SearchCommand.h"
#include "apps/viscera/SofaSuiteCommand.h"
#include "apps/viscera/TrajectoryCommand.h"
#include "apps/viscera/VelocityCommand.h"
#include "apps/viscera/ForceCommand.h"
#include "engine/Run.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "engine/rigid/RigidObject.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/mesh/Mesh.h"
#include "io/scene/InputCache.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

struct RunCommand {
  std::string scene;
  int steps = -1;
  double time = -1;
  std::string out, summary, stateOut, wrench, saveState, fromState;
  std::vector<std::string> sets;
  int threads = 0;
  bool quiet = false;
  bool allNotes = false;
};

// The scene file with the command line's --set edits applied.
std::unique_ptr<Scene> loadScene(const std::string& path, const std::vector<std::string>& sets) {
  SceneDesc desc = io::readScene(path);
  for (const auto& s : sets) desc.applySetting(s);
  return buildScene(desc);
}

// Notes from reading and initialising the scene (ignored elements, idle solvers, ...): the first
// 20, or all of them.
void printNotes(const Scene& scene, bool quiet, bool all) {
  if (quiet) return;
  if (all) cli::printNotes(scene.notes(), scene.notes().size());
  else cli::printNotes(scene.notes());
}

int cmdRun(const RunCommand& o) {
  // Ctrl-C or SIGTERM, from here on (while the scene is built too): the run stops at a step
  // boundary and its outputs are still written.
  SignalStop signals;
  // Every output is checked before anything runs: a typo in a folder costs nothing.
  const std::vector<std::pair<std::string, const char*>> outputs = {
      {o.summary, "--summary"}, {o.wrench, "--wrench"}, {o.stateOut, "--state-out"}, {o.saveState, "--save-state"}};
  for (const auto& [path, option] : outputs) {
    if (path.empty()) continue;
    // A file inside --out may name that folder before the run makes it (as `make demo` does).
    const auto folder = [](std::filesystem::path p) {  // "out/demo/" and "out/demo" alike
      p = p.lexically_normal();
      return p.has_filename() ? p : p.parent_path();
    };
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    const bool insideNewOut = !o.out.empty() && folder(parent) == folder(o.out) && !std::filesystem::exists(parent);
    if (!insideNewOut) cli::requireParentFolder(path, option);
  }
  std::unique_ptr<tbb::global_control> threads;
  if (o.threads > 0) threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, o.threads);
  auto scene = loadScene(o.scene, o.sets);
  if (!o.out.empty()) scene->setOutputDirectory(o.out);
  Simulation sim(*scene);  // initialises: every input error surfaces before anything is written
  std::optional<State> initial;
  if (!o.fromState.empty()) {
    initial = State::load(o.fromState);
    try {
      sim.restoreState(*initial);
    } catch (const Error& e) {
      throw Error(SourceLoc{o.fromState}, e.what());
    }
  }
  // The scene, its data files (read by now) and the starting state stay as they are.
  std::vector<std::string> inputs = io::cachedFiles();
  inputs.push_back(o.scene);
  if (!o.fromState.empty()) inputs.push_back(o.fromState);
  for (const auto& [path, option] : outputs)
    if (!path.empty()) cli::requireNotAnInput(path, option, inputs);
  printNotes(*scene, o.quiet, o.allNotes);
  // Exporters and cameras write into --out: one run at a time.
  std::optional<FolderLock> lock;
  if (!o.out.empty()) lock.emplace(o.out);
  RunOptions ro;
  if (o.steps >= 0) ro.steps = o.steps;
  else if (o.time >= 0) ro.time = o.time;
  ro.recordWrench = !o.wrench.empty();
  ProgressLine progress;
  if (!o.quiet) ro.observers.push_back(&progress);
  ro.observers.push_back(&signals);
  // The wrench rows also go to WRENCH.partial as the run steps, for a run killed outright; not
  // beside a device or FIFO given as the table.
  std::optional<WrenchStream> stream;
  std::error_code ec;
  const auto kind = o.wrench.empty() ? std::filesystem::file_type::none : std::filesystem::status(o.wrench, ec).type();
  if (kind == std::filesystem::file_type::regular || kind == std::filesystem::file_type::not_found) {
    stream.emplace(o.wrench);
    ro.observers.push_back(&*stream);
  }
  const RunResult r = run(sim, ro);

  if (!o.summary.empty()) writeFileAtomic(o.summary, summaryJson(r, o.scene));
  if (!o.wrench.empty()) writeFileAtomic(o.wrench, wrenchCsv(r));
  if (!o.stateOut.empty()) {
    std::ostringstream c;
    c << std::setprecision(17) << "object,node,x,y,z\n";
    for (const auto* s : scene->all<MechanicalObject>()) {
      const Eigen::Matrix3Xd& x = s->x(sim.state());
      for (int i = 0; i < s->size(); ++i)
        c << s->name() << "," << i << "," << x(0, i) << "," << x(1, i) << "," << x(2, i) << "\n";
    }
    writeFileAtomic(o.stateOut, c.str());
  }
  if (!o.saveState.empty()) sim.captureState().save(o.saveState);
  if (r.failure) {
    std::cerr << o.scene << ": " << r.failure->str() << "\n";
    return kExitDiverged;
  }
  if (r.status == RunResult::Status::Interrupted) {
    std::cerr << o.scene << ": " << r.stopReason << " after " << r.steps << " steps (t = " << r.endTime
              << "); the outputs hold the steps run\n";
    return signals.exitCode();
  }
  if (!o.quiet)
    std::cerr << "ran " << r.steps << " steps (" << r.simulatedTime() << " s simulated) in " << formatDuration(r.wallSeconds)
              << ", " << std::setprecision(3) << r.msPerStep() << " ms/step\n";
  return kExitOk;
}

int cmdCheck(const std::string& path, const std::vector<std::string>& sets, bool allNotes) {
  auto scene = loadScene(path, sets);
  scene->init();
  printNotes(*scene, false, allNotes);
  int objects = static_cast<int>(scene->all<MechanicalObject>().size());
  std::cout << path << ": ok (" << objects << " mechanical object" << (objects == 1 ? "" : "s") << ", dt = " << scene->dt()
            << ", units " << scene->units().str() << ")\n";
  return kExitOk;
}

void printSpec(const ComponentSpec& s, bool full) {
  std::cout << s.name;
  if (!s.aliases.empty()) {
    std::cout << " (also";
    for (const auto& a : s.aliases) std::cout << " " << a;
    std::cout << ")";
  }
  std::cout << " [" << s.category << "]\n  " << s.doc << "\n";
  if (!full) return;
  for (const auto& a : s.attrs) {
    std::cout << "  - " << a.name << " (" << kindName(a.kind);
    if (a.kind == AttrKind::Enum) {
      std::cout << ":";
      for (const auto& c : a.choices) std::cout << " " << c;
    }
    if (a.hasUnit) std::cout << ", unit " << a.dim.str();
    if (!a.rangeText().empty()) std::cout << ", range " << a.rangeText();
    if (a.required) std::cout << ", required";
    else if (!a.defaultValue.empty()) std::cout << ", default \"" << a.defaultValue << "\"";
    if (a.linkable) std::cout << ", may link";
    std::cout << ")";
    for (const auto& al : a.aliases) std::cout << " alias " << al;
    std::cout << ": " << a.doc << "\n";
  }
}

int cmdComponents(const std::string& name) {
  const Registry& r = builtinRegistry();
  if (!name.empty()) {
    if (name == "Node") {
      printSpec(Registry::nodeSpec(), true);
      return kExitOk;
    }
    const ComponentSpec* s = r.find(name);
    if (!s) {
      if (const std::string* why = r.ignoredReason(name)) {
        std::cout << name << ": accepted and ignored (" << *why << ")\n";
        return kExitOk;
      }
      std::cerr << "unknown component '" << name << "'\n";
      return kExitInvalidInput;
    }
    printSpec(*s, true);
    return kExitOk;
  }
  printSpec(Registry::nodeSpec(), true);
  for (const auto& [n, s] : r.specs()) {
    std::cout << "\n";
    printSpec(s, true);
  }
  std::cout << "\nAccepted and ignored:";
  for (const auto& [n, why] : r.ignored()) std::cout << " " << n;
  std::cout << "\n";
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Viscera: soft-tissue simulation for robot-assisted surgery research"};
  app.require_subcommand(1);
  // Options of every command (given before or after the command's name).
  app.fallthrough();
  std::vector<std::string> dataPath;
  app.add_option("--data-path", dataPath,
                 "a folder where files named in scenes are looked for after the scene's folder, before SOFA_DATA_PATH "
                 "and the default (share/ and share/mesh/ above the scene, SOFA's examples folder); repeatable")
      ->check(CLI::ExistingDirectory);
  RunCommand ro;
  auto* run = app.add_subcommand("run", "run a scene");
  run->add_option("scene", ro.scene, "scene file (.xml or SOFA .scn)")->required();
  auto* steps = run->add_option("--steps", ro.steps, "number of steps (default 100)")->check(CLI::NonNegativeNumber);
  run->add_option("--time", ro.time, "simulated time to run, in the scene's time unit")->check(CLI::NonNegativeNumber)->excludes(steps);
  run->add_option("--out", ro.out, "output folder for exporters (default: the scene's folder)");
  run->add_option("--summary", ro.summary, "write a JSON summary (steps, times, largest displacements)");
  run->add_option("--state-out", ro.stateOut, "write final positions as CSV (object,node,x,y,z)");
  run->add_option("--wrench", ro.wrench, "write the contact wrench on each instrument every step as CSV (t,fx,fy,fz,tx,ty,tz,contacts)");
  run->add_option("--threads", ro.threads, "worker threads (default: all cores)")->check(CLI::PositiveNumber);
  run->add_option("--save-state", ro.saveState, "write the final state (binary) to continue from with --from-state");
  run->add_option("--from-state", ro.fromState, "start from a state written by --save-state for this scene");
  run->add_flag("--quiet", ro.quiet, "no progress or notes");
  run->add_flag("--all-notes", ro.allNotes, "print every note (default: the first 20)");
  const char* setHelp = "set an attribute, ADDRESS=VALUE with ADDRESS node/path/component.attribute "
                        "(e.g. phantom/fem.youngModulus=\"3.2 kPa\"); repeatable";
  run->add_option("--set", ro.sets, setHelp);
  std::string checkScene;
  std::vector<std::string> checkSets;
  auto* check = app.add_subcommand("check", "validate a scene without running it");
  check->add_option("scene", checkScene, "scene file")->required();
  check->add_option("--set", checkSets, setHelp);
  bool checkAllNotes = false;
  check->add_flag("--all-notes", checkAllNotes, "print every note (default: the first 20)");
  std::string compName;
  auto* comps = app.add_subcommand("components", "list components and their attributes");
  comps->add_option("name", compName, "one component");

  // Each command module sets `action` when its subcommand is given.
  std::function<int()> action;
  addTrajectoryCommand(app, action);
  addKinematicsCommand(app, action);
  addEspmCommand(app, action);
  addVelocityCommand(app, action);
  addForceCommand(app, action);
  addCloudCommand(app, action);
  addRegisterCommand(app, action);
  addCameraCommand(app, action);
  addDistanceCommand(app, action);
  addMeshCommand(app, action);
  addDatasetCommand(app, action);
  addSearchCommand(app, action);
  addAuditCommand(app, action);
  addSofaSuiteCommand(app, action);
  addLearnCommand(app, action);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int rc = app.exit(e);
    return rc == 0 ? kExitOk : kExitInvalidInput;
  }
  io::setDataPath(dataPath);
  try {
    if (*run) return cmdRun(ro);
    if (*check) return cmdCheck(checkScene, checkSets, checkAllNotes);
    if (*comps) return cmdComponents(compName);
    if (action) return action();
  } catch (const Error& e) {
    std::cerr << "error: " << printable(e.what()) << "\n";
    return kExitInvalidInput;
  } catch (const std::exception& e) {
    std::cerr << "internal error: " << printable(e.what()) << "\n";
    return kExitInternal;
  }
  return kExitOk;
}
