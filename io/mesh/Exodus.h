// Exodus II time series (.exo): the mesh once, then for each frame its time, vector fields on the
// nodes and scalar fields on the cells, in netCDF-4 with zlib and byte shuffle (libexodusII).
// ParaView and VTK (vtkExodusIIReader) open it and move the nodes by the field "displacement".
// A series that shares its mesh between frames is far smaller than a .vtu per frame: the
// connectivity, about a third of a compressed tetrahedral frame, is stored once.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "io/mesh/Mesh.h"

namespace viscera::io {

// What every frame of a series shares.
struct ExodusLayout {
  Eigen::Matrix3Xd rest;                           // node coordinates, written once
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets;      // cells: tetrahedra, or else
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangles; // triangles, or else one point cell per node
  std::vector<std::string> nodeVectors;            // 3 components a node each (x, y, z)
  std::vector<std::string> cellScalars;            // one value a cell each
  bool float32 = true;                             // values as Float32 (else Float64)
  int compressionLevel = 1;                        // zlib level 1..9
};

// Writes a series frame by frame into a temporary file beside `path` (PATH.tmp.PID.N, which the
// next run holding the folder removes if this process dies), which finish() closes and renames to
// `path`: readers see the whole series or the file that was there before. Destroyed unfinished
// (an error during the run), the temporary goes. Not for concurrent use of one object; separate
// writers in separate threads are safe (calls into the library are serialised).
class ExodusWriter {
 public:
  ExodusWriter(const std::string& path, const ExodusLayout& layout);
  ~ExodusWriter();
  ExodusWriter(const ExodusWriter&) = delete;
  ExodusWriter& operator=(const ExodusWriter&) = delete;

  // One frame: nodeVectors[i] is 3 x #nodes for the layout's i-th vector field, cellScalars[i] one
  // value per cell for its i-th scalar field (sizes checked).
  void append(double time, const std::vector<Eigen::Matrix3Xd>& nodeVectors, const std::vector<Eigen::VectorXd>& cellScalars);
  void finish();
  int frames() const { return frames_; }

 private:
  std::string path_, temporary_;
  int file_ = -1;
  int frames_ = 0;
  long nodes_ = 0, cells_ = 0;
  size_t vectors_ = 0, scalars_ = 0;
  void close();
};

// A series read back: the mesh (rest coordinates, tetrahedra or triangles), the frames' times, and
// each frame's node positions (rest + the field "displacement" when the file has one).
class ExodusReader {
 public:
  explicit ExodusReader(const std::string& path);
  ~ExodusReader();
  ExodusReader(const ExodusReader&) = delete;
  ExodusReader& operator=(const ExodusReader&) = delete;

  const VolumeMesh& mesh() const { return mesh_; }
  const std::vector<double>& times() const { return times_; }
  const std::vector<std::string>& nodeVariables() const { return nodeVars_; }
  const std::vector<std::string>& cellVariables() const { return cellVars_; }
  // Frame i (0-based) of a node variable or of a cell variable (by name).
  Eigen::VectorXd nodeVariable(int frame, const std::string& name) const;
  Eigen::VectorXd cellVariable(int frame, const std::string& name) const;
  Eigen::Matrix3Xd positions(int frame) const;

 private:
  std::string path_;
  int file_ = -1;
  long blockId_ = 0;
  VolumeMesh mesh_;
  std::vector<double> times_;
  std::vector<std::string> nodeVars_, cellVars_;
};

}  // namespace viscera::io
