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
  // Gmsh files only: 8-node hexahedra (nodes 0-3 one face counter-clockwise seen from outside
  // the cell's other face 4-7, as Gmsh, VTK and SOFA order them) and 4-node quadrangles.
  Eigen::Matrix<int, 8, Eigen::Dynamic> hexahedra;
  Eigen::Matrix<int, 4, Eigen::Dynamic> quads;
};

// Reads a mesh by extension (.msh, .vtk, .vtu; .exo: an Exodus series' first frame). Throws viscera::Error "file:line: what" for
// unreadable files, bad counts, indices out of range, unsupported element types or formats.
VolumeMesh readVolumeMesh(const std::string& path);
VolumeMesh readGmsh(const std::string& path);
// A .vtk file: legacy VTK, or VTK XML saved under that extension (as SOFA reads it).
VolumeMesh readVtkLegacy(const std::string& path);
VolumeMesh readVtu(const std::string& path);

// Checks a tetrahedral mesh: indices in range, no degenerate tetrahedra (|volume| below a
// relative tolerance), one consistent orientation. `source` names the file in messages.
// Returns the orientation sign (+1 if volumes are positive, -1 if all negative).
int checkTetMesh(const VolumeMesh& mesh, const std::string& source);

// The faces that belong to exactly one tetrahedron (tets: 4 x #tets), oriented outwards (right-hand
// rule, normal away from the tetrahedron's fourth node at points: 3 x #nodes), as 3 x #faces, in
// the order of their sorted node triples. Tetrahedra may be of either orientation.
using TriangleList = Eigen::Matrix<int, 3, Eigen::Dynamic>;  // 3 x #triangles
TriangleList boundaryTriangles(const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets, const Eigen::Matrix3Xd& points);

// A named data array on points or cells: `components` values per entry, entry-major.
struct DataArray {
  std::string name;
  int components = 1;
  std::vector<double> values;
};

// How writeVtu encodes its arrays. The defaults give plain base64 "binary" arrays with Int64
// connectivity and offsets, and points and data as Float64, so values read back bit-exact.
struct VtuWriteOptions {
  // zlib-compressed arrays (compressor="vtkZLibDataCompressor", VTK's block layout), which
  // VTK/ParaView and readVtu read. About 2.5x smaller for FEM frames (Float64 fields compress
  // least; the connectivity ~8x).
  bool compress = false;
  int compressionLevel = 1;          // zlib level 1 (fastest) .. 9; higher levels gain ~1% on FEM data
  int compressionBlockSize = 32768;  // uncompressed bytes per zlib block (VTK's default), >= 1024
  // Connectivity and offsets as Int32 (instead of Int64) when every value fits.
  bool int32Indices = false;
  // Points and data as Float32 (7 significant digits, as ParaView and SOFA write them): half the
  // bytes of Float64.
  bool float32 = false;
  // The <Cells> section made by encodeVtuCells for the same tetrahedra and options: a series whose
  // frames share their cells encodes (and compresses) them once. Null: encoded per file.
  const std::string* encodedCells = nullptr;
};

// The <Cells> section of a .vtu of `tets` (connectivity, offsets, types), encoded as `options`
// say; give it to writeVtu as encodedCells.
std::string encodeVtuCells(const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets, const VtuWriteOptions& options);

// Writes an unstructured grid of tetrahedra (and optionally no cells at all) as .vtu.
void writeVtu(const std::string& path, const Eigen::Matrix3Xd& points, const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets,
              const std::vector<DataArray>& pointData, const std::vector<DataArray>& cellData, const VtuWriteOptions& options = {});
// Writes a polygonal data set (.vtp): points with triangles (3 x #triangles, may be empty) and,
// when `vertexCells` is set, one vertex cell per point (how a point cloud shows in ParaView).
// Options as for writeVtu; point data only.
void writeVtp(const std::string& path, const Eigen::Matrix3Xd& points, const Eigen::Matrix<int, 3, Eigen::Dynamic>& triangles,
              bool vertexCells, const std::vector<DataArray>& pointData, const VtuWriteOptions& options = {});
// Writes a .pvd collection: (time, file relative to the .pvd) pairs.
void writePvd(const std::string& path, const std::vector<std::pair<double, std::string>>& entries);

// One frame of a series: its time and its file (relative names resolved against the .pvd's folder).
struct SeriesFrame {
  double time = 0;
  std::string path;
};
// The frames of a .pvd collection (its <DataSet timestep="..." file="..."/> elements) in time
// order. Errors name the file and line: unreadable XML, a missing or non-finite timestep, a
// missing file, no frames, two frames at one time.
std::vector<SeriesFrame> readPvd(const std::string& path);


// Writes a Gmsh MSH 2.2 ASCII file (atomically): the mesh's triangles (element type 2), when it
// has any, then its tetrahedra (type 4), each with physical and elementary tag 1; nodes numbered
// from 1 in column order.
void writeGmsh(const std::string& path, const VolumeMesh& mesh);

}  // namespace viscera::io
