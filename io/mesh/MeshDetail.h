// Helpers shared by the mesh readers: file loading, line/token cursors with line numbers,
// strict number parsing and VTK cell assembly. Internal to io/mesh; not part of the interface.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "core/Error.h"
#include "io/mesh/Mesh.h"

namespace viscera::io::detail {

// Throws viscera::Error "source:line: what" (the line is left out when it is 0).
[[noreturn]] void fail(const std::string& source, int line, const std::string& what);

// The whole file as bytes; throws an Error naming the path when it cannot be read.
std::string readWholeFile(const std::string& path);

// A token quoted for a message, shortened when it is long or binary (core/Error.h).
using viscera::quoted;

std::string_view trim(std::string_view s);
bool equalsIgnoreCase(std::string_view a, std::string_view b);
bool startsWithIgnoreCase(std::string_view s, std::string_view prefix);
void splitTokens(std::string_view line, std::vector<std::string_view>& out);

// Whole-token parses: "12abc", "" or out-of-range values are rejected (false).
bool parseReal(std::string_view token, double& out);  // finite values only

// Walks a text line by line, keeping the 1-based number of the current line.
class LineCursor {
 public:
  LineCursor(std::string_view text, std::string source) : text_(text), source_(std::move(source)) {}

  bool next();          // moves to the next line; false (and the line stays) at end of file
  bool nextNonBlank();  // skips blank lines
  int line() const { return line_; }
  std::string_view text() const { return current_; }  // trimmed current line
  const std::vector<std::string_view>& tokens();      // whitespace-separated tokens of it
  const std::string& source() const { return source_; }

  [[noreturn]] void fail(const std::string& what) const { detail::fail(source_, line_, what); }
  // tokens()[i] as a number; `what` names the value in the error message.
  long long intAt(size_t i, const std::string& what);
  double realAt(size_t i, const std::string& what);

 private:
  std::string_view text_;
  std::string source_;
  size_t pos_ = 0;
  int line_ = 0;
  std::string_view current_;
  std::vector<std::string_view> tokens_;
  bool split_ = false;
};

// Walks a text token by token across lines (free-format data such as legacy VTK).
class TokenCursor {
 public:
  explicit TokenCursor(LineCursor& lines) : lines_(lines) {}

  bool next(std::string_view& token);  // false at end of file
  bool peek(std::string_view& token);  // like next() but does not consume
  int line() const { return lines_.line(); }  // line of the last token read
  void skipRestOfLine() { index_ = lines_.tokens().size(); started_ = true; }
  // Skips the rest of this line and all lines up to and including the next blank one.
  void skipToBlankLine();
  LineCursor& lines() { return lines_; }

  // Fails with "file ends where <what> was expected" at end of file.
  std::string_view expect(const std::string& what);
  long long expectInt(const std::string& what);
  double expectReal(const std::string& what);
  [[noreturn]] void fail(const std::string& what) const { lines_.fail(what); }

 private:
  bool fill();
  LineCursor& lines_;
  size_t index_ = 0;
  bool started_ = false;
};

// Collects points and elements before they are copied into a VolumeMesh.
struct MeshBuilder {
  std::vector<double> xyz;
  std::vector<int> tets;
  std::vector<int> triangles;
  std::vector<int> hexahedra;
  std::vector<int> quads;

  long long numPoints() const { return static_cast<long long>(xyz.size() / 3); }
  VolumeMesh finish() const;
};

// VTK cells in offsets form: cell c uses connectivity[offsets[c] .. offsets[c + 1]).
struct VtkCells {
  std::vector<long long> connectivity;
  std::vector<long long> offsets;  // #cells + 1 entries, the first is 0
  std::vector<long long> types;
};

// Appends tetrahedra (VTK type 10) and triangles (5) to `mesh`, skipping vertices and lines
// (1-4); other types, wrong point counts and indices outside [0, numPoints) are errors.
// Point indices are shifted by `pointBase`. `cellLine`/`typeLine` give the line to report;
// `container` names what holds the points in messages ("file", "piece").
void appendVtkCells(const VtkCells& cells, long long pointBase, long long numPoints, MeshBuilder& mesh,
                    const std::string& source, const std::function<int(size_t)>& cellLine,
                    const std::function<int(size_t)>& typeLine, const char* container = "file");

}  // namespace viscera::io::detail
