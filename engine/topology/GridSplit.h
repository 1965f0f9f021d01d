// Regular grids and their split into tetrahedra, in SOFA's orders so that SOFA scenes give the
// same meshes.
#pragma once

#include <Eigen/Core>

#include "engine/Roles.h"

namespace viscera {

// Points of an n[0] x n[1] x n[2] grid over [lo, hi]; index = i + n0 (j + n1 k).
// `origin`, when given, is SOFA's p0: the first node, in place of lo (the spacing stays (hi - lo) / (n - 1)).
Eigen::Matrix3Xd gridPoints(const std::array<int, 3>& n, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                            const Eigen::Vector3d* origin = nullptr);
// Hexahedra (x fastest); corners (i,j,k), (i+1,j,k), (i+1,j+1,k), (i,j+1,k), then the same at k+1.
HexList gridHexahedra(const std::array<int, 3>& n);
// SOFA's Hexa2TetraTopologicalMapping: six tetrahedra per hexahedron; with `swapping`, cells are
// mirrored along x on even x, along y on odd y, along z on odd z (nx, ny cells per row/layer),
// and mirrored cells use the orientation-preserving vertex order (unless !fixOrientation, as
// SOFA's TetrahedronFEMForceField does when placed directly on hexahedra).
TetList splitHexahedra(const HexList& hexa, int nx, int ny, bool swapping, bool fixOrientation = true);

// The boundary faces of hexahedra in SOFA's node order (faces that belong to one hexahedron),
// outward at the points X (a mirrored hexahedron's faces are turned): the surface of a grid.
Eigen::Matrix<int, 4, Eigen::Dynamic> hexahedronBoundaryQuads(const HexList& hexa, const Eigen::Matrix3Xd& X);
// Each quad split into two triangles (0 1 2, 0 2 3).
Eigen::Matrix<int, 3, Eigen::Dynamic> quadTriangles(const Eigen::Matrix<int, 4, Eigen::Dynamic>& quads);
// The two together.
Eigen::Matrix<int, 3, Eigen::Dynamic> hexahedronBoundaryTriangles(const HexList& hexa, const Eigen::Matrix3Xd& X);

// The tetrahedra a TetrahedronFEMForceField builds on `topo`: its tetrahedra, or, directly on a
// grid, SOFA's split of its hexahedra (straight vertex order, as SOFA's force field does). Engines
// that select elements (SphereROI) use the same list, so that element indices agree.
TetList elementTetrahedra(const Topology& topo);

// A component that fills another's elements at init (topological mappings).
class TopologyFiller {
 public:
  virtual ~TopologyFiller() = default;
  virtual bool fills(const class Component& c) const = 0;
};

}  // namespace viscera
