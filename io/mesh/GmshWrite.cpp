// Gmsh MSH 2.2 ASCII writer (the format MeshGmshLoader and readGmsh read back, and Gmsh opens).
#include <cstdio>
#include <string>

#include "core/Files.h"
#include "core/Error.h"
#include "io/mesh/Mesh.h"

namespace viscera::io {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) { throw Error(SourceLoc{path}, what); }

template <int N>
void checkCells(const std::string& path, const Eigen::Matrix<int, N, Eigen::Dynamic>& cells, Eigen::Index numPoints, const char* noun) {
  for (Eigen::Index c = 0; c < cells.cols(); ++c)
    for (int k = 0; k < N; ++k)
      if (cells(k, c) < 0 || cells(k, c) >= numPoints)
        fail(path, std::string("cannot write: ") + noun + " " + std::to_string(c) + " refers to node " + std::to_string(cells(k, c)) +
                       ", but there are " + std::to_string(numPoints) + " nodes");
}

// Appends an element line: number, type, two tags (physical, elementary), 1-based nodes.
template <int N>
void appendElements(std::string& out, long long& number, int type, const Eigen::Matrix<int, N, Eigen::Dynamic>& cells) {
  char buffer[64];
  for (Eigen::Index c = 0; c < cells.cols(); ++c) {
    out += std::to_string(++number) + " " + std::to_string(type) + " 2 1 1";
    for (int k = 0; k < N; ++k) {
      std::snprintf(buffer, sizeof buffer, " %d", cells(k, c) + 1);
      out += buffer;
    }
    out += "\n";
  }
}

}  // namespace

void writeGmsh(const std::string& path, const VolumeMesh& mesh) {
  const Eigen::Index numPoints = mesh.points.cols();
  for (Eigen::Index i = 0; i < numPoints; ++i)
    if (!mesh.points.col(i).allFinite()) fail(path, "cannot write: node " + std::to_string(i) + " is not finite");
  checkCells<4>(path, mesh.tets, numPoints, "tetrahedron");
  checkCells<3>(path, mesh.triangles, numPoints, "triangle");

  std::string out = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" + std::to_string(numPoints) + "\n";
  char buffer[96];
  for (Eigen::Index i = 0; i < numPoints; ++i) {
    // 17 significant digits: the doubles read back bit for bit.
    std::snprintf(buffer, sizeof buffer, "%lld %.17g %.17g %.17g\n", static_cast<long long>(i + 1), mesh.points(0, i), mesh.points(1, i),
                  mesh.points(2, i));
    out += buffer;
  }
  out += "$EndNodes\n$Elements\n" + std::to_string(mesh.triangles.cols() + mesh.tets.cols()) + "\n";
  long long number = 0;
  appendElements<3>(out, number, 2, mesh.triangles);
  appendElements<4>(out, number, 4, mesh.tets);
  out += "$EndElements\n";
  writeFileAtomic(path, out);
}

}  // namespace viscera::io
