// Volume meshes and their files: Gmsh .msh (legacy $NOD/$ELM, v2 and v4 ASCII), VTK legacy .vtk,
// VTK XML .vtu; .vtu/.pvd output for ParaView. Every writer is atomic (temporary file + rename).
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

namespace viscera::io {

struct VolumeMesh {
  Eigen::Matrix3Xd points;                         // 3 x #nodes
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets;      // 4 x #tets, 0-based node indices
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangles; // 3 x #triangles (surface elements in the file)
};

// Reads a mesh by extension (.msh, .vtk, .vtu). Throws viscera::Error "file:line: what" for
// unreadable files, bad counts, indices out of range, unsupported element types or formats.
VolumeMesh readVolumeMesh(const std::string& path);
VolumeMesh readGmsh(const std::string& path);
VolumeMesh readVtkLegacy(const std::string& path);
VolumeMesh readVtu(const std::string& path);

// Checks a tetrahedral mesh: indices in range, no degenerate tetrahedra (|volume| below a
// relative tolerance), one consistent orientation. `source` names the file in messages.
// Returns the orientation sign (+1 if volumes are positive, -1 if all negative).
int checkTetMesh(const VolumeMesh& mesh, const std::string& source);

// A named data array on points or cells: `components` values per entry, entry-major.
struct DataArray {
  std::string name;
  int components = 1;
  std::vector<double> values;
};

// Writes an unstructured grid of tetrahedra (and optionally no cells at all) as .vtu.
void writeVtu(const std::string& path, const Eigen::Matrix3Xd& points, const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets,
              const std::vector<DataArray>& pointData, const std::vector<DataArray>& cellData);
// Writes a .pvd collection: (time, file relative to the .pvd) pairs.
void writePvd(const std::string& path, const std::vector<std::pair<double, std::string>>& entries);

// Writes `content` to `path` through a temporary file in the same folder and a rename, so that
// readers never see a half-written file. Throws viscera::Error on failure.
void writeFileAtomic(const std::string& path, const std::string& content);

}  // namespace viscera::io
