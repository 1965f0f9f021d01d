// Tetrahedral meshing of a closed triangle surface with the TetGen program (Debian package
// `tetgen`), and quality measures of tetrahedral meshes.
#pragma once

#include <Eigen/Core>
#include <string>

#include "io/mesh/Mesh.h"
#include "io/surface/SurfaceMesh.h"

namespace viscera::io {

struct TetOptions {
  // Quality bound (TetGen -q): the largest allowed ratio of a tetrahedron's circumradius to its
  // shortest edge (0.61 for a regular tetrahedron). 0 turns quality refinement off; otherwise at
  // least 1.1, since below that TetGen's refinement may not terminate.
  double radiusEdgeRatio = 1.5;
  // Smallest dihedral angle TetGen aims for, in degrees (TetGen -q ratio/angle), 0..18 (above
  // 18 TetGen may not terminate); only with quality refinement. 0 leaves TetGen's default.
  double minDihedral = 0.0;
  // Largest tetrahedron volume (TetGen -a), in the surface's length unit cubed; 0 = no bound.
  double maxVolume = 0.0;
  // Do not split boundary faces (TetGen -Y): the boundary of the mesh is the input surface,
  // vertex for vertex and triangle for triangle.
  bool keepSurface = false;
  // The TetGen executable: a name looked up on PATH, or a path.
  std::string tetgenProgram = "tetgen";
  // TetGen is stopped after this many seconds of wall time; 0 = no limit.
  double timeoutSeconds = 0.0;
};

// Fills the closed surface with tetrahedra. The surface must pass requireClosedSurface (checked
// here; its orientation does not matter). Runs TetGen with -p (the input is a piecewise linear
// complex) -Q (quiet) -z (0-based output) and the options, in a temporary folder that is removed
// afterwards. Returns positively oriented tetrahedra (volume > 0) on the nodes they use, and the
// boundary triangles, oriented outwards. Throws viscera::Error naming `source` for bad options, a
// missing program ("install the Debian package tetgen"), a surface TetGen rejects (for a
// self-intersecting one, a pair of crossing triangles by their vertices) or an unusable result.
VolumeMesh tetrahedralize(const SurfaceMesh& surface, const TetOptions& options, const std::string& source);

// Size and shape of the tetrahedra of a mesh (their orientation does not matter; a degenerate
// tetrahedron has an infinite radius-edge ratio).
struct TetQuality {
  long long nodes = 0, tetrahedra = 0, triangles = 0;  // triangles: the mesh's surface triangles
  double volume = 0.0;                                 // sum of the tetrahedra's volumes
  double minVolume = 0.0, maxVolume = 0.0, meanVolume = 0.0;
  double minDihedral = 0.0, maxDihedral = 0.0;  // degrees; 70.53 for a regular tetrahedron
  // Circumradius / shortest edge: the worst (largest) and the mean; 0.612 for a regular tetrahedron.
  double maxRadiusEdgeRatio = 0.0, meanRadiusEdgeRatio = 0.0;
};
TetQuality measureTetMesh(const VolumeMesh& mesh);

}  // namespace viscera::io
