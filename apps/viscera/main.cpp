// The `viscera` command line: run, check and document scenes.
#include <CLI/CLI.hpp>
#include <tbb/global_control.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <functional>
#include <memory>
#include <sstream>

#include "apps/viscera/CameraCommand.h"
#include "apps/viscera/CloudCommand.h"
#include "apps/viscera/DistanceCommand.h"
#include "apps/viscera/EspmCommand.h"
#include "apps/viscera/KinematicsCommand.h"
#include "apps/viscera/MeshCommand.h"
#include "apps/viscera/RegisterCommand.h"
#include "apps/viscera/TrajectoryCommand.h"
#include "apps/viscera/VelocityCommand.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "engine/rigid/RigidObject.h"
#include "engine/core/Registry.h"
#include "engine/core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/mesh/Mesh.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

struct RunOptions {
  std::string scene;
  int steps = -1;
  double time = -1;
  std::string out, summary, stateOut, wrench;
  int threads = 0;
  bool quiet = false;
};

std::string jsonEscape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '"' || c == '\\') o += '\\', o += c;
    else if (c == '\n') o += "\\n";
    else if (static_cast<unsigned char>(c) < 0x20) o += ' ';
    else o += c;
  }
  return o;
}

std::unique_ptr<Scene> loadScene(const std::string& path) { return Scene::build(io::readScene(path)); }

// Notes from reading and initialising the scene (ignored elements, idle solvers, ...).
void printNotes(const Scene& scene, bool quiet) {
  if (quiet) return;
  for (const auto& n : scene.notes()) std::cerr << n << "\n";
}

std::string formatDuration(double s) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(s < 10 ? 1 : 0);
  if (s < 120) o << s << " s";
  else if (s < 7200) o << s / 60 << " min";
  else o << s / 3600 << " h";
  return o.str();
}

int cmdRun(const RunOptions& o) {
  std::unique_ptr<tbb::global_control> threads;
  if (o.threads > 0) threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, o.threads);
  auto scene = loadScene(o.scene);
  if (!o.out.empty()) scene->setOutputDirectory(o.out);
  Simulation sim(*scene);  // initialises: every input error surfaces before anything is written
  printNotes(*scene, o.quiet);
  // Contact wrench on each instrument, every step.
  auto bodies = scene->all<RigidObject>();
  std::ostringstream wrench;
  wrench << std::setprecision(9);
  if (!o.wrench.empty()) {
    wrench << "t";
    for (const auto* b : bodies)
      for (const char* c : {"fx", "fy", "fz", "tx", "ty", "tz", "contacts"})
        wrench << "," << (bodies.size() > 1 ? b->name() + "." : std::string()) << c;
    wrench << "\n";
  }
  struct Peak {
    double force = 0, time = 0;
    long contactSteps = 0;
  };
  std::vector<Peak> peaks(bodies.size());
  int total = o.steps >= 0 ? o.steps : o.time >= 0 ? static_cast<int>(std::llround(o.time / scene->dt())) : 100;
  const bool progress = !o.quiet && isatty(STDERR_FILENO) && !std::getenv("CI");

  auto t0 = std::chrono::steady_clock::now();
  auto lastPrint = t0;
  sim.begin();
  std::optional<Diverged> failure;
  for (int i = 0; i < total; ++i) {
    failure = sim.step();
    if (failure) break;
    for (size_t k = 0; k < bodies.size(); ++k) {
      const RigidObject* b = bodies[k];
      if (b->force.norm() > peaks[k].force) peaks[k] = {b->force.norm(), sim.time(), peaks[k].contactSteps};
      peaks[k].contactSteps += b->contacts > 0;
    }
    if (!o.wrench.empty()) {
      wrench << sim.time();
      for (const auto* b : bodies)
        wrench << "," << b->force.x() << "," << b->force.y() << "," << b->force.z() << "," << b->torque.x() << ","
               << b->torque.y() << "," << b->torque.z() << "," << b->contacts;
      wrench << "\n";
    }
    auto now = std::chrono::steady_clock::now();
    if (progress && (now - lastPrint > std::chrono::milliseconds(250) || i + 1 == total)) {
      lastPrint = now;
      double el = std::chrono::duration<double>(now - t0).count();
      double rate = (i + 1) / std::max(el, 1e-9);
      std::fprintf(stderr, "\rstep %d/%d  t = %.6g s  %.0f steps/s  ETA %s   ", i + 1, total, sim.time(), rate,
                   formatDuration((total - i - 1) / rate).c_str());
      std::fflush(stderr);
    }
  }
  if (progress) std::fprintf(stderr, "\n");
  sim.end();
  double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  auto states = scene->all<MechanicalObject>();
  if (!o.summary.empty()) {
    std::ostringstream j;
    j << std::setprecision(10);
    j << "{\n  \"scene\": \"" << jsonEscape(o.scene) << "\",\n";
    j << "  \"status\": \"" << (failure ? "diverged" : "ok") << "\",\n";
    if (failure) j << "  \"failure\": \"" << jsonEscape(failure->str()) << "\",\n";
    j << "  \"steps\": " << sim.steps() << ",\n  \"dt\": " << scene->dt() << ",\n";
    j << "  \"simulated_time\": " << sim.time() - scene->startTime() << ",\n";
    j << "  \"wall_time_s\": " << wall << ",\n";
    j << "  \"ms_per_step\": " << (sim.steps() ? 1000.0 * wall / sim.steps() : 0.0) << ",\n";
    j << "  \"units\": \"" << scene->units().str() << "\",\n";
    j << "  \"objects\": [";
    for (size_t k = 0; k < states.size(); ++k) {
      const auto* s = states[k];
      double maxDisp = s->size() ? (s->x - s->x0).colwise().norm().maxCoeff() : 0.0;
      j << (k ? "," : "") << "\n    {\"name\": \"" << jsonEscape(s->name()) << "\", \"nodes\": " << s->size()
        << ", \"max_displacement\": " << maxDisp << "}";
    }
    j << "\n  ],\n  \"instruments\": [";
    for (size_t k = 0; k < bodies.size(); ++k) {
      const auto* b = bodies[k];
      j << (k ? "," : "") << "\n    {\"name\": \"" << jsonEscape(b->name()) << "\", \"position\": [" << b->p.x() << ", "
        << b->p.y() << ", " << b->p.z() << "], \"force\": [" << b->force.x() << ", " << b->force.y() << ", "
        << b->force.z() << "], \"torque\": [" << b->torque.x() << ", " << b->torque.y() << ", " << b->torque.z()
        << "], \"contacts\": " << b->contacts << ", \"peak_force\": " << peaks[k].force
        << ", \"peak_force_time\": " << peaks[k].time << ", \"steps_in_contact\": " << peaks[k].contactSteps << "}";
    }
    j << "\n  ]";
    if (const CollisionPipeline* p = sim.pipeline())
      j << ",\n  \"contact\": {\"response\": \""
        << (p->settings().response == ContactSettings::Response::Penalty ? "penalty" : "constraint")
        << "\", \"max_contacts\": " << p->maxContacts() << ", \"max_penetration\": " << p->maxPenetration()
        << ", \"contact_distance\": " << p->settings().contactDistance << "}";
    j << "\n}\n";
    io::writeFileAtomic(o.summary, j.str());
  }
  if (!o.wrench.empty()) io::writeFileAtomic(o.wrench, wrench.str());
  if (!o.stateOut.empty()) {
    std::ostringstream c;
    c << std::setprecision(17) << "object,node,x,y,z\n";
    for (const auto* s : states)
      for (int i = 0; i < s->size(); ++i)
        c << s->name() << "," << i << "," << s->x(0, i) << "," << s->x(1, i) << "," << s->x(2, i) << "\n";
    io::writeFileAtomic(o.stateOut, c.str());
  }
  if (failure) {
    std::cerr << o.scene << ": " << failure->str() << "\n";
    return kExitDiverged;
  }
  if (!o.quiet)
    std::cerr << "ran " << sim.steps() << " steps (" << sim.time() - scene->startTime() << " s simulated) in "
              << formatDuration(wall) << ", " << std::setprecision(3) << 1000.0 * wall / std::max(1, sim.steps())
              << " ms/step\n";
  return kExitOk;
}

int cmdCheck(const std::string& path) {
  auto scene = loadScene(path);
  scene->init();
  printNotes(*scene, false);
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
  RunOptions ro;
  auto* run = app.add_subcommand("run", "run a scene");
  run->add_option("scene", ro.scene, "scene file (.xml or SOFA .scn)")->required();
  auto* steps = run->add_option("--steps", ro.steps, "number of steps (default 100)")->check(CLI::NonNegativeNumber);
  run->add_option("--time", ro.time, "simulated time to run, in the scene's time unit")->check(CLI::NonNegativeNumber)->excludes(steps);
  run->add_option("--out", ro.out, "output folder for exporters (default: the scene's folder)");
  run->add_option("--summary", ro.summary, "write a JSON summary (steps, times, largest displacements)");
  run->add_option("--state-out", ro.stateOut, "write final positions as CSV (object,node,x,y,z)");
  run->add_option("--wrench", ro.wrench, "write the contact wrench on each instrument every step as CSV (t,fx,fy,fz,tx,ty,tz,contacts)");
  run->add_option("--threads", ro.threads, "worker threads (default: all cores)")->check(CLI::PositiveNumber);
  run->add_flag("--quiet", ro.quiet, "no progress or notes");
  std::string checkScene;
  auto* check = app.add_subcommand("check", "validate a scene without running it");
  check->add_option("scene", checkScene, "scene file")->required();
  std::string compName;
  auto* comps = app.add_subcommand("components", "list components and their attributes");
  comps->add_option("name", compName, "one component");

  // Each command module sets `action` when its subcommand is given.
  std::function<int()> action;
  addTrajectoryCommand(app, action);
  addKinematicsCommand(app, action);
  addEspmCommand(app, action);
  addVelocityCommand(app, action);
  addCloudCommand(app, action);
  addRegisterCommand(app, action);
  addCameraCommand(app, action);
  addDistanceCommand(app, action);
  addMeshCommand(app, action);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int rc = app.exit(e);
    return rc == 0 ? kExitOk : kExitInvalidInput;
  }
  try {
    if (*run) return cmdRun(ro);
    if (*check) return cmdCheck(checkScene);
    if (*comps) return cmdComponents(compName);
    if (action) return action();
  } catch (const Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInvalidInput;
  } catch (const std::exception& e) {
    std::cerr << "internal error: " << e.what() << "\n";
    return kExitInternal;
  }
  return kExitOk;
}
