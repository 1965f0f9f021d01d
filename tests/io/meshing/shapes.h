// Surfaces for the meshing tests, built in code so their volumes and areas are known: an
// icosphere, a box with subdivided faces, cubes that touch along an edge or at a corner; and a
// plain OFF writer for surfaces that OpenMesh's half-edge writer refuses (non-manifold ones).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "io/surface/SurfaceMesh.h"

namespace viscera_test {

using viscera::io::SurfaceMesh;

inline SurfaceMesh makeSurface(const std::vector<Eigen::Vector3d>& points, const std::vector<std::array<int, 3>>& triangles) {
  SurfaceMesh s;
  s.points.resize(3, static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) s.points.col(static_cast<Eigen::Index>(i)) = points[i];
  s.triangles.resize(3, static_cast<Eigen::Index>(triangles.size()));
  for (size_t t = 0; t < triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) s.triangles(k, static_cast<Eigen::Index>(t)) = triangles[t][static_cast<size_t>(k)];
  return s;
}

// Icosahedron subdivided `levels` times (each triangle into four, new vertices pushed onto the
// sphere), oriented outwards: 10 * 4^levels + 2 vertices, 20 * 4^levels triangles.
inline SurfaceMesh icosphere(int levels, double radius) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> p = {{-1, g, 0},  {1, g, 0},  {-1, -g, 0}, {1, -g, 0}, {0, -1, g},  {0, 1, g},
                                    {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
  std::vector<std::array<int, 3>> t = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                       {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                       {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& q : p) q.normalize();
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> middle;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = middle.find(key);
      if (it != middle.end()) return it->second;
      p.push_back((p[static_cast<size_t>(a)] + p[static_cast<size_t>(b)]).normalized());
      return middle[key] = static_cast<int>(p.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& f : t) {
      const int a = mid(f[0], f[1]), b = mid(f[1], f[2]), c = mid(f[2], f[0]);
      next.push_back({f[0], a, c});
      next.push_back({f[1], b, a});
      next.push_back({f[2], c, b});
      next.push_back({a, b, c});
    }
    t = std::move(next);
  }
  for (auto& q : p) q *= radius;
  return makeSurface(p, t);
}

// The surface of the box [0, size.x] x [0, size.y] x [0, size.z] with n.x x n.y x n.z cells:
// every face is a grid of squares split into two triangles, oriented outwards. Vertices are shared
// between faces. `skipTop` leaves the face z = size.z out (an open box).
inline SurfaceMesh gridBox(const Eigen::Vector3d& size, const std::array<int, 3>& n, bool skipTop = false) {
  std::map<std::array<int, 3>, int> index;
  std::vector<Eigen::Vector3d> points;
  auto vertex = [&](std::array<int, 3> ijk) {
    auto it = index.find(ijk);
    if (it != index.end()) return it->second;
    Eigen::Vector3d p;
    for (int k = 0; k < 3; ++k) p[k] = size[k] * ijk[static_cast<size_t>(k)] / n[static_cast<size_t>(k)];
    points.push_back(p);
    return index[ijk] = static_cast<int>(points.size()) - 1;
  };
  std::vector<std::array<int, 3>> triangles;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      if (skipTop && axis == 2 && side == 1) continue;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;  // (u, v, axis) is right-handed
      for (int i = 0; i < n[static_cast<size_t>(u)]; ++i)
        for (int j = 0; j < n[static_cast<size_t>(v)]; ++j) {
          auto corner = [&](int di, int dj) {
            std::array<int, 3> ijk{};
            ijk[static_cast<size_t>(axis)] = side * n[static_cast<size_t>(axis)];
            ijk[static_cast<size_t>(u)] = i + di;
            ijk[static_cast<size_t>(v)] = j + dj;
            return vertex(ijk);
          };
          const int a = corner(0, 0), b = corner(1, 0), c = corner(1, 1), d = corner(0, 1);
          // Counter-clockwise in (u, v) faces +axis; the side at 0 faces -axis.
          if (side == 1) {
            triangles.push_back({a, b, c});
            triangles.push_back({a, c, d});
          } else {
            triangles.push_back({a, c, b});
            triangles.push_back({a, d, c});
          }
        }
    }
  return makeSurface(points, triangles);
}

// The two-triangles-per-face unit cube moved by `offset`, appended to `s` with its own vertices
// except those that coincide with vertices already in `s` (which are shared).
inline void appendCube(SurfaceMesh& s, const Eigen::Vector3d& offset) {
  const SurfaceMesh cube = gridBox(Eigen::Vector3d(1, 1, 1), {1, 1, 1});
  std::vector<int> map;
  std::vector<Eigen::Vector3d> points;
  for (Eigen::Index i = 0; i < s.points.cols(); ++i) points.push_back(s.points.col(i));
  for (Eigen::Index i = 0; i < cube.points.cols(); ++i) {
    const Eigen::Vector3d p = cube.points.col(i) + offset;
    int found = -1;
    for (size_t j = 0; j < points.size(); ++j)
      if ((points[j] - p).norm() == 0.0) found = static_cast<int>(j);
    if (found < 0) {
      points.push_back(p);
      found = static_cast<int>(points.size()) - 1;
    }
    map.push_back(found);
  }
  std::vector<std::array<int, 3>> triangles;
  for (Eigen::Index t = 0; t < s.triangles.cols(); ++t) triangles.push_back({s.triangles(0, t), s.triangles(1, t), s.triangles(2, t)});
  for (Eigen::Index t = 0; t < cube.triangles.cols(); ++t)
    triangles.push_back({map[static_cast<size_t>(cube.triangles(0, t))], map[static_cast<size_t>(cube.triangles(1, t))],
                         map[static_cast<size_t>(cube.triangles(2, t))]});
  s = makeSurface(points, triangles);
}

// Writes an OFF file directly (any triangle soup, unlike writeSurface).
inline void writeOff(const std::string& path, const SurfaceMesh& s) {
  std::ofstream out(path);
  out.precision(17);
  out << "OFF\n" << s.points.cols() << " " << s.triangles.cols() << " 0\n";
  for (Eigen::Index i = 0; i < s.points.cols(); ++i) out << s.points(0, i) << " " << s.points(1, i) << " " << s.points(2, i) << "\n";
  for (Eigen::Index t = 0; t < s.triangles.cols(); ++t)
    out << "3 " << s.triangles(0, t) << " " << s.triangles(1, t) << " " << s.triangles(2, t) << "\n";
}

// The triangles of a surface as sorted triples of corner coordinates, each triangle's corners in
// cyclic order starting from the smallest (orientation kept), for comparing surfaces whose vertex
// numbers differ.
inline std::vector<std::array<double, 9>> triangleSet(const Eigen::Matrix3Xd& points,
                                                      const Eigen::Matrix<int, 3, Eigen::Dynamic>& triangles) {
  std::vector<std::array<double, 9>> out;
  for (Eigen::Index t = 0; t < triangles.cols(); ++t) {
    std::array<std::array<double, 3>, 3> c;
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) c[static_cast<size_t>(k)][static_cast<size_t>(d)] = points(d, triangles(k, t));
    const auto first = std::min_element(c.begin(), c.end()) - c.begin();
    std::array<double, 9> row{};
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) row[static_cast<size_t>(3 * k + d)] = c[static_cast<size_t>((first + k) % 3)][static_cast<size_t>(d)];
    out.push_back(row);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace viscera_test
