// Closed triangle surfaces (OBJ, STL, OFF, PLY) read through OpenMesh, with the checks meshing
// needs: closed, manifold, consistently oriented.
#pragma once

#include <Eigen/Core>
#include <string>

namespace viscera::io {

struct SurfaceMesh {
  Eigen::Matrix3Xd points;                         // 3 x #vertices
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangles;  // 3 x #triangles, 0-based
};

}  // namespace viscera::io
