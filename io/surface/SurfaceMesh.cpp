// Surface files through OpenMesh's readers and writers, and the topological checks of a triangle
// surface (boundary, manifoldness, orientation), done on the indexed triangles.
#include "io/surface/SurfaceMesh.h"
#include "core/Files.h"

#include <Eigen/Geometry>
#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/IO/importer/ImporterT.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <numeric>
#include <sstream>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "core/Error.h"
#include "io/mesh/Mesh.h"

namespace viscera::io {
namespace {

[[noreturn]] void fail(const std::string& file, const std::string& what) { throw Error(SourceLoc{file}, what); }

// Double-precision points, so that writing does not round coordinates to float.
struct DoubleTraits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using OmMesh = OpenMesh::TriMesh_ArrayKernelT<DoubleTraits>;

enum class Format { Obj, Stl, Off, Ply };

struct FormatInfo {
  Format format;
  const char* extension;  // with the dot, as OpenMesh's stream interface wants it
};

FormatInfo formatOf(const std::string& path, const char* doing) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".obj") return {Format::Obj, ".obj"};
  if (ext == ".stl") return {Format::Stl, ".stl"};
  if (ext == ".off") return {Format::Off, ".off"};
  if (ext == ".ply") return {Format::Ply, ".ply"};
  fail(path, std::string("cannot ") + doing + " surface: unsupported format " + (ext.empty() ? "(no extension)" : "'" + ext + "'") +
                 "; expected .obj, .stl, .off or .ply");
}

std::string formatPoint(const Eigen::Vector3d& p) {
  std::ostringstream s;
  s.precision(6);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

std::string plural(long long n, const std::string& one, const std::string& many) { return std::to_string(n) + " " + (n == 1 ? one : many); }

// OpenMesh reports through its global streams omerr, omlog and omout, which print to the terminal.
// While a file is read or written their text goes to a string instead, for our error messages. The
// streams are process-wide, so a mutex keeps two threads from redirecting them at once.
class CapturedOpenMeshOutput {
 public:
  CapturedOpenMeshOutput() : lock_(mutex()) {
    for (auto& s : streams_) {
      s.toCerr = s.stream->disconnect(std::cerr);
      s.toClog = s.stream->disconnect(std::clog);
      s.toCout = s.stream->disconnect(std::cout);
      s.stream->connect(text_);
    }
  }
  ~CapturedOpenMeshOutput() {
    for (auto& s : streams_) {
      s.stream->flush();
      s.stream->disconnect(text_);
      if (s.toCerr) s.stream->connect(std::cerr);
      if (s.toClog) s.stream->connect(std::clog);
      if (s.toCout) s.stream->connect(std::cout);
    }
  }
  CapturedOpenMeshOutput(const CapturedOpenMeshOutput&) = delete;
  CapturedOpenMeshOutput& operator=(const CapturedOpenMeshOutput&) = delete;

  // What OpenMesh said so far, on one line ("" if nothing).
  std::string text() {
    for (auto& s : streams_) s.stream->flush();
    std::string t = text_.str();
    std::replace(t.begin(), t.end(), '\n', ' ');
    while (!t.empty() && std::isspace(static_cast<unsigned char>(t.back()))) t.pop_back();
    return t;
  }

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  struct Redirected {
    OpenMesh::mostream* stream;
    bool toCerr = false, toClog = false, toCout = false;
  };
  std::lock_guard<std::mutex> lock_;
  std::ostringstream text_;
  Redirected streams_[3] = {{&omerr()}, {&omlog()}, {&omout()}};
};

// Records the vertices and faces as the reader delivers them (file order, 0-based) and passes them
// on to OpenMesh's own importer, which the readers also use for normals and options. The records
// are what readSurface returns: the half-edge mesh behind them gives non-manifold and misoriented
// faces vertices of their own, which would hide exactly what checkSurface looks for.
class RecordingImporter : public OpenMesh::IO::ImporterT<OmMesh> {
  using Base = OpenMesh::IO::ImporterT<OmMesh>;

 public:
  explicit RecordingImporter(OmMesh& mesh) : Base(mesh) {}

  OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3f& p) override {
    return record(Base::add_vertex(p), OpenMesh::Vec3d(p[0], p[1], p[2]));
  }
  OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3d& p) override { return record(Base::add_vertex(p), p); }
  // The PLY reader adds vertices without coordinates and sets them afterwards.
  OpenMesh::VertexHandle add_vertex() override { return record(Base::add_vertex(), OpenMesh::Vec3d(0, 0, 0)); }
  void set_point(OpenMesh::VertexHandle vh, const OpenMesh::Vec3f& p) override {
    Base::set_point(vh, p);
    if (const int i = fileIndex(vh); i >= 0) points[static_cast<size_t>(i)] = OpenMesh::Vec3d(p[0], p[1], p[2]);
  }
  OpenMesh::FaceHandle add_face(const VHandles& handles) override {
    std::vector<int> face;
    for (const auto& vh : handles) {
      const int i = fileIndex(vh);
      if (i < 0 && badFace < 0) {
        badFace = static_cast<long long>(faces.size());
        badVertex = vh.idx();
      }
      face.push_back(i);
    }
    faces.push_back(std::move(face));
    return Base::add_face(handles);
  }

  std::vector<OpenMesh::Vec3d> points;
  std::vector<std::vector<int>> faces;
  long long badFace = -1;  // first face that refers to a vertex the file does not have
  int badVertex = -1;      // that vertex (as the reader numbered it)

 private:
  OpenMesh::VertexHandle record(OpenMesh::VertexHandle vh, const OpenMesh::Vec3d& p) {
    if (vh.idx() < 0) return vh;
    if (static_cast<size_t>(vh.idx()) >= fileIndexOfHandle_.size()) fileIndexOfHandle_.resize(static_cast<size_t>(vh.idx()) + 1, -1);
    fileIndexOfHandle_[static_cast<size_t>(vh.idx())] = static_cast<int>(points.size());
    points.push_back(p);
    return vh;
  }
  int fileIndex(OpenMesh::VertexHandle vh) const {
    const int h = vh.idx();
    return h >= 0 && static_cast<size_t>(h) < fileIndexOfHandle_.size() ? fileIndexOfHandle_[static_cast<size_t>(h)] : -1;
  }
  // OpenMesh vertex handle -> index in `points`; -1 for vertices the half-edge mesh added itself.
  std::vector<int> fileIndexOfHandle_;
};

// Merges each vertex into the first kept vertex found within `tolerance`, renumbers the
// triangles and drops vertices that no triangle uses. Cells of a grid as wide as the tolerance
// hold the kept vertices, so each vertex is compared with the 27 cells around its own.
void weldVertices(SurfaceMesh& s, double tolerance) {
  const Eigen::Index n = s.points.cols();
  std::vector<int> target(static_cast<size_t>(n));
  std::iota(target.begin(), target.end(), 0);
  if (tolerance > 0 && n > 0) {
    const Eigen::Vector3d origin = s.points.rowwise().minCoeff();
    auto cellOf = [&](Eigen::Index i) { return ((s.points.col(i) - origin) / tolerance).array().floor().cast<std::int64_t>().eval(); };
    auto key = [](std::int64_t x, std::int64_t y, std::int64_t z) {
      return (static_cast<std::uint64_t>(x) * 73856093u) ^ (static_cast<std::uint64_t>(y) * 19349663u) ^
             (static_cast<std::uint64_t>(z) * 83492791u);
    };
    std::unordered_multimap<std::uint64_t, int> kept;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto c = cellOf(i);
      int found = -1;
      for (int dx = -1; dx <= 1 && found < 0; ++dx)
        for (int dy = -1; dy <= 1 && found < 0; ++dy)
          for (int dz = -1; dz <= 1 && found < 0; ++dz) {
            auto [b, e] = kept.equal_range(key(c.x() + dx, c.y() + dy, c.z() + dz));
            for (auto it = b; it != e && found < 0; ++it)
              if ((s.points.col(it->second) - s.points.col(i)).norm() <= tolerance) found = it->second;
          }
      if (found >= 0) {
        target[static_cast<size_t>(i)] = found;
      } else {
        kept.emplace(key(c.x(), c.y(), c.z()), static_cast<int>(i));
      }
    }
  }
  // Renumber the vertices that triangles use, in order of first appearance in the old numbering.
  std::vector<int> used(static_cast<size_t>(n), 0);
  for (Eigen::Index t = 0; t < s.triangles.cols(); ++t)
    for (int k = 0; k < 3; ++k) used[static_cast<size_t>(target[static_cast<size_t>(s.triangles(k, t))])] = 1;
  std::vector<int> newIndex(static_cast<size_t>(n), -1);
  int count = 0;
  for (Eigen::Index i = 0; i < n; ++i)
    if (used[static_cast<size_t>(i)]) newIndex[static_cast<size_t>(i)] = count++;
  Eigen::Matrix3Xd points(3, count);
  for (Eigen::Index i = 0; i < n; ++i)
    if (newIndex[static_cast<size_t>(i)] >= 0) points.col(newIndex[static_cast<size_t>(i)]) = s.points.col(i);
  for (Eigen::Index t = 0; t < s.triangles.cols(); ++t)
    for (int k = 0; k < 3; ++k) s.triangles(k, t) = newIndex[static_cast<size_t>(target[static_cast<size_t>(s.triangles(k, t))])];
  s.points = std::move(points);
}

// Whether a triangle names one vertex twice (such triangles are degenerate and have no proper edges).
bool repeatsVertex(const SurfaceMesh& s, Eigen::Index t) {
  return s.triangles(0, t) == s.triangles(1, t) || s.triangles(1, t) == s.triangles(2, t) || s.triangles(0, t) == s.triangles(2, t);
}

void checkIndices(const SurfaceMesh& s, const std::string& source, const char* doing) {
  const Eigen::Index n = s.points.cols();
  for (Eigen::Index t = 0; t < s.triangles.cols(); ++t)
    for (int k = 0; k < 3; ++k)
      if (s.triangles(k, t) < 0 || s.triangles(k, t) >= n)
        fail(source, std::string(doing) + "triangle " + std::to_string(t) + " refers to vertex " + std::to_string(s.triangles(k, t)) +
                         ", but the surface has " + plural(n, "vertex", "vertices"));
  for (Eigen::Index i = 0; i < n; ++i)
    if (!s.points.col(i).allFinite())
      fail(source, std::string(doing) + "vertex " + std::to_string(i) + " has a coordinate that is not finite");
}

// Union-find over triangle corners.
class Corners {
 public:
  explicit Corners(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  int find(int c) {
    while (parent_[static_cast<size_t>(c)] != c)
      c = parent_[static_cast<size_t>(c)] = parent_[static_cast<size_t>(parent_[static_cast<size_t>(c)])];
    return c;
  }
  void join(int a, int b) {
    a = find(a), b = find(b);
    if (a != b) parent_[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
  }

 private:
  std::vector<int> parent_;
};

}  // namespace

SurfaceMesh readSurface(const std::string& path) {
  const FormatInfo format = formatOf(path, "read");
  {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) fail(path, "cannot read surface: it is a directory");
    std::ifstream probe(path, std::ios::binary);
    if (!probe) fail(path, std::string("cannot open surface file: ") + std::strerror(errno));
    if (probe.peek() == std::ifstream::traits_type::eof()) fail(path, "the surface file is empty");
  }

  OmMesh mesh;
  RecordingImporter importer(mesh);
  {
    CapturedOpenMeshOutput captured;
    OpenMesh::IO::Options options;
    if (!OpenMesh::IO::IOManager().read(path, importer, options)) {
      const std::string said = captured.text();
      fail(path, std::string("OpenMesh cannot read it as ") + (format.extension + 1) + (said.empty() ? "" : ": " + said));
    }
  }
  if (importer.badFace >= 0)
    fail(path, "face " + std::to_string(importer.badFace) + " refers to vertex " + std::to_string(importer.badVertex) +
                   " (0-based), but the file has " + plural(static_cast<long long>(importer.points.size()), "vertex", "vertices"));

  SurfaceMesh s;
  s.points.resize(3, static_cast<Eigen::Index>(importer.points.size()));
  for (size_t i = 0; i < importer.points.size(); ++i)
    for (int k = 0; k < 3; ++k) s.points(k, static_cast<Eigen::Index>(i)) = importer.points[i][k];
  // Polygons become fans of triangles around their first vertex.
  std::vector<int> tri;
  for (size_t f = 0; f < importer.faces.size(); ++f) {
    const auto& face = importer.faces[f];
    if (face.size() < 3)
      fail(path, "face " + std::to_string(f) + " has only " + plural(static_cast<long long>(face.size()), "vertex", "vertices"));
    for (size_t k = 1; k + 1 < face.size(); ++k) tri.insert(tri.end(), {face[0], face[k], face[k + 1]});
  }
  s.triangles = Eigen::Map<const Eigen::Matrix<int, 3, Eigen::Dynamic>>(tri.data(), 3, static_cast<Eigen::Index>(tri.size() / 3));
  if (s.triangles.cols() == 0) fail(path, "no triangles in the file (" + plural(s.points.cols(), "vertex", "vertices") + ", no faces)");
  checkIndices(s, path, "");
  if (format.format == Format::Stl) {
    const double diagonal = (s.points.rowwise().maxCoeff() - s.points.rowwise().minCoeff()).norm();
    weldVertices(s, 1e-6 * diagonal);
  }
  return s;
}

void writeSurface(const std::string& path, const SurfaceMesh& surface, bool binary) {
  const FormatInfo format = formatOf(path, "write");
  if (surface.triangles.cols() == 0) fail(path, "cannot write surface: it has no triangles");
  checkIndices(surface, path, "cannot write surface: ");

  std::ostringstream out;
  {
    CapturedOpenMeshOutput captured;
    OmMesh mesh;
    mesh.reserve(static_cast<size_t>(surface.points.cols()), 3 * static_cast<size_t>(surface.triangles.cols()) / 2,
                 static_cast<size_t>(surface.triangles.cols()));
    for (Eigen::Index i = 0; i < surface.points.cols(); ++i)
      mesh.add_vertex(OpenMesh::Vec3d(surface.points(0, i), surface.points(1, i), surface.points(2, i)));
    for (Eigen::Index t = 0; t < surface.triangles.cols(); ++t) {
      const auto v = [&](int k) { return OpenMesh::VertexHandle(surface.triangles(k, t)); };
      if (repeatsVertex(surface, t) || !mesh.add_face(v(0), v(1), v(2)).is_valid())
        fail(path, "cannot write surface: triangle " + std::to_string(t) + " (vertices " + std::to_string(surface.triangles(0, t)) + ", " +
                       std::to_string(surface.triangles(1, t)) + ", " + std::to_string(surface.triangles(2, t)) +
                       ") does not fit a manifold, consistently oriented surface, the only kind OpenMesh's half-edge mesh holds");
    }
    OpenMesh::IO::Options options;
    if (binary && (format.format == Format::Stl || format.format == Format::Ply)) options += OpenMesh::IO::Options::Binary;
    if (!OpenMesh::IO::write_mesh(mesh, out, format.extension, options, 17)) {
      const std::string said = captured.text();
      fail(path,
           std::string("cannot write surface: OpenMesh failed to write ") + (format.extension + 1) + (said.empty() ? "" : ": " + said));
    }
  }
  writeFileAtomic(path, out.str());
}

SurfaceCheck checkSurface(const SurfaceMesh& s) {
  checkIndices(s, "", "");
  SurfaceCheck c;
  const Eigen::Index numTris = s.triangles.cols();
  if (numTris == 0) return c;

  // Volume by the divergence theorem, sum of signed tetrahedra (reference point, triangle); the
  // reference is the mean vertex, which keeps the terms small for surfaces far from the origin.
  const Eigen::Vector3d ref = s.points.rowwise().mean();
  struct EdgeUse {
    int a, b;  // a < b
    int tri;
    bool forward;  // the triangle runs a -> b
  };
  std::vector<EdgeUse> uses;
  uses.reserve(3 * static_cast<size_t>(numTris));
  for (Eigen::Index t = 0; t < numTris; ++t) {
    const Eigen::Vector3d p0 = s.points.col(s.triangles(0, t)), p1 = s.points.col(s.triangles(1, t)), p2 = s.points.col(s.triangles(2, t));
    const Eigen::Vector3d cross = (p1 - p0).cross(p2 - p0);
    c.area += 0.5 * cross.norm();
    c.volume += (p0 - ref).dot((p1 - ref).cross(p2 - ref)) / 6.0;
    const double longest = std::max({(p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm()});
    if (repeatsVertex(s, t) || cross.norm() <= 1e-12 * longest * longest) {
      if (c.degenerateTriangles++ == 0) c.degenerateTriangleExample = static_cast<int>(t);
      if (repeatsVertex(s, t)) continue;
    }
    for (int k = 0; k < 3; ++k) {
      const int from = s.triangles(k, t), to = s.triangles((k + 1) % 3, t);
      uses.push_back({std::min(from, to), std::max(from, to), static_cast<int>(t), from < to});
    }
  }
  std::sort(uses.begin(), uses.end(),
            [](const EdgeUse& x, const EdgeUse& y) { return std::tie(x.a, x.b, x.tri, x.forward) < std::tie(y.a, y.b, y.tri, y.forward); });

  // Corner (t, k) is 3t + k. Triangles around a vertex that share an edge at it belong to the same
  // fan: joining their corners there leaves one set per fan.
  Corners corners(3 * static_cast<size_t>(numTris));
  auto cornerOf = [&](int t, int v) {
    for (int k = 0; k < 3; ++k)
      if (s.triangles(k, t) == v) return 3 * t + k;
    return -1;  // not reached: v is a vertex of t
  };
  for (size_t begin = 0; begin < uses.size();) {
    size_t end = begin + 1;
    while (end < uses.size() && uses[end].a == uses[begin].a && uses[end].b == uses[begin].b) ++end;
    const int count = static_cast<int>(end - begin);
    const std::array<int, 2> edge{uses[begin].a, uses[begin].b};
    if (count == 1) {
      if (c.boundaryEdges++ == 0) c.boundaryEdgeExample = edge;
    } else if (count > 2) {
      if (c.nonManifoldEdges++ == 0) {
        c.nonManifoldEdgeExample = edge;
        c.nonManifoldEdgeExampleTriangles = count;
      }
    } else if (uses[begin].forward == uses[begin + 1].forward) {
      if (c.misorientedEdges++ == 0) c.misorientedEdgeExample = edge;
    }
    for (size_t u = begin + 1; u < end; ++u)
      for (int v : edge) corners.join(cornerOf(uses[begin].tri, v), cornerOf(uses[u].tri, v));
    begin = end;
  }
  // (vertex, fan) pairs without repeats: a vertex listed twice lies on two fans.
  std::vector<std::pair<int, int>> fans;
  fans.reserve(3 * static_cast<size_t>(numTris));
  for (Eigen::Index t = 0; t < numTris; ++t)
    if (!repeatsVertex(s, t))
      for (int k = 0; k < 3; ++k) fans.emplace_back(s.triangles(k, t), corners.find(3 * static_cast<int>(t) + k));
  std::sort(fans.begin(), fans.end());
  fans.erase(std::unique(fans.begin(), fans.end()), fans.end());
  for (size_t i = 1; i < fans.size(); ++i)
    if (fans[i].first == fans[i - 1].first && (i < 2 || fans[i - 2].first != fans[i].first)) {
      if (c.nonManifoldVertices++ == 0) c.nonManifoldVertexExample = fans[i].first;
    }
  return c;
}

void requireClosedSurface(const SurfaceMesh& surface, const std::string& source) {
  if (surface.triangles.cols() == 0) fail(source, "the surface has no triangles");
  checkIndices(surface, source, "");
  const SurfaceCheck c = checkSurface(surface);
  if (c.ok()) return;
  auto vertex = [&](int v) { return "vertex " + std::to_string(v) + " " + formatPoint(surface.points.col(v)); };
  auto edge = [&](const std::array<int, 2>& e) { return "the edge between " + vertex(e[0]) + " and " + vertex(e[1]); };
  std::vector<std::string> problems;
  if (!c.closed())
    problems.push_back("it is not closed: " + plural(c.boundaryEdges, "edge belongs", "edges belong") + " to only one triangle, e.g. " +
                       edge(c.boundaryEdgeExample));
  if (c.nonManifoldEdges > 0)
    problems.push_back("it is not manifold: " + plural(c.nonManifoldEdges, "edge is", "edges are") +
                       " shared by more than two triangles, e.g. " + edge(c.nonManifoldEdgeExample) + " (" +
                       std::to_string(c.nonManifoldEdgeExampleTriangles) + " triangles)");
  if (c.nonManifoldVertices > 0)
    problems.push_back("it is not manifold: at " + plural(c.nonManifoldVertices, "vertex", "vertices") +
                       " separate fans of triangles meet, e.g. " + vertex(c.nonManifoldVertexExample));
  if (!c.oriented())
    problems.push_back("it is not consistently oriented: " + plural(c.misorientedEdges, "edge is", "edges are") +
                       " traversed in the same direction by both of its triangles (a flipped triangle), e.g. " +
                       edge(c.misorientedEdgeExample));
  if (c.degenerateTriangles > 0) {
    const int t = c.degenerateTriangleExample;
    problems.push_back(plural(c.degenerateTriangles, "triangle has", "triangles have") + " zero area, e.g. triangle " + std::to_string(t) +
                       " (vertices " + std::to_string(surface.triangles(0, t)) + ", " + std::to_string(surface.triangles(1, t)) + ", " +
                       std::to_string(surface.triangles(2, t)) + ")");
  }
  std::string message = "the surface cannot be meshed: ";
  for (size_t i = 0; i < problems.size(); ++i) message += (i ? "; " : "") + problems[i];
  message += " (vertices are numbered from 0)";
  fail(source, message);
}

void flipSurface(SurfaceMesh& surface) { surface.triangles.row(1).swap(surface.triangles.row(2)); }

}  // namespace viscera::io
