// `viscera trajectory`: builds a PalpationSpec from the options (the box given directly or as
// the bounding box of a volume mesh), generates the pokes and writes the trajectory CSV.
#include "apps/viscera/TrajectoryCommand.h"
#include "apps/viscera/CliText.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "motion/Palpation.h"
#include "motion/Trajectory.h"

namespace viscera {
namespace {

using cli::words;

struct TrajectoryOptions {
  motion::PalpationSpec spec;
  std::string box, mesh, faces, out;
};

// "xmin ymin zmin xmax ymax zmax" (blanks or commas between).
void parseBox(const std::string& text, motion::PalpationSpec& spec) {
  const auto v = cli::finiteNumbers(text, "--box", 6, "xmin ymin zmin xmax ymax zmax");
  spec.boxMin = Eigen::Vector3d(v[0], v[1], v[2]);
  spec.boxMax = Eigen::Vector3d(v[3], v[4], v[5]);
}

// The bounding box of a volume mesh's points.
void boxFromMesh(const std::string& path, motion::PalpationSpec& spec) {
  const io::VolumeMesh mesh = io::readVolumeMesh(path);
  if (mesh.points.cols() == 0) throw Error(SourceLoc{path}, "the mesh has no points, so no bounding box for the trajectory");
  spec.boxMin = mesh.points.rowwise().minCoeff();
  spec.boxMax = mesh.points.rowwise().maxCoeff();
}

// generatePalpation's messages start with the PalpationSpec field at fault; name the option instead.
std::string withOptionName(const std::string& message, const TrajectoryOptions& o) {
  static const std::map<std::string, std::string> kOptions = {
      {"radius", "--radius"}, {"depth", "--depth"},       {"depthJitter", "--jitter"}, {"speed", "--speed"},
      {"travelSpeed", "--travel-speed"}, {"dwell", "--dwell"}, {"rest", "--rest"},     {"lift", "--lift"},
      {"margin", "--margin"}, {"duration", "--duration"}, {"rate", "--rate"},          {"faces", "--faces"}};
  const size_t colon = message.find(": ");
  if (colon == std::string::npos) return message;
  const std::string field = message.substr(0, colon);
  if (field == "box") return (o.mesh.empty() ? "--box" : "--mesh " + o.mesh + " (bounding box)") + message.substr(colon);
  auto it = kOptions.find(field);
  return it == kOptions.end() ? message : it->second + message.substr(colon);
}

int writeTrajectory(TrajectoryOptions o) {
  if (o.box.empty() == o.mesh.empty()) throw Error("trajectory: give the specimen as either --box or --mesh");
  if (!o.box.empty()) parseBox(o.box, o.spec);
  else boxFromMesh(o.mesh, o.spec);
  if (!o.faces.empty()) {
    o.spec.faces.clear();
    for (const auto& w : words(o.faces)) {
      try {
        o.spec.faces.push_back(motion::parseFace(w));
      } catch (const std::invalid_argument& e) {
        throw Error(std::string("--faces: ") + e.what());
      }
    }
  }

  motion::PalpationResult result;
  try {
    result = motion::generatePalpation(o.spec);
  } catch (const std::invalid_argument& e) {
    throw Error(withOptionName(e.what(), o));
  }
  motion::writeTrajectoryCsv(o.out, result.trajectory);

  std::ostringstream msg;
  msg << "wrote " << result.trajectory.size() << " samples (" << result.pokes << " poke" << (result.pokes == 1 ? "" : "s");
  const char* sep = ": ";
  for (auto f : {motion::Face::Top, motion::Face::XMin, motion::Face::XMax, motion::Face::YMin, motion::Face::YMax}) {
    const auto n = std::count(result.pokedFaces.begin(), result.pokedFaces.end(), f);
    if (n == 0) continue;
    msg << sep << n << " " << motion::faceName(f);
    sep = ", ";
  }
  msg << ") over " << o.spec.duration << " s to " << o.out << "\n";
  std::cerr << msg.str();
  return kExitOk;
}

}  // namespace

void addTrajectoryCommand(CLI::App& app, std::function<int()>& action) {
  auto o = std::make_shared<TrajectoryOptions>();
  auto& s = o->spec;
  auto* cmd = app.add_subcommand("trajectory", "write a palpation trajectory CSV");
  cmd->footer(
      "The trajectory is of the sphere's centre (z up), rows t,x,y,z,qx,qy,qz,qw. Lengths, times and speeds are plain\n"
      "numbers in the scene's units (mm and s for a scene with units=\"mm g s\").");
  auto* box = cmd->add_option("--box", o->box, "specimen bounding box \"xmin ymin zmin xmax ymax zmax\"");
  cmd->add_option("--mesh", o->mesh, "take the box from the points of this volume mesh (.msh, .vtk, .vtu)")->excludes(box);
  cmd->add_option("--radius", s.radius, "radius of the instrument sphere (length)")->capture_default_str();
  cmd->add_option("--depth", s.depth, "how far the sphere goes past the undeformed face (length)")->capture_default_str();
  cmd->add_option("--jitter", s.depthJitter, "each poke's depth is depth * (1 +- jitter), uniform, jitter in [0, 1)")
      ->capture_default_str();
  cmd->add_option("--speed", s.speed, "press and retract speed (length / time)")->capture_default_str();
  cmd->add_option("--travel-speed", s.travelSpeed, "speed of the moves between pokes (length / time)")->capture_default_str();
  cmd->add_option("--dwell", s.dwell, "hold at full depth (time)")->capture_default_str();
  cmd->add_option("--rest", s.rest, "hold before each poke (time)")->capture_default_str();
  cmd->add_option("--lift", s.lift, "clearance from the specimen while moving between pokes (length)")->capture_default_str();
  cmd->add_option("--margin", s.margin, "poke centres keep this fraction of the face size from its edges, in [0, 0.5)")
      ->capture_default_str();
  cmd->add_option("--duration", s.duration, "length of the trajectory (time)")->capture_default_str();
  cmd->add_option("--rate", s.rate, "samples per unit time")->capture_default_str();
  cmd->add_option("--faces", o->faces, "faces to poke, comma separated: top,x-,x+,y- and y+ (default all)");
  cmd->add_option("--seed", s.seed, "random seed; the same options give the same file")->capture_default_str();
  cmd->add_option("--out", o->out, "the CSV file to write")->required();
  cmd->callback([o, &action] { action = [o] { return writeTrajectory(*o); }; });
}

}  // namespace viscera
