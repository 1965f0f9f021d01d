// `viscera mesh`: fills a closed surface (OBJ, STL, OFF, PLY) with tetrahedra through TetGen and
// writes a .msh or .vtu volume mesh with a quality report; `viscera mesh --check` only checks the
// surface.
#include "apps/viscera/MeshCommand.h"
#include "core/Files.h"
#include "apps/viscera/CliText.h"

#include <CLI/CLI.hpp>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/meshing/Tetrahedralize.h"
#include "io/surface/SurfaceMesh.h"

namespace viscera {
namespace {

using cli::jsonString;

namespace fs = std::filesystem;

struct MeshCommandOptions {
  std::string surface, out, report;
  bool check = false, quiet = false;
  io::TetOptions tet;
};

std::string lowerExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

std::string point(const Eigen::Vector3d& p) {
  std::ostringstream s;
  s.precision(6);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

// An output file must go into an existing folder; checked before the meshing, which can take a while.
void requireOutputFolder(const std::string& path, const char* option) {
  cli::requireParentFolder(path, option);
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw Error(std::string(option) + " " + path + ": is a folder");
}

void checkOptions(const MeshCommandOptions& o) {
  const auto& t = o.tet;
  if (!std::isfinite(t.radiusEdgeRatio) || (t.radiusEdgeRatio != 0 && t.radiusEdgeRatio < 1.1))
    throw Error(
        "--quality: give 0 (no quality refinement) or a radius-edge ratio bound of at least 1.1 (below that TetGen may not "
        "terminate)");
  if (!std::isfinite(t.minDihedral) || t.minDihedral < 0 || t.minDihedral > 18)
    throw Error("--min-dihedral: must be in [0, 18] degrees (above 18 TetGen may not terminate)");
  if (t.minDihedral > 0 && t.radiusEdgeRatio == 0) throw Error("--min-dihedral needs quality refinement (--quality > 0)");
  if (!std::isfinite(t.maxVolume) || t.maxVolume < 0) throw Error("--max-volume: must be >= 0 (0: no bound)");
  if (!std::isfinite(t.timeoutSeconds) || t.timeoutSeconds < 0) throw Error("--timeout: must be >= 0 seconds (0: no limit)");
}

// Reads and checks the surface; an inward-oriented one is flipped (with a note unless quiet).
io::SurfaceMesh loadSurface(const std::string& path, bool quiet, io::SurfaceCheck& check, bool& flipped) {
  io::SurfaceMesh surface = io::readSurface(path);
  io::requireClosedSurface(surface, path);
  check = io::checkSurface(surface);
  flipped = check.volume < 0;
  if (flipped) {
    io::flipSurface(surface);
    check.volume = -check.volume;
    if (!quiet)
      std::cerr << "note: " << path << ": the surface is oriented inwards (its volume came out negative); its triangles were flipped\n";
  }
  return surface;
}

void printSurface(std::ostream& out, const std::string& path, const io::SurfaceMesh& s, const io::SurfaceCheck& c) {
  out << path << ": closed, manifold, consistently oriented surface\n"
      << "  vertices " << s.points.cols() << ", triangles " << s.triangles.cols() << "\n"
      << "  bounding box " << point(s.points.rowwise().minCoeff()) << " .. " << point(s.points.rowwise().maxCoeff()) << "\n"
      << "  area " << c.area << ", enclosed volume " << c.volume << "\n";
}

int checkOnly(const MeshCommandOptions& o) {
  io::SurfaceCheck check;
  bool flipped = false;
  const io::SurfaceMesh surface = loadSurface(o.surface, true, check, flipped);
  if (o.quiet) return kExitOk;
  std::cout.precision(6);
  printSurface(std::cout, o.surface, surface, check);
  if (flipped) std::cout << "  oriented inwards: `viscera mesh` flips its triangles before meshing\n";
  return kExitOk;
}

int meshSurface(const MeshCommandOptions& o) {
  const std::string ext = lowerExtension(o.out);
  if (ext != ".msh" && ext != ".vtu")
    throw Error("mesh: output " + o.out + ": unknown format " + (ext.empty() ? "(no extension)" : "'" + ext + "'") +
                "; expected .msh (Gmsh 2.2) or .vtu (VTK XML)");
  requireOutputFolder(o.out, "output");
  if (!o.report.empty()) requireOutputFolder(o.report, "--report");

  io::SurfaceCheck check;
  bool flipped = false;
  const io::SurfaceMesh surface = loadSurface(o.surface, o.quiet, check, flipped);
  const io::VolumeMesh mesh = io::tetrahedralize(surface, o.tet, o.surface);
  const io::TetQuality q = io::measureTetMesh(mesh);
  const double volumeDifference = std::abs(q.volume - check.volume) / check.volume;

  std::ostringstream text;
  text.precision(6);
  printSurface(text, o.surface, surface, check);
  text << o.out << ": " << q.nodes << " nodes, " << q.tetrahedra << " tetrahedra, " << q.triangles << " boundary triangles\n"
       << "  volume " << q.volume << " (surface " << check.volume << ", relative difference " << volumeDifference << ")\n"
       << "  tetrahedron volume: min " << q.minVolume << ", max " << q.maxVolume << ", mean " << q.meanVolume << "\n"
       << "  dihedral angles: min " << q.minDihedral << " deg, max " << q.maxDihedral << " deg\n"
       << "  radius-edge ratio: max " << q.maxRadiusEdgeRatio << ", mean " << q.meanRadiusEdgeRatio << "\n";

  std::ostringstream json;
  json.precision(10);
  json << "{\n  \"surface\": " << jsonString(o.surface) << ",\n  \"output\": " << jsonString(o.out) << ",\n"
       << "  \"surface_vertices\": " << surface.points.cols() << ",\n  \"surface_triangles\": " << surface.triangles.cols() << ",\n"
       << "  \"surface_area\": " << check.area << ",\n  \"surface_volume\": " << check.volume << ",\n"
       << "  \"flipped\": " << (flipped ? "true" : "false") << ",\n"
       << "  \"options\": {\"quality\": " << o.tet.radiusEdgeRatio << ", \"min_dihedral\": " << o.tet.minDihedral
       << ", \"max_volume\": " << o.tet.maxVolume << ", \"keep_surface\": " << (o.tet.keepSurface ? "true" : "false") << "},\n"
       << "  \"nodes\": " << q.nodes << ",\n  \"tetrahedra\": " << q.tetrahedra << ",\n  \"boundary_triangles\": " << q.triangles << ",\n"
       << "  \"volume\": " << q.volume << ",\n  \"volume_relative_difference\": " << volumeDifference << ",\n"
       << "  \"tet_volume\": {\"min\": " << q.minVolume << ", \"max\": " << q.maxVolume << ", \"mean\": " << q.meanVolume << "},\n"
       << "  \"dihedral_deg\": {\"min\": " << q.minDihedral << ", \"max\": " << q.maxDihedral << "},\n"
       << "  \"radius_edge_ratio\": {\"max\": " << q.maxRadiusEdgeRatio << ", \"mean\": " << q.meanRadiusEdgeRatio << "}\n}\n";

  if (ext == ".msh") io::writeGmsh(o.out, mesh);
  else io::writeVtu(o.out, mesh.points, mesh.tets, {}, {});
  if (!o.report.empty()) {
    try {
      writeFileAtomic(o.report, json.str());
    } catch (const Error&) {
      // Both outputs or neither.
      std::error_code ec;
      fs::remove(o.out, ec);
      throw;
    }
  }
  if (!o.quiet) {
    std::cout << text.str();
    std::cerr << "wrote " << o.out << (o.report.empty() ? "" : " and " + o.report) << "\n";
  }
  return kExitOk;
}

int runMeshCommand(const MeshCommandOptions& o) {
  checkOptions(o);
  if (o.check) {
    if (!o.out.empty()) throw Error("mesh --check takes only the surface, not an output file (" + o.out + ")");
    return checkOnly(o);
  }
  if (o.out.empty()) throw Error("mesh: give the output file (.msh or .vtu), or --check to only check the surface");
  return meshSurface(o);
}

}  // namespace

void addMeshCommand(CLI::App& app, std::function<int()>& action) {
  auto o = std::make_shared<MeshCommandOptions>();
  auto* cmd = app.add_subcommand("mesh", "fill a closed surface with tetrahedra (TetGen) or check the surface");
  cmd->footer(
      "The surface (.obj, .stl, .off, .ply) must be closed, manifold, consistently oriented and without zero-area\n"
      "triangles; an inward-oriented one is flipped. The output format follows OUT's extension: .msh (Gmsh 2.2, with\n"
      "the boundary triangles) or .vtu. Meshing runs the `tetgen` program (Debian package tetgen).");
  cmd->add_option("surface", o->surface, "closed triangle surface (.obj, .stl, .off, .ply)")->required();
  cmd->add_option("out", o->out, "volume mesh to write (.msh or .vtu)");
  cmd->add_flag("--check", o->check, "only check the surface and print its report");
  cmd->add_option("--quality", o->tet.radiusEdgeRatio,
                  "largest radius-edge ratio of a tetrahedron (TetGen -q); 0 = no quality refinement, else >= 1.1")
      ->capture_default_str();
  cmd->add_option("--min-dihedral", o->tet.minDihedral, "smallest dihedral angle TetGen aims for, degrees in [0, 18]; 0 = TetGen's default")
      ->capture_default_str();
  cmd->add_option("--max-volume", o->tet.maxVolume, "largest tetrahedron volume (TetGen -a), surface units cubed; 0 = no bound")
      ->capture_default_str();
  cmd->add_flag("--keep-surface", o->tet.keepSurface, "do not split boundary triangles (TetGen -Y): the mesh's boundary is the surface");
  cmd->add_option("--report", o->report, "also write the quality report as JSON");
  cmd->add_option("--tetgen", o->tet.tetgenProgram, "the TetGen program (a name on PATH or a path)")->capture_default_str();
  cmd->add_option("--timeout", o->tet.timeoutSeconds, "stop TetGen after this many seconds; 0 = no limit")->capture_default_str();
  cmd->add_flag("--quiet", o->quiet, "print nothing but errors");
  cmd->callback([o, &action] { action = [o] { return runMeshCommand(*o); }; });
}

}  // namespace viscera
