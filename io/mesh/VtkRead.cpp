// Legacy VTK reader: ASCII DATASET UNSTRUCTURED_GRID, with the classic CELLS layout and the
// OFFSETS/CONNECTIVITY layout of version 5.x files.
#include <algorithm>
#include <climits>
#include <string>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/mesh/MeshDetail.h"
#include "core/Text.h"

namespace viscera::io {
namespace {

using detail::equalsIgnoreCase;
using detail::quoted;

class VtkLegacyReader {
 public:
  VtkLegacyReader(std::string_view text, const std::string& path) : lines_(text, path), in_(lines_) {}

  VolumeMesh read() {
    readHeader();
    std::string_view keyword;
    while (in_.next(keyword)) {
      if (equalsIgnoreCase(keyword, "POINTS")) {
        readPoints();
      } else if (equalsIgnoreCase(keyword, "CELLS")) {
        readCells();
      } else if (equalsIgnoreCase(keyword, "CELL_TYPES")) {
        readCellTypes();
      } else if (equalsIgnoreCase(keyword, "POINT_DATA") || equalsIgnoreCase(keyword, "CELL_DATA")) {
        break;  // attribute data follows the geometry; nothing in it is needed
      } else if (equalsIgnoreCase(keyword, "FIELD")) {
        skipField();
      } else if (equalsIgnoreCase(keyword, "METADATA")) {
        in_.skipToBlankLine();
      } else {
        in_.fail("unexpected " + quoted(keyword) + "; expected POINTS, CELLS, CELL_TYPES, POINT_DATA or CELL_DATA");
      }
    }
    if (pointsLine_ == 0) in_.fail("no POINTS section");
    if (cellsLine_ && !typesLine_)
      detail::fail(lines_.source(), cellsLine_, "CELLS without CELL_TYPES (the file ends without giving the cell types)");
    if (cellsLine_) {
      detail::appendVtkCells(
          cells_, 0, mesh_.numPoints(), mesh_, lines_.source(), [&](size_t c) { return cellLines_[c]; },
          [&](size_t c) { return typeLines_[c]; });
    }
    return mesh_.finish();
  }

 private:
  void readHeader() {
    if (!lines_.next() || !detail::startsWithIgnoreCase(lines_.text(), "# vtk DataFile Version"))
      lines_.fail("not a legacy VTK file: the first line must be '# vtk DataFile Version x.x'");
    if (!lines_.next()) lines_.fail("file ends before the title line");
    if (!lines_.next()) lines_.fail("file ends before the ASCII/BINARY line");
    if (equalsIgnoreCase(lines_.text(), "BINARY")) lines_.fail("binary legacy .vtk is not supported; save as ASCII (or as .vtu)");
    if (!equalsIgnoreCase(lines_.text(), "ASCII")) lines_.fail("expected ASCII or BINARY on line 3, found " + quoted(lines_.text()));
    if (!equalsIgnoreCase(in_.expect("DATASET"), "DATASET")) in_.fail("expected DATASET after the header");
    const std::string_view type = in_.expect("the dataset type");
    if (!equalsIgnoreCase(type, "UNSTRUCTURED_GRID"))
      in_.fail("DATASET " + std::string(type) + " is not supported; expected UNSTRUCTURED_GRID");
  }

  long long count(const std::string& what) {
    const long long n = in_.expectInt(what);
    if (n < 0 || n > INT_MAX) in_.fail(what + " must be between 0 and " + std::to_string(INT_MAX) + ", found " + std::to_string(n));
    return n;
  }

  // The data type after a count ("float", "vtktypeint64", ...); a number there means it is missing.
  void dataType(const std::string& section) {
    const std::string_view type = in_.expect("the data type of " + section);
    double ignored;
    if (detail::parseReal(type, ignored)) in_.fail(section + " needs a data type (such as float or double) after its counts");
  }

  // Next token of a section that declared `declared` values, with a message naming the section.
  std::string_view value(const std::string& section, long long declared, long long done, const char* noun) {
    std::string_view token;
    if (!in_.next(token))
      in_.fail("file ends inside " + section + " after " + std::to_string(done) + " of the " + std::to_string(declared) + " " + noun +
               " it declares");
    return token;
  }

  long long intValue(const std::string& section, long long declared, long long done, const char* noun) {
    const std::string_view token = value(section, declared, done, noun);
    long long v;
    if (!parseInteger(token, v)) in_.fail("expected an integer in " + section + ", found " + quoted(token));
    return v;
  }

  void readPoints() {
    if (pointsLine_) in_.fail("second POINTS section (the first is on line " + std::to_string(pointsLine_) + ")");
    pointsLine_ = in_.line();
    const long long n = count("the number of points");
    dataType("POINTS");
    mesh_.xyz.reserve(static_cast<size_t>(std::min<long long>(3 * n, 3 << 20)));
    for (long long i = 0; i < 3 * n; ++i) {
      const std::string_view token = value("POINTS", 3 * n, i, "coordinates");
      double v;
      if (!detail::parseReal(token, v)) in_.fail("expected a finite number for a point coordinate, found " + quoted(token));
      mesh_.xyz.push_back(v);
    }
  }

  void readCells() {
    if (cellsLine_) in_.fail("second CELLS section (the first is on line " + std::to_string(cellsLine_) + ")");
    cellsLine_ = in_.line();
    const long long first = count("the number of cells"), second = count("the size of the cell list");
    std::string_view next;
    if (in_.peek(next) && equalsIgnoreCase(next, "OFFSETS")) {
      readCellsV5(first, second);
      return;
    }
    // Classic layout: per cell its point count then the indices; `second` counts all integers.
    cells_.offsets.assign(1, 0);
    long long used = 0;
    for (long long c = 0; c < first; ++c) {
      const long long k = intValue("CELLS", first, c, "cells");
      cellLines_.push_back(in_.line());
      if (k < 0) in_.fail("cell " + std::to_string(c) + " has a negative point count");
      used += 1 + k;
      if (used > second)
        in_.fail("CELLS (line " + std::to_string(cellsLine_) + ") declares a list size of " + std::to_string(second) +
                 " but the cells hold more values");
      for (long long j = 0; j < k; ++j) cells_.connectivity.push_back(intValue("CELLS", first, c, "cells"));
      cells_.offsets.push_back(static_cast<long long>(cells_.connectivity.size()));
    }
    if (used != second)
      detail::fail(lines_.source(), cellsLine_,
                   "CELLS declares a list size of " + std::to_string(second) + " but its " + std::to_string(first) + " cells hold " +
                       std::to_string(used) + " values");
    numCells_ = first;
  }

  // Version 5 layout: "CELLS <#offsets> <#connectivity>", then OFFSETS and CONNECTIVITY arrays.
  void readCellsV5(long long numOffsets, long long numConnectivity) {
    in_.expect("OFFSETS");
    dataType("OFFSETS");
    for (long long i = 0; i < numOffsets; ++i) {
      cells_.offsets.push_back(intValue("OFFSETS", numOffsets, i, "offsets"));
      cellLines_.push_back(in_.line());
    }
    if (!equalsIgnoreCase(in_.expect("CONNECTIVITY"), "CONNECTIVITY")) in_.fail("expected CONNECTIVITY after the cell offsets");
    dataType("CONNECTIVITY");
    for (long long i = 0; i < numConnectivity; ++i) cells_.connectivity.push_back(intValue("CONNECTIVITY", numConnectivity, i, "indices"));
    if (numOffsets == 0) cells_.offsets.assign(1, 0), cellLines_.assign(1, cellsLine_);
    if (cells_.offsets.front() != 0 || cells_.offsets.back() != numConnectivity)
      detail::fail(lines_.source(), cellLines_.front(),
                   "OFFSETS must run from 0 to the connectivity size " + std::to_string(numConnectivity) + ", found " +
                       std::to_string(cells_.offsets.front()) + ".." + std::to_string(cells_.offsets.back()));
    numCells_ = static_cast<long long>(cells_.offsets.size()) - 1;
  }

  void readCellTypes() {
    if (typesLine_) in_.fail("second CELL_TYPES section (the first is on line " + std::to_string(typesLine_) + ")");
    typesLine_ = in_.line();
    if (!cellsLine_) in_.fail("CELL_TYPES before CELLS");
    const long long n = count("the number of cell types");
    if (n != numCells_)
      in_.fail("CELL_TYPES declares " + std::to_string(n) + " cells but CELLS (line " + std::to_string(cellsLine_) + ") has " +
               std::to_string(numCells_));
    for (long long i = 0; i < n; ++i) {
      cells_.types.push_back(intValue("CELL_TYPES", n, i, "cell types"));
      typeLines_.push_back(in_.line());
    }
  }

  // FIELD name #arrays, then per array: name #components #tuples type values...
  void skipField() {
    in_.expect("the field name");
    const long long arrays = count("the number of field arrays");
    for (long long a = 0; a < arrays; ++a) {
      std::string_view name;
      while (in_.peek(name) && equalsIgnoreCase(name, "METADATA")) in_.skipToBlankLine();
      in_.expect("a field array name");
      const long long components = count("the number of components"), tuples = count("the number of tuples");
      dataType("the field array");
      for (long long i = 0; i < components * tuples; ++i) value("FIELD", components * tuples, i, "values");
    }
  }

  detail::LineCursor lines_;
  detail::TokenCursor in_;
  detail::MeshBuilder mesh_;
  detail::VtkCells cells_;
  std::vector<int> cellLines_, typeLines_;
  long long numCells_ = 0;
  int pointsLine_ = 0, cellsLine_ = 0, typesLine_ = 0;
};

}  // namespace

VolumeMesh readVtkLegacy(const std::string& path) {
  const std::string text = detail::readWholeFile(path);
  // SOFA's loader also takes a VTK XML unstructured grid saved with the .vtk extension.
  const size_t start = text.find_first_not_of(" \t\r\n");
  if (start != std::string::npos && text[start] == '<') return readVtu(path);
  return VtkLegacyReader(text, path).read();
}

}  // namespace viscera::io
