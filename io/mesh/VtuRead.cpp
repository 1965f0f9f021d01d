// VTK XML UnstructuredGrid (.vtu) reader: inline "ascii" and base64 "binary" DataArrays, the
// latter plain or zlib-compressed (compressor="vtkZLibDataCompressor"). Scenes and .pvd series
// are read with pugixml; .vtu files keep this small parser of the XML subset VTK writes because
// (1) VTK files may end in raw <AppendedData> bytes, which an XML library rejects before the
// reader can say what is unsupported, and (2) its messages name the unclosed or mismatched
// element and the line it was opened on (tests/io/mesh_malformed_test.cpp), where pugixml reports
// an offset and "Start-end tags mismatch".
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <climits>
#include <cmath>
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/mesh/MeshDetail.h"
#include "core/Text.h"

namespace viscera::io {
namespace {

using detail::quoted;

struct XmlElement {
  std::string name;
  std::vector<std::pair<std::string, std::string>> attributes;
  std::vector<XmlElement> children;
  std::string text;  // character data directly inside the element
  int line = 0;      // line of the start tag
  int textLine = 0;  // line where `text` begins

  const std::string* attribute(std::string_view key) const {
    for (const auto& [k, v] : attributes)
      if (k == key) return &v;
    return nullptr;
  }
  const XmlElement* child(std::string_view key) const {
    for (const auto& c : children)
      if (c.name == key) return &c;
    return nullptr;
  }
};

// Elements, attributes, text, comments, CDATA, processing instructions and the predefined
// entities. Parsing stops at <AppendedData>, whose raw bytes are not XML.
class XmlParser {
 public:
  XmlParser(std::string_view text, const std::string& source) : s_(text), source_(source) {}

  XmlElement parseDocument() {
    if (startsWith("\xEF\xBB\xBF")) pos_ = 3;  // UTF-8 byte order mark
    skipMisc();
    if (pos_ >= s_.size()) fail("no XML root element");
    if (s_[pos_] != '<') fail("expected '<' at the start of the XML document, found " + quoted(s_.substr(pos_, 20)));
    XmlElement root;
    parseElement(root, 0);
    if (!stopped_) {
      skipMisc();
      if (pos_ < s_.size()) fail("unexpected content after the root element </" + root.name + ">");
    }
    return root;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const { detail::fail(source_, line_, what); }

  bool startsWith(std::string_view p) const { return s_.substr(pos_, p.size()) == p; }

  void advance(size_t n) {
    n = std::min(n, s_.size() - pos_);
    line_ += static_cast<int>(std::count(s_.begin() + pos_, s_.begin() + pos_ + n, '\n'));
    pos_ += n;
  }

  void skipPast(std::string_view end, const char* what) {
    const size_t at = s_.find(end, pos_);
    if (at == std::string_view::npos) fail(std::string("file ends inside ") + what);
    advance(at + end.size() - pos_);
  }

  static bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

  void skipSpace() {
    size_t end = pos_;
    while (end < s_.size() && isSpace(s_[end])) ++end;
    advance(end - pos_);
  }

  // Whitespace, comments, processing instructions and DOCTYPE outside the root element.
  void skipMisc() {
    for (;;) {
      skipSpace();
      if (startsWith("<?")) skipPast("?>", "a processing instruction");
      else if (startsWith("<!--")) skipPast("-->", "a comment");
      else if (startsWith("<!")) skipPast(">", "a declaration");
      else return;
    }
  }

  std::string_view parseName() {
    size_t end = pos_;
    while (end < s_.size() && !isSpace(s_[end]) && std::string_view("/>=<\"'").find(s_[end]) == std::string_view::npos) ++end;
    std::string_view name = s_.substr(pos_, end - pos_);
    advance(end - pos_);
    return name;
  }

  std::string decode(std::string_view raw) const {
    if (raw.find('&') == std::string_view::npos) return std::string(raw);
    std::string out;
    for (size_t i = 0; i < raw.size(); ++i) {
      if (raw[i] != '&') {
        out += raw[i];
        continue;
      }
      const size_t semi = raw.find(';', i);
      if (semi == std::string_view::npos) fail("unterminated entity " + quoted(raw.substr(i, 10)));
      const std::string_view ent = raw.substr(i + 1, semi - i - 1);
      if (ent == "lt") out += '<';
      else if (ent == "gt") out += '>';
      else if (ent == "amp") out += '&';
      else if (ent == "quot") out += '"';
      else if (ent == "apos") out += '\'';
      else if (ent.size() > 1 && ent[0] == '#') {
        long long code = 0;
        const bool hex = ent[1] == 'x' || ent[1] == 'X';
        bool ok = !ent.substr(hex ? 2 : 1).empty();
        for (char c : ent.substr(hex ? 2 : 1)) {
          const int d = std::isdigit(static_cast<unsigned char>(c)) ? c - '0'
                        : hex && std::isxdigit(static_cast<unsigned char>(c)) ? std::tolower(c) - 'a' + 10
                                                                              : -1;
          if (d < 0 || code > 0x10FFFF) ok = false;
          else code = code * (hex ? 16 : 10) + d;
        }
        if (!ok || code > 127) fail("unsupported character reference " + quoted(raw.substr(i, semi - i + 1)));
        out += static_cast<char>(code);  // only ASCII shows up in VTK names and numbers
      } else {
        fail("unknown entity " + quoted(raw.substr(i, semi - i + 1)));
      }
      i = semi;
    }
    return out;
  }

  void parseElement(XmlElement& e, int depth) {
    if (depth > 64) fail("XML elements nested too deeply");
    e.line = line_;
    advance(1);  // '<'
    e.name = std::string(parseName());
    if (e.name.empty()) fail("expected an element name after '<'");
    for (;;) {
      skipSpace();
      if (pos_ >= s_.size()) fail("file ends inside the <" + e.name + "> tag");
      if (startsWith("/>")) {
        advance(2);
        return;
      }
      if (s_[pos_] == '>') {
        advance(1);
        break;
      }
      const std::string key(parseName());
      if (key.empty()) fail("unexpected " + quoted(s_.substr(pos_, 1)) + " in the <" + e.name + "> tag");
      skipSpace();
      if (!startsWith("=")) fail("attribute " + key + " of <" + e.name + "> needs '=' and a quoted value");
      advance(1);
      skipSpace();
      if (pos_ >= s_.size() || (s_[pos_] != '"' && s_[pos_] != '\''))
        fail("attribute " + key + " of <" + e.name + "> needs a quoted value");
      const char quote = s_[pos_];
      const size_t end = s_.find(quote, pos_ + 1);
      if (end == std::string_view::npos) fail("file ends inside the value of attribute " + key);
      e.attributes.emplace_back(key, decode(s_.substr(pos_ + 1, end - pos_ - 1)));
      advance(end + 1 - pos_);
    }
    if (e.name == "AppendedData") {
      stopped_ = true;  // raw binary follows; the readers reject arrays that would need it
      return;
    }
    for (;;) {
      if (pos_ >= s_.size())
        fail("file ends inside <" + e.name + "> (opened on line " + std::to_string(e.line) + ")");
      if (startsWith("</")) {
        advance(2);
        const std::string_view name = parseName();
        skipSpace();
        if (!startsWith(">")) fail("expected '>' to close </" + std::string(name) + ">");
        if (name != e.name)
          fail("</" + std::string(name) + "> does not match <" + e.name + "> opened on line " + std::to_string(e.line));
        advance(1);
        return;
      }
      if (startsWith("<!--")) {
        skipPast("-->", "a comment");
      } else if (startsWith("<![CDATA[")) {
        advance(9);
        const size_t end = s_.find("]]>", pos_);
        if (end == std::string_view::npos) fail("file ends inside a CDATA section");
        if (e.textLine == 0) e.textLine = line_;
        e.text.append(s_.substr(pos_, end - pos_));
        advance(end + 3 - pos_);
      } else if (startsWith("<?")) {
        skipPast("?>", "a processing instruction");
      } else if (s_[pos_] == '<') {
        e.children.emplace_back();
        parseElement(e.children.back(), depth + 1);
        if (stopped_) return;
      } else {
        size_t end = s_.find('<', pos_);
        if (end == std::string_view::npos) end = s_.size();
        if (e.textLine == 0) e.textLine = line_;
        e.text += decode(s_.substr(pos_, end - pos_));
        advance(end - pos_);
      }
    }
  }

  std::string_view s_;
  const std::string& source_;
  size_t pos_ = 0;
  int line_ = 1;
  bool stopped_ = false;
};

enum class Scalar { Int, UInt, Float };

struct ScalarType {
  Scalar kind;
  int bytes;
};

bool scalarType(std::string_view name, ScalarType& out) {
  static const std::pair<std::string_view, ScalarType> kTypes[] = {
      {"Int8", {Scalar::Int, 1}},     {"UInt8", {Scalar::UInt, 1}},   {"Int16", {Scalar::Int, 2}},    {"UInt16", {Scalar::UInt, 2}},
      {"Int32", {Scalar::Int, 4}},    {"UInt32", {Scalar::UInt, 4}},  {"Int64", {Scalar::Int, 8}},    {"UInt64", {Scalar::UInt, 8}},
      {"Float32", {Scalar::Float, 4}}, {"Float64", {Scalar::Float, 8}}};
  for (const auto& [n, t] : kTypes)
    if (n == name) {
      out = t;
      return true;
    }
  return false;
}

int base64Value(char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

class VtuReader {
 public:
  VtuReader(std::string_view text, const std::string& path) : text_(text), path_(path) {}

  VolumeMesh read() {
    const XmlElement root = XmlParser(text_, path_).parseDocument();
    if (root.name != "VTKFile") fail(root.line, "not a VTK XML file: the root element is <" + root.name + ">, not <VTKFile>");
    const std::string* type = root.attribute("type");
    if (!type || *type != "UnstructuredGrid")
      fail(root.line, "VTKFile type " + (type ? quoted(*type) : std::string("(missing)")) + " is not supported; expected UnstructuredGrid");
    if (const std::string* c = root.attribute("compressor"); c && !detail::trim(*c).empty()) {
      if (detail::trim(*c) != "vtkZLibDataCompressor")
        fail(root.line, "compressed .vtu (compressor=\"" + *c + "\") is not supported; save without compression or with zlib");
      zlib_ = true;
    }
    if (const std::string* h = root.attribute("header_type")) {
      if (*h == "UInt64") header64_ = true;
      else if (*h != "UInt32") fail(root.line, "header_type " + quoted(*h) + " is not supported (UInt32 or UInt64)");
    }
    if (const std::string* b = root.attribute("byte_order")) {
      if (*b == "BigEndian") bigEndian_ = true;
      else if (*b != "LittleEndian") fail(root.line, "unknown byte_order " + quoted(*b));
    }
    const XmlElement* grid = root.child("UnstructuredGrid");
    if (!grid) fail(root.line, "<VTKFile> has no <UnstructuredGrid> element");
    detail::MeshBuilder mesh;
    int pieces = 0;
    for (const XmlElement& piece : grid->children)
      if (piece.name == "Piece") readPiece(piece, mesh), ++pieces;
    if (pieces == 0) fail(grid->line, "<UnstructuredGrid> has no <Piece>");
    return mesh.finish();
  }

 private:
  [[noreturn]] void fail(int line, const std::string& what) const { detail::fail(path_, line, what); }

  long long countAttribute(const XmlElement& e, const char* key) const {
    const std::string* v = e.attribute(key);
    if (!v) fail(e.line, "<" + e.name + "> needs a " + key + " attribute");
    long long n;
    if (!parseInteger(detail::trim(*v), n) || n < 0 || n > INT_MAX)
      fail(e.line, std::string(key) + " must be a count between 0 and " + std::to_string(INT_MAX) + ", found " + quoted(*v));
    return n;
  }

  const XmlElement* namedArray(const XmlElement& parent, std::string_view name) const {
    for (const auto& c : parent.children)
      if (c.name == "DataArray")
        if (const std::string* n = c.attribute("Name"); n && *n == name) return &c;
    return nullptr;
  }

  // The values of a DataArray as T (double or long long). `expected` < 0: any count.
  template <class T>
  std::vector<T> readArray(const XmlElement& a, long long expected, const std::string& what) const {
    const std::string* typeName = a.attribute("type");
    ScalarType type;
    if (!typeName) fail(a.line, "the " + what + " DataArray has no type attribute");
    if (!scalarType(*typeName, type)) fail(a.line, "the " + what + " DataArray has unknown type " + quoted(*typeName));
    constexpr bool wantInt = std::is_integral_v<T>;
    if (wantInt && type.kind == Scalar::Float) fail(a.line, "the " + what + " DataArray must have an integer type, found " + *typeName);
    const std::string* format = a.attribute("format");
    std::vector<T> out;
    if (!format || *format == "ascii") {
      readAscii(a, out, what);
    } else if (*format == "binary") {
      readBinary(a, type, out, what);
    } else if (*format == "appended") {
      fail(a.line, "the " + what + " DataArray uses appended data, which is not supported; save with inline ascii or binary data");
    } else {
      fail(a.line, "the " + what + " DataArray has unknown format " + quoted(*format));
    }
    if (expected >= 0 && static_cast<long long>(out.size()) != expected)
      fail(a.line, "the " + what + " DataArray holds " + std::to_string(out.size()) + " values but " + std::to_string(expected) +
                       " are expected");
    return out;
  }

  template <class T>
  void readAscii(const XmlElement& a, std::vector<T>& out, const std::string& what) const {
    const std::string& s = a.text;
    int line = a.textLine ? a.textLine : a.line;
    size_t i = 0;
    while (i < s.size()) {
      while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\n')) line += s[i++] == '\n';
      const size_t start = i;
      while (i < s.size() && !(s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\n')) ++i;
      if (i == start) break;
      const std::string_view token(s.data() + start, i - start);
      if constexpr (std::is_integral_v<T>) {
        long long v;
        if (!parseInteger(token, v)) fail(line, "expected an integer in the " + what + " DataArray, found " + quoted(token));
        out.push_back(v);
      } else {
        double v;
        if (!detail::parseReal(token, v)) fail(line, "expected a finite number in the " + what + " DataArray, found " + quoted(token));
        out.push_back(v);
      }
    }
  }

  // Base64 of "<byte count header><raw values>"; the header may also be encoded on its own
  // (padded), so padding in the middle of the text starts a new group.
  std::vector<unsigned char> decodeBase64(const XmlElement& a, const std::string& what) const {
    std::vector<unsigned char> bytes;
    bytes.reserve(a.text.size() / 4 * 3);
    int group[4], n = 0;
    for (char c : a.text) {
      if (c == ' ' || c == '\t' || c == '\r' || c == '\n') continue;
      const int v = c == '=' ? -2 : base64Value(c);
      if (v == -1) fail(a.line, "invalid character " + quoted(std::string_view(&c, 1)) + " in the base64 data of the " + what + " DataArray");
      group[n++] = v;
      if (n < 4) continue;
      n = 0;
      if (group[0] < 0 || group[1] < 0 || (group[2] < 0 && group[3] >= 0))
        fail(a.line, "misplaced '=' padding in the base64 data of the " + what + " DataArray");
      bytes.push_back(static_cast<unsigned char>(group[0] << 2 | group[1] >> 4));
      if (group[2] >= 0) bytes.push_back(static_cast<unsigned char>((group[1] & 15) << 4 | group[2] >> 2));
      if (group[3] >= 0) bytes.push_back(static_cast<unsigned char>((group[2] & 3) << 6 | group[3]));
    }
    if (n != 0) fail(a.line, "truncated base64 data in the " + what + " DataArray");
    return bytes;
  }

  uint64_t loadUnsigned(const unsigned char* p, int size) const {
    uint64_t v = 0;
    for (int k = 0; k < size; ++k) v |= static_cast<uint64_t>(p[bigEndian_ ? size - 1 - k : k]) << (8 * k);
    return v;
  }

  // The raw value bytes of a binary DataArray, whose base64 text holds a byte-count header and
  // the values, or, compressed, VTK's block header and zlib blocks (see inflateBlocks).
  std::vector<unsigned char> binaryPayload(const XmlElement& a, const std::string& what) const {
    std::vector<unsigned char> bytes = decodeBase64(a, what);
    const size_t header = header64_ ? 8 : 4;
    if (zlib_) return inflateBlocks(a, bytes, header, what);
    if (bytes.size() < header) fail(a.line, "the binary " + what + " DataArray is too short to hold its size header");
    const uint64_t size = loadUnsigned(bytes.data(), static_cast<int>(header));
    if (size != bytes.size() - header)
      fail(a.line, "the binary " + what + " DataArray declares " + std::to_string(size) + " bytes but holds " +
                       std::to_string(bytes.size() - header));
    bytes.erase(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(header));
    return bytes;
  }

  // VTK's compressed layout: header words [#blocks, block size, size of the last block if partial
  // (0: full), compressed size of each block], then the zlib streams of the blocks back to back.
  // VTK base64-encodes the header and the blocks as two runs; their decoded bytes just follow on.
  std::vector<unsigned char> inflateBlocks(const XmlElement& a, const std::vector<unsigned char>& bytes, size_t word,
                                           const std::string& what) const {
    const std::string array = "the compressed " + what + " DataArray";
    if (bytes.size() < 3 * word) fail(a.line, array + " is too short to hold its compression header");
    const uint64_t numBlocks = loadUnsigned(bytes.data(), static_cast<int>(word));
    const uint64_t blockSize = loadUnsigned(bytes.data() + word, static_cast<int>(word));
    const uint64_t lastSize = loadUnsigned(bytes.data() + 2 * word, static_cast<int>(word));
    if (numBlocks > (bytes.size() - 3 * word) / word)
      fail(a.line, array + " declares " + std::to_string(numBlocks) + " blocks, more than its header can hold");
    if (numBlocks > 0 && (blockSize == 0 || lastSize > blockSize))
      fail(a.line, array + " has an invalid block size " + std::to_string(blockSize) + " (last block " + std::to_string(lastSize) + ")");
    const size_t dataStart = (3 + numBlocks) * word;
    uint64_t packedTotal = 0;
    for (uint64_t b = 0; b < numBlocks; ++b) {
      const uint64_t packed = loadUnsigned(bytes.data() + (3 + b) * word, static_cast<int>(word));
      if (packed > bytes.size())
        fail(a.line, array + " declares block " + std::to_string(b) + " of " + std::to_string(packed) + " bytes, more than the file holds");
      packedTotal += packed;
    }
    if (packedTotal != bytes.size() - dataStart)
      fail(a.line, array + " declares " + std::to_string(packedTotal) + " compressed bytes but holds " +
                       std::to_string(bytes.size() - dataStart));
    std::vector<unsigned char> out;
    size_t at = dataStart;
    for (uint64_t b = 0; b < numBlocks; ++b) {
      const uint64_t packed = loadUnsigned(bytes.data() + (3 + b) * word, static_cast<int>(word));
      const uint64_t size = b + 1 == numBlocks && lastSize != 0 ? lastSize : blockSize;
      // zlib inflates at most about 1032:1; a larger claim is a corrupt header, not a reason to allocate.
      if (size > 1032 * packed + 64)
        fail(a.line, array + " declares block " + std::to_string(b) + " of " + std::to_string(size) + " bytes from only " +
                         std::to_string(packed) + " compressed bytes");
      const size_t o = out.size();
      out.resize(o + size);
      uLongf got = static_cast<uLongf>(size);
      const int rc = uncompress(out.data() + o, &got, bytes.data() + at, static_cast<uLong>(packed));
      if (rc != Z_OK || got != size)
        fail(a.line, array + ": block " + std::to_string(b) + " does not inflate to its declared " + std::to_string(size) + " bytes (" +
                         (rc == Z_OK ? std::to_string(got) + " bytes" : std::string("zlib: ") + zError(rc)) + ")");
      at += packed;
    }
    return out;
  }

  template <class T>
  void readBinary(const XmlElement& a, ScalarType type, std::vector<T>& out, const std::string& what) const {
    const std::vector<unsigned char> bytes = binaryPayload(a, what);
    const size_t size = bytes.size();
    if (size % type.bytes != 0)
      fail(a.line, "the binary " + what + " DataArray holds " + std::to_string(size) + " bytes, not a multiple of its " +
                       std::to_string(type.bytes) + "-byte values");
    const size_t count = size / type.bytes;
    out.reserve(count);
    for (size_t i = 0; i < count; ++i) {
      const uint64_t raw = loadUnsigned(bytes.data() + i * type.bytes, type.bytes);
      if (type.kind == Scalar::Float) {
        const double v = type.bytes == 4 ? static_cast<double>(std::bit_cast<float>(static_cast<uint32_t>(raw))) : std::bit_cast<double>(raw);
        if (!std::isfinite(v)) fail(a.line, "the " + what + " DataArray holds a value that is not finite (entry " + std::to_string(i) + ")");
        out.push_back(static_cast<T>(v));
      } else if (type.kind == Scalar::UInt) {
        if (raw > static_cast<uint64_t>(LLONG_MAX)) fail(a.line, "the " + what + " DataArray holds a value too large for an index");
        out.push_back(static_cast<T>(raw));
      } else {
        const int shift = 64 - 8 * type.bytes;  // sign-extend narrower integers
        const long long v = type.bytes == 8 ? static_cast<long long>(raw) : static_cast<long long>(raw << shift) >> shift;
        out.push_back(static_cast<T>(v));
      }
    }
  }

  void readPiece(const XmlElement& piece, detail::MeshBuilder& mesh) const {
    const long long numPoints = countAttribute(piece, "NumberOfPoints"), numCells = countAttribute(piece, "NumberOfCells");
    const long long base = mesh.numPoints();
    if (const XmlElement* points = piece.child("Points")) {
      const XmlElement* array = points->child("DataArray");
      if (!array) fail(points->line, "<Points> has no <DataArray>");
      const std::string* comps = array->attribute("NumberOfComponents");
      if (!comps || detail::trim(*comps) != "3")
        fail(array->line, "the points DataArray must have NumberOfComponents=\"3\"");
      const std::vector<double> xyz = readArray<double>(*array, 3 * numPoints, "points");
      mesh.xyz.insert(mesh.xyz.end(), xyz.begin(), xyz.end());
    } else if (numPoints > 0) {
      fail(piece.line, "the piece has " + std::to_string(numPoints) + " points but no <Points>");
    }
    const XmlElement* cellsElement = piece.child("Cells");
    if (!cellsElement) {
      if (numCells > 0) fail(piece.line, "the piece has " + std::to_string(numCells) + " cells but no <Cells>");
      return;
    }
    const XmlElement* conn = namedArray(*cellsElement, "connectivity");
    const XmlElement* offs = namedArray(*cellsElement, "offsets");
    const XmlElement* types = namedArray(*cellsElement, "types");
    if (!conn || !offs || !types)
      fail(cellsElement->line, std::string("<Cells> needs DataArrays named connectivity, offsets and types; missing ") +
                                   (!conn ? "connectivity" : !offs ? "offsets" : "types"));
    detail::VtkCells cells;
    cells.types = readArray<long long>(*types, numCells, "types");
    const std::vector<long long> ends = readArray<long long>(*offs, numCells, "offsets");
    cells.connectivity = readArray<long long>(*conn, -1, "connectivity");
    cells.offsets.reserve(ends.size() + 1);
    cells.offsets.push_back(0);
    cells.offsets.insert(cells.offsets.end(), ends.begin(), ends.end());
    if (cells.offsets.back() != static_cast<long long>(cells.connectivity.size()))
      fail(offs->line, "the offsets end at " + std::to_string(cells.offsets.back()) + " but the connectivity holds " +
                           std::to_string(cells.connectivity.size()) + " indices");
    const int connLine = conn->line, typesLine = types->line;
    detail::appendVtkCells(
        cells, base, numPoints, mesh, path_, [&](size_t) { return connLine; }, [&](size_t) { return typesLine; }, "piece");
  }

  std::string_view text_;
  const std::string& path_;
  bool header64_ = false;
  bool bigEndian_ = false;
  bool zlib_ = false;  // binary arrays are zlib-compressed blocks
};

}  // namespace

VolumeMesh readVtu(const std::string& path) {
  const std::string text = detail::readWholeFile(path);
  return VtuReader(text, path).read();
}

}  // namespace viscera::io
