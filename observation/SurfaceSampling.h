// Super-sampling of a triangle surface: every triangle subdivided `factor` times per edge, the
// points of the subdivision expressed as fixed linear combinations of the surface's vertices. A
// deformed surface is then re-sampled by one sparse product per frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "observation/SurfaceIndex.h"

namespace viscera::obs {

struct SurfaceSampling {
  // #samples x #vertices, at most three non-zeros per row, each row summing to 1: sample s lies at
  // sum_v weights(s, v) x_v. Samples come in three groups: the vertices used by the triangles (in
  // increasing vertex order, weight 1), then the points inside edges (edges in increasing order of
  // their sorted vertex pair, points from the lower vertex on), then the points inside triangles
  // (triangles in order). Points shared by triangles appear once.
  Eigen::SparseMatrix<double, Eigen::RowMajor> weights;
  int factor = 1;

  int numSamples() const { return static_cast<int>(weights.rows()); }
  int numVertices() const { return static_cast<int>(weights.cols()); }

  // The sample positions (3 x #samples) for vertex positions x (3 x #vertices), written to `out`
  // (resized as needed, so a caller that keeps `out` between frames does not reallocate).
  void sample(const Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& out) const;
  Eigen::Matrix3Xd sample(const Eigen::Matrix3Xd& x) const;
};

// The sampling of `triangles` (3 x #triangles, indices into numVertices vertices) subdivided
// `factor` >= 1 times per edge: sample points at barycentric coordinates (i, j, k) / factor with
// i + j + k = factor on each triangle, so a triangle has (factor + 1)(factor + 2) / 2 points.
// Throws std::invalid_argument for factor < 1 or an index out of range.
SurfaceSampling superSample(const TriangleList& triangles, int numVertices, int factor = 3);

}  // namespace viscera::obs
