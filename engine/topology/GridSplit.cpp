#include "engine/topology/GridSplit.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <map>

#include <utility>

namespace viscera {

Eigen::Matrix3Xd gridPoints(const std::array<int, 3>& n, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                            const Eigen::Vector3d* p0) {
  Eigen::Matrix3Xd p(3, n[0] * n[1] * n[2]);
  Eigen::Vector3d step, origin = lo;
  for (int a = 0; a < 3; ++a) {
    step[a] = n[a] > 1 ? (hi[a] - lo[a]) / (n[a] - 1) : 0.0;
    // One node on an axis sits at the middle of [lo, hi] (x and y) as in SOFA.
    if (n[a] == 1 && a < 2) origin[a] = 0.5 * (lo[a] + hi[a]);
  }
  if (p0) origin = *p0;
  int idx = 0;
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i) p.col(idx++) = origin + Eigen::Vector3d(i * step[0], j * step[1], k * step[2]);
  return p;
}

HexList gridHexahedra(const std::array<int, 3>& n) {
  HexList h;
  auto id = [&](int i, int j, int k) { return i + n[0] * (j + n[1] * k); };
  for (int k = 0; k + 1 < n[2]; ++k)
    for (int j = 0; j + 1 < n[1]; ++j)
      for (int i = 0; i + 1 < n[0]; ++i)
        h.push_back({id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1),
                     id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)});
  return h;
}

TetList splitHexahedra(const HexList& hexa, int nx, int ny, bool swapping, bool fixOrientation) {
  static const int straight[6][4] = {{0, 5, 1, 6}, {0, 1, 3, 6}, {1, 3, 6, 2}, {6, 3, 0, 7}, {6, 7, 0, 5}, {7, 5, 4, 0}};
  static const int mirrored[6][4] = {{0, 5, 6, 1}, {0, 1, 6, 3}, {1, 3, 2, 6}, {6, 3, 7, 0}, {6, 7, 5, 0}, {7, 5, 0, 4}};
  TetList t(4, 6 * hexa.size());
  for (size_t i = 0; i < hexa.size(); ++i) {
    std::array<int, 8> c = hexa[i];
    bool swapped = false;
    if (swapping) {
      const size_t ix = static_cast<size_t>(nx), iy = static_cast<size_t>(ny);
      if (!((i % ix) & 1)) {
        std::swap(c[0], c[1]); std::swap(c[4], c[5]); std::swap(c[3], c[2]); std::swap(c[7], c[6]);
        swapped = !swapped;
      }
      if (((i / ix) % iy) & 1) {
        std::swap(c[4], c[7]); std::swap(c[5], c[6]); std::swap(c[1], c[2]); std::swap(c[0], c[3]);
        swapped = !swapped;
      }
      if ((i / (ix * iy)) & 1) {
        std::swap(c[4], c[0]); std::swap(c[5], c[1]); std::swap(c[6], c[2]); std::swap(c[7], c[3]);
        swapped = !swapped;
      }
    }
    const int(*pattern)[4] = swapped && fixOrientation ? mirrored : straight;
    for (int k = 0; k < 6; ++k)
      for (int v = 0; v < 4; ++v) t(v, 6 * i + k) = c[pattern[k][v]];
  }
  return t;
}

TetList elementTetrahedra(const Topology& topo) {
  if (topo.tetrahedra().cols() > 0) return topo.tetrahedra();
  // Directly on hexahedra, SOFA's force field applies the mirroring tests of the swapping split
  // but always the straight vertex order.
  auto cells = topo.gridCells();
  if (cells[0] == 0) cells = {2, 1, 1};
  return splitHexahedra(topo.hexahedra(), cells[0], cells[1], true, false);
}

Eigen::Matrix<int, 4, Eigen::Dynamic> hexahedronBoundaryQuads(const HexList& hexa, const Eigen::Matrix3Xd& X) {
  // Outward faces of a hexahedron whose nodes are (0,0,0) (1,0,0) (1,1,0) (0,1,0), then z = 1.
  static const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  std::map<std::array<int, 4>, std::pair<int, std::array<int, 4>>> seen;  // sorted corners -> count, face
  for (const auto& h : hexa) {
    // Mirrored (negative volume at its centre, from the mean edges): its faces point inwards.
    const Eigen::Vector3d ex = X.col(h[1]) - X.col(h[0]) + X.col(h[2]) - X.col(h[3]) + X.col(h[5]) - X.col(h[4]) + X.col(h[6]) - X.col(h[7]);
    const Eigen::Vector3d ey = X.col(h[3]) - X.col(h[0]) + X.col(h[2]) - X.col(h[1]) + X.col(h[7]) - X.col(h[4]) + X.col(h[6]) - X.col(h[5]);
    const Eigen::Vector3d ez = X.col(h[4]) - X.col(h[0]) + X.col(h[5]) - X.col(h[1]) + X.col(h[6]) - X.col(h[2]) + X.col(h[7]) - X.col(h[3]);
    const bool mirrored = ex.dot(ey.cross(ez)) < 0;
    for (const auto& f : faces) {
      std::array<int, 4> q{h[f[0]], h[f[1]], h[f[2]], h[f[3]]}, key = q;
      if (mirrored) std::swap(q[1], q[3]);
      std::sort(key.begin(), key.end());
      auto [it, fresh] = seen.try_emplace(key, 0, q);
      ++it->second.first;
    }
  }
  std::vector<std::array<int, 4>> boundary;
  for (const auto& [key, entry] : seen)
    if (entry.first == 1) boundary.push_back(entry.second);
  Eigen::Matrix<int, 4, Eigen::Dynamic> quads(4, boundary.size());
  for (size_t i = 0; i < boundary.size(); ++i) quads.col(static_cast<Eigen::Index>(i)) << boundary[i][0], boundary[i][1], boundary[i][2], boundary[i][3];
  return quads;
}

Eigen::Matrix<int, 3, Eigen::Dynamic> quadTriangles(const Eigen::Matrix<int, 4, Eigen::Dynamic>& quads) {
  Eigen::Matrix<int, 3, Eigen::Dynamic> tris(3, 2 * quads.cols());
  for (Eigen::Index i = 0; i < quads.cols(); ++i) {
    tris.col(2 * i) << quads(0, i), quads(1, i), quads(2, i);
    tris.col(2 * i + 1) << quads(0, i), quads(2, i), quads(3, i);
  }
  return tris;
}

Eigen::Matrix<int, 3, Eigen::Dynamic> hexahedronBoundaryTriangles(const HexList& hexa, const Eigen::Matrix3Xd& X) {
  return quadTriangles(hexahedronBoundaryQuads(hexa, X));
}

}  // namespace viscera
