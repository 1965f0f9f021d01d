#include "observation/SurfaceSampling.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace viscera::obs {

void SurfaceSampling::sample(const Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& out) const {
  if (x.cols() != weights.cols())
    throw std::invalid_argument("SurfaceSampling::sample: " + std::to_string(x.cols()) + " vertex positions for a sampling of " +
                                std::to_string(weights.cols()) + " vertices");
  out.resize(3, weights.rows());
  const int* outer = weights.outerIndexPtr();
  const int* inner = weights.innerIndexPtr();
  const double* w = weights.valuePtr();
  for (Eigen::Index s = 0; s < weights.rows(); ++s) {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int k = outer[s]; k < outer[s + 1]; ++k) p += w[k] * x.col(inner[k]);
    out.col(s) = p;
  }
}

Eigen::Matrix3Xd SurfaceSampling::sample(const Eigen::Matrix3Xd& x) const {
  Eigen::Matrix3Xd out;
  sample(x, out);
  return out;
}

SurfaceSampling superSample(const TriangleList& triangles, int numVertices, int factor) {
  if (factor < 1) throw std::invalid_argument("superSample: the factor must be at least 1, got " + std::to_string(factor));
  for (Eigen::Index t = 0; t < triangles.cols(); ++t)
    for (int k = 0; k < 3; ++k)
      if (triangles(k, t) < 0 || triangles(k, t) >= numVertices)
        throw std::invalid_argument("superSample: triangle " + std::to_string(t) + " refers to vertex " +
                                    std::to_string(triangles(k, t)) + " of " + std::to_string(numVertices));
  std::vector<Eigen::Triplet<double>> entries;
  int numSamples = 0;

  // The vertices the triangles use.
  std::vector<char> used(static_cast<size_t>(numVertices), 0);
  for (Eigen::Index t = 0; t < triangles.cols(); ++t)
    for (int k = 0; k < 3; ++k) used[static_cast<size_t>(triangles(k, t))] = 1;
  for (int v = 0; v < numVertices; ++v)
    if (used[static_cast<size_t>(v)]) entries.emplace_back(numSamples++, v, 1.0);

  // The factor - 1 points inside each edge, from its lower vertex a to b: a + s / factor (b - a).
  const double step = 1.0 / factor;
  if (factor >= 2) {
    std::vector<std::pair<int, int>> edges;
    edges.reserve(static_cast<size_t>(3 * triangles.cols()));
    for (Eigen::Index t = 0; t < triangles.cols(); ++t)
      for (int k = 0; k < 3; ++k) {
        const int a = triangles(k, t), b = triangles((k + 1) % 3, t);
        edges.emplace_back(std::min(a, b), std::max(a, b));
      }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    for (const auto& [a, b] : edges)
      for (int s = 1; s < factor; ++s) {
        entries.emplace_back(numSamples, a, (factor - s) * step);
        entries.emplace_back(numSamples, b, s * step);
        ++numSamples;
      }
  }

  // The points strictly inside each triangle: barycentric (i, j, k) / factor with i, j, k >= 1.
  for (Eigen::Index t = 0; t < triangles.cols(); ++t)
    for (int i = 1; i < factor; ++i)
      for (int j = 1; i + j < factor; ++j) {
        const int k = factor - i - j;
        entries.emplace_back(numSamples, triangles(0, t), i * step);
        entries.emplace_back(numSamples, triangles(1, t), j * step);
        entries.emplace_back(numSamples, triangles(2, t), k * step);
        ++numSamples;
      }

  SurfaceSampling out;
  out.factor = factor;
  out.weights.resize(numSamples, numVertices);
  out.weights.setFromTriplets(entries.begin(), entries.end());
  return out;
}

}  // namespace viscera::obs
