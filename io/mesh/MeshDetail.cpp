#include "core/Files.h"
#include "io/mesh/MeshDetail.h"
#include "io/mesh/Exodus.h"

#include <cctype>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

#include "core/Error.h"
#include "core/Text.h"

namespace viscera::io {
namespace detail {

void fail(const std::string& source, int line, const std::string& what) {
  throw Error(SourceLoc{source, line, 0}, what);
}

std::string readWholeFile(const std::string& path) {
  std::string bytes = readInputFile(path, "mesh file");
  // A byte-order mark before an ASCII header (files saved by Windows editors).
  if (bytes.compare(0, 3, "\xEF\xBB\xBF") == 0) bytes.erase(0, 3);
  return bytes;
}

static bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && isSpace(s.front())) s.remove_prefix(1);
  while (!s.empty() && isSpace(s.back())) s.remove_suffix(1);
  return s;
}

bool equalsIgnoreCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && startsWithIgnoreCase(a, b);
}

bool startsWithIgnoreCase(std::string_view s, std::string_view prefix) {
  if (s.size() < prefix.size()) return false;
  for (size_t i = 0; i < prefix.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(s[i])) != std::tolower(static_cast<unsigned char>(prefix[i]))) return false;
  return true;
}

void splitTokens(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && isSpace(line[i])) ++i;
    size_t start = i;
    while (i < line.size() && !isSpace(line[i])) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
}

bool parseReal(std::string_view token, double& out) { return parseNumber(token, out) && std::isfinite(out); }

bool LineCursor::next() {
  if (pos_ >= text_.size()) return false;
  size_t end = text_.find('\n', pos_);
  if (end == std::string_view::npos) end = text_.size();
  current_ = trim(text_.substr(pos_, end - pos_));
  pos_ = end + 1;
  ++line_;
  split_ = false;
  return true;
}

bool LineCursor::nextNonBlank() {
  while (next())
    if (!current_.empty()) return true;
  return false;
}

const std::vector<std::string_view>& LineCursor::tokens() {
  if (!split_) {
    splitTokens(current_, tokens_);
    split_ = true;
  }
  return tokens_;
}

long long LineCursor::intAt(size_t i, const std::string& what) {
  const auto& t = tokens();
  if (i >= t.size()) fail("missing " + what);
  long long v;
  if (!parseInteger(t[i], v)) fail("expected an integer for " + what + ", found " + quoted(t[i]));
  return v;
}

double LineCursor::realAt(size_t i, const std::string& what) {
  const auto& t = tokens();
  if (i >= t.size()) fail("missing " + what);
  double v;
  if (!parseReal(t[i], v)) fail("expected a finite number for " + what + ", found " + quoted(t[i]));
  return v;
}

bool TokenCursor::fill() {
  if (!started_) {
    started_ = true;
    index_ = 0;
    if (!lines_.next()) return false;
  }
  while (index_ >= lines_.tokens().size()) {
    if (!lines_.next()) return false;
    index_ = 0;
  }
  return true;
}

void TokenCursor::skipToBlankLine() {
  while (lines_.next())
    if (lines_.text().empty()) break;
  skipRestOfLine();  // at end of file this also drops the last line's tokens
}

bool TokenCursor::next(std::string_view& token) {
  if (!fill()) return false;
  token = lines_.tokens()[index_++];
  return true;
}

bool TokenCursor::peek(std::string_view& token) {
  if (!fill()) return false;
  token = lines_.tokens()[index_];
  return true;
}

std::string_view TokenCursor::expect(const std::string& what) {
  std::string_view token;
  if (!next(token)) fail("file ends where " + what + " was expected");
  return token;
}

long long TokenCursor::expectInt(const std::string& what) {
  std::string_view token = expect(what);
  long long v;
  if (!parseInteger(token, v)) fail("expected an integer for " + what + ", found " + quoted(token));
  return v;
}

double TokenCursor::expectReal(const std::string& what) {
  std::string_view token = expect(what);
  double v;
  if (!parseReal(token, v)) fail("expected a finite number for " + what + ", found " + quoted(token));
  return v;
}

VolumeMesh MeshBuilder::finish() const {
  VolumeMesh mesh;
  const Eigen::Index np = static_cast<Eigen::Index>(xyz.size() / 3);
  mesh.points = Eigen::Map<const Eigen::Matrix3Xd>(xyz.data(), 3, np);
  mesh.tets = Eigen::Map<const Eigen::Matrix<int, 4, Eigen::Dynamic>>(tets.data(), 4, static_cast<Eigen::Index>(tets.size() / 4));
  mesh.triangles =
      Eigen::Map<const Eigen::Matrix<int, 3, Eigen::Dynamic>>(triangles.data(), 3, static_cast<Eigen::Index>(triangles.size() / 3));
  mesh.hexahedra =
      Eigen::Map<const Eigen::Matrix<int, 8, Eigen::Dynamic>>(hexahedra.data(), 8, static_cast<Eigen::Index>(hexahedra.size() / 8));
  mesh.quads = Eigen::Map<const Eigen::Matrix<int, 4, Eigen::Dynamic>>(quads.data(), 4, static_cast<Eigen::Index>(quads.size() / 4));
  return mesh;
}

// Names of the VTK cell types one is likely to meet, for messages.
static const char* vtkTypeName(long long type) {
  switch (type) {
    case 6: return "triangle strip";
    case 7: return "polygon";
    case 8: return "pixel";
    case 9: return "quad";
    case 11: return "voxel";
    case 12: return "hexahedron";
    case 13: return "wedge";
    case 14: return "pyramid";
    case 21: return "quadratic edge";
    case 22: return "quadratic triangle";
    case 23: return "quadratic quad";
    case 24: return "quadratic tetrahedron";
    case 25: return "quadratic hexahedron";
    default: return nullptr;
  }
}

void appendVtkCells(const VtkCells& cells, long long pointBase, long long numPoints, MeshBuilder& mesh,
                    const std::string& source, const std::function<int(size_t)>& cellLine,
                    const std::function<int(size_t)>& typeLine, const char* container) {
  const size_t n = cells.types.size();
  if (cells.offsets.size() != n + 1 || cells.offsets.front() != 0)
    fail(source, n ? typeLine(0) : 0, "cell offsets do not match the number of cell types");
  if (pointBase + numPoints > INT_MAX) fail(source, 0, "too many points for 32-bit indices");
  for (size_t c = 0; c < n; ++c) {
    const long long begin = cells.offsets[c], end = cells.offsets[c + 1];
    if (begin > end || end > static_cast<long long>(cells.connectivity.size()))
      fail(source, cellLine(c),
           "cell " + std::to_string(c) + " has offsets " + std::to_string(begin) + ".." + std::to_string(end) +
               ", outside the " + std::to_string(cells.connectivity.size()) + " connectivity entries");
    const long long count = end - begin, type = cells.types[c];
    int want = -1;  // point count of a kept cell; 0 for skipped ones
    bool countOk = false;
    const char* name = "";
    switch (type) {
      case 10: want = 4; countOk = count == 4; name = "a tetrahedron"; break;
      case 5: want = 3; countOk = count == 3; name = "a triangle"; break;
      case 1: want = 0; countOk = count == 1; name = "a vertex"; break;
      case 2: want = 0; countOk = count >= 1; name = "a poly-vertex"; break;
      case 3: want = 0; countOk = count == 2; name = "a line"; break;
      case 4: want = 0; countOk = count >= 2; name = "a poly-line"; break;
      default: {
        const char* known = vtkTypeName(type);
        fail(source, typeLine(c),
             "cell " + std::to_string(c) + " has VTK type " + std::to_string(type) + (known ? std::string(" (") + known + ")" : "") +
                 ", which is not supported: only tetrahedra (10) and triangles (5) are read; vertices and lines are skipped");
      }
    }
    if (!countOk)
      fail(source, cellLine(c),
           "cell " + std::to_string(c) + " is " + name + " (VTK type " + std::to_string(type) + ") but has " + std::to_string(count) +
               " points");
    for (long long k = begin; k < end; ++k) {
      const long long p = cells.connectivity[k];
      if (p < 0 || p >= numPoints)
        fail(source, cellLine(c),
             "cell " + std::to_string(c) + " refers to point " + std::to_string(p) + ", but the " + container + " has " +
                 std::to_string(numPoints) + " points");
    }
    if (want == 0) continue;
    auto& out = want == 4 ? mesh.tets : mesh.triangles;
    for (long long k = begin; k < end; ++k) out.push_back(static_cast<int>(pointBase + cells.connectivity[k]));
  }
}

}  // namespace detail

VolumeMesh readVolumeMesh(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".msh") return readGmsh(path);
  if (ext == ".vtk") return readVtkLegacy(path);
  if (ext == ".vtu") return readVtu(path);
  if (ext == ".exo") {  // an Exodus series: its first frame
    const ExodusReader series(path);
    VolumeMesh mesh = series.mesh();
    if (!series.times().empty()) mesh.points = series.positions(0);
    return mesh;
  }
  detail::fail(path, 0,
               "unknown mesh format " + (ext.empty() ? std::string("(no extension)") : detail::quoted(ext)) +
                   ": expected .msh (Gmsh), .vtk (legacy VTK), .vtu (VTK XML) or .exo (Exodus II, its first frame)");
}

}  // namespace viscera::io
