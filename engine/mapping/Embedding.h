// Points embedded in a tetrahedral mesh: each point follows one tetrahedron through its
// barycentric coordinates there, x_p = sum_k w_k x_{n_k} (the linear map of SOFA's
// BarycentricMapping), and the boundary triangles of a tetrahedral mesh.
#pragma once

#include <Eigen/Core>

#include "engine/Roles.h"
#include "io/mesh/Mesh.h"

namespace viscera {

using TriangleList = Eigen::Matrix<int, 3, Eigen::Dynamic>;  // 3 x #triangles

// Where each point sits in the mesh. Column p describes point p.
struct TetEmbedding {
  TetList nodes;             // 4 x #points: the nodes of the tetrahedron point p follows
  Eigen::Matrix4Xd weights;  // 4 x #points: barycentric coordinates there (sum 1; outside [0, 1] when extrapolated)
  Eigen::VectorXi element;   // #points: that tetrahedron, -1 when none lies within reach
  Eigen::VectorXd distance;  // #points: distance to that tetrahedron (0 inside, +inf when none within reach)

  int size() const { return static_cast<int>(element.size()); }
  // Points outside every tetrahedron but within reach (they follow the nearest one).
  int extrapolatedCount() const;
  // Points with no tetrahedron within reach.
  int unplacedCount() const;
};

// Embeds `points` (3 x #points) in the tetrahedra `tets` (4 x #tets, indices into `nodes`,
// 3 x #nodes). A point inside a tetrahedron (up to round-off: barycentric coordinates >= -1e-9)
// gets the containing one whose smallest coordinate is largest; a point outside every tetrahedron
// but within `maxDistance` of one gets the nearest tetrahedron and its unclamped barycentric
// coordinates there, so that affine motions of the mesh carry it exactly. The candidates come from
// a bounding-volume hierarchy over the tetrahedra's boxes. Degenerate tetrahedra (zero volume)
// are skipped.
TetEmbedding embedInTetrahedra(const Eigen::Matrix3Xd& nodes, const TetList& tets, const Eigen::Matrix3Xd& points,
                               double maxDistance);

// out (3 x #points) = the embedded points for node positions x (3 x #nodes). Every point must be
// placed (element >= 0).
void applyEmbedding(const TetEmbedding& embedding, const Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& out);

// Points embedded in trilinear hexahedra (a grid's cells, SOFA's order): each point follows one
// hexahedron through its trilinear shape functions at the point's local coordinates there.
struct HexEmbedding {
  Eigen::Matrix<int, 8, Eigen::Dynamic> nodes;     // 8 x #points
  Eigen::Matrix<double, 8, Eigen::Dynamic> weights;  // 8 x #points (sum 1; some negative when extrapolated)
  Eigen::VectorXd distance;                         // #points: distance to that hexahedron's box (0 inside)
  int size() const { return static_cast<int>(distance.size()); }
  int extrapolatedCount() const;
};

// Embeds `points` in the hexahedra: a point inside one (local coordinates in [0, 1] up to 1e-9,
// found by Newton's method on the trilinear map from the candidates whose boxes hold it) follows
// it; any other point follows the hexahedron whose box is nearest, with its unclamped local
// coordinates (exact for affine motions). Returns the distances in `distance` for the caller to
// judge; it needs at least one hexahedron.
HexEmbedding embedInHexahedra(const Eigen::Matrix3Xd& nodes, const HexList& hexa, const Eigen::Matrix3Xd& points);
void applyEmbedding(const HexEmbedding& embedding, const Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& out);

// Euclidean distance from p to the solid tetrahedron (a, b, c, d); 0 inside.
double distanceToTetrahedron(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c, const Eigen::Vector3d& d);

// The nearest tetrahedron to p by checking every one (for messages about points out of reach):
// (index, distance), or (-1, +inf) for an empty mesh.
std::pair<int, double> nearestTetrahedron(const Eigen::Matrix3Xd& nodes, const TetList& tets, const Eigen::Vector3d& p);

// Mean length of the tetrahedra's edges (each edge counted once per tetrahedron); 0 if none.
double meanEdgeLength(const Eigen::Matrix3Xd& nodes, const TetList& tets);

// The outward boundary faces of tetrahedra (io/mesh/Mesh.h).
using io::boundaryTriangles;

}  // namespace viscera
