#include <algorithm>
#include <array>
#include <numeric>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "core/Error.h"
#include "io/mesh/Mesh.h"

namespace viscera::io {
namespace {

[[noreturn]] void fail(const std::string& source, const std::string& what) { throw Error(SourceLoc{source, 0, 0}, what); }

std::string shortNumber(double v) {
  std::ostringstream s;
  s.precision(3);
  s << v;
  return s.str();
}

template <int N>
void checkIndices(const Eigen::Matrix<int, N, Eigen::Dynamic>& cells, Eigen::Index numPoints, const std::string& source,
                  const char* noun) {
  for (Eigen::Index c = 0; c < cells.cols(); ++c)
    for (int k = 0; k < N; ++k)
      if (cells(k, c) < 0 || cells(k, c) >= numPoints)
        fail(source, std::string(noun) + " " + std::to_string(c) + " refers to node " + std::to_string(cells(k, c)) + ", but the mesh has " +
                         std::to_string(numPoints) + " nodes");
}

}  // namespace

int checkTetMesh(const VolumeMesh& mesh, const std::string& source) {
  const Eigen::Index numTets = mesh.tets.cols(), numPoints = mesh.points.cols();
  if (numTets == 0) fail(source, "no tetrahedra");
  for (Eigen::Index i = 0; i < numPoints; ++i)
    if (!mesh.points.col(i).allFinite()) fail(source, "node " + std::to_string(i) + " has a coordinate that is not finite");
  checkIndices<4>(mesh.tets, numPoints, source, "tetrahedron");
  checkIndices<3>(mesh.triangles, numPoints, source, "triangle");

  std::vector<signed char> sign(static_cast<size_t>(numTets));
  Eigen::Index positive = 0;
  for (Eigen::Index c = 0; c < numTets; ++c) {
    const Eigen::Vector3d p0 = mesh.points.col(mesh.tets(0, c));
    Eigen::Matrix3d edges;
    for (int k = 0; k < 3; ++k) edges.col(k) = mesh.points.col(mesh.tets(k + 1, c)) - p0;
    const double volume = edges.determinant() / 6.0;
    double longest = 0;  // over all six edges
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        longest = std::max(longest, (mesh.points.col(mesh.tets(a, c)) - mesh.points.col(mesh.tets(b, c))).norm());
    // Relative to the tet's own size, so the test is independent of the length unit.
    if (std::abs(volume) <= 1e-12 * longest * longest * longest)
      fail(source, "tetrahedron " + std::to_string(c) + " is degenerate (volume " + shortNumber(volume) + ", longest edge " +
                       shortNumber(longest) + ")");
    sign[static_cast<size_t>(c)] = volume > 0 ? 1 : -1;
    positive += volume > 0;
  }
  // The majority sets the orientation; the first tet against it is reported.
  const int orientation = 2 * positive >= numTets ? 1 : -1;
  const Eigen::Index inverted = orientation > 0 ? numTets - positive : positive;
  if (inverted > 0) {
    const auto first = std::find(sign.begin(), sign.end(), static_cast<signed char>(-orientation)) - sign.begin();
    fail(source, "tetrahedron " + std::to_string(first) + " is inverted (" + (orientation > 0 ? "negative" : "positive") +
                     " volume) while others are " + (orientation > 0 ? "positive" : "negative") + " (" + std::to_string(inverted) +
                     " of " + std::to_string(numTets) + " tetrahedra are inverted)");
  }
  return orientation;
}

TriangleList boundaryTriangles(const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets, const Eigen::Matrix3Xd& points) {
  // Face k of a tetrahedron is the one opposite its node k.
  static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  struct Face {
    std::array<int, 3> sorted;
    int tet, local;
  };
  std::vector<Face> faces;
  faces.reserve(4 * static_cast<size_t>(tets.cols()));
  for (Eigen::Index e = 0; e < tets.cols(); ++e)
    for (int k = 0; k < 4; ++k) {
      std::array<int, 3> v = {tets(kFace[k][0], e), tets(kFace[k][1], e), tets(kFace[k][2], e)};
      std::sort(v.begin(), v.end());
      faces.push_back({v, static_cast<int>(e), k});
    }
  std::vector<size_t> order(faces.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return faces[a].sorted < faces[b].sorted; });
  std::vector<char> boundary(faces.size(), 0);
  for (size_t i = 0; i < order.size();) {
    size_t j = i + 1;
    while (j < order.size() && faces[order[j]].sorted == faces[order[i]].sorted) ++j;
    if (j == i + 1) boundary[order[i]] = 1;
    i = j;
  }
  // Emitted in the order of their sorted node triples, so the result does not depend on how the
  // tetrahedra are numbered.
  std::vector<int> out;
  for (size_t f : order) {
    if (!boundary[f]) continue;
    const int e = faces[f].tet, k = faces[f].local;
    std::array<int, 3> tri = {tets(kFace[k][0], e), tets(kFace[k][1], e), tets(kFace[k][2], e)};
    // Outwards: the opposite node lies behind the face.
    const Eigen::Vector3d a = points.col(tri[0]), b = points.col(tri[1]), c = points.col(tri[2]);
    if ((b - a).cross(c - a).dot(points.col(tets(k, e)) - a) > 0) std::swap(tri[1], tri[2]);
    out.insert(out.end(), tri.begin(), tri.end());
  }
  return Eigen::Map<const Eigen::Matrix<int, 3, Eigen::Dynamic>>(out.data(), 3, static_cast<Eigen::Index>(out.size() / 3));
}

}  // namespace viscera::io
