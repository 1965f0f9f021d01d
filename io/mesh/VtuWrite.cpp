// .vtu and .pvd output for ParaView, and the atomic file write every writer goes through.
#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "core/Files.h"
#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "core/Text.h"

namespace viscera::io {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) { throw Error(SourceLoc{path, 0, 0}, what); }

std::string escapeAttribute(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\n': out += "&#10;"; break;
      default: out += c;
    }
  }
  return out;
}

// Little-endian bytes of one DataArray's values. Bytes are assembled explicitly so the output
// does not depend on the host's byte order.
class Block {
 public:
  explicit Block(uint64_t payloadBytes) { bytes_.reserve(payloadBytes); }
  void putUnsigned(uint64_t v, int size) {
    char le[8];
    for (int k = 0; k < size; ++k) le[k] = static_cast<char>((v >> (8 * k)) & 0xFF);
    bytes_.append(le, static_cast<size_t>(size));
  }
  void putInt(int64_t v, int size) { putUnsigned(static_cast<uint64_t>(v), size); }
  void putFloat64(double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    putUnsigned(bits, 8);
  }
  void putFloat32(float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    putUnsigned(bits, 4);
  }
  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
};

void appendBase64(std::string& out, const char* data, size_t n) {
  static const char kDigits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* p = reinterpret_cast<const unsigned char*>(data);
  size_t o = out.size();
  out.resize(o + (n + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < n; i += 3, o += 4) {
    const uint32_t v = uint32_t(p[i]) << 16 | uint32_t(p[i + 1]) << 8 | p[i + 2];
    out[o] = kDigits[v >> 18];
    out[o + 1] = kDigits[(v >> 12) & 63];
    out[o + 2] = kDigits[(v >> 6) & 63];
    out[o + 3] = kDigits[v & 63];
  }
  if (i < n) {
    const uint32_t v = uint32_t(p[i]) << 16 | (i + 1 < n ? uint32_t(p[i + 1]) << 8 : 0);
    out[o] = kDigits[v >> 18];
    out[o + 1] = kDigits[(v >> 12) & 63];
    out[o + 2] = i + 1 < n ? kDigits[(v >> 6) & 63] : '=';
    out[o + 3] = '=';
  }
}

void appendLittleEndian(std::string& out, uint64_t v) {
  for (int k = 0; k < 8; ++k) out += static_cast<char>((v >> (8 * k)) & 0xFF);
}

// How the arrays of one file are encoded (header_type is always UInt64).
struct Encoding {
  const std::string& path;
  const VtuWriteOptions& options;
  std::string scratch;  // reused between arrays: header, then compressed blocks
};

// The base64 text of one array. Uncompressed: one base64 run of [UInt64 byte count][values].
// Compressed (VTK's vtkZLibDataCompressor layout): the header [#blocks, block size, size of the
// last block if partial (else 0), compressed size of each block] as one base64 run, then the
// concatenated zlib streams of the blocks as a second run; VTK decodes the two separately.
void appendEncoded(std::string& out, Encoding& e, const std::string& raw) {
  std::string& buffer = e.scratch;
  buffer.clear();
  if (!e.options.compress) {
    appendLittleEndian(buffer, raw.size());
    buffer += raw;
    appendBase64(out, buffer.data(), buffer.size());
    return;
  }
  const size_t blockSize = static_cast<size_t>(e.options.compressionBlockSize);
  const size_t numBlocks = (raw.size() + blockSize - 1) / blockSize;
  appendLittleEndian(buffer, numBlocks);
  appendLittleEndian(buffer, blockSize);
  appendLittleEndian(buffer, raw.size() % blockSize);
  const size_t headerBytes = 8 * (3 + numBlocks);
  buffer.resize(headerBytes);
  for (size_t b = 0; b < numBlocks; ++b) {
    const size_t begin = b * blockSize, n = std::min(blockSize, raw.size() - begin);
    const size_t at = buffer.size();
    uLongf packed = compressBound(static_cast<uLong>(n));
    buffer.resize(at + packed);
    const int rc = compress2(reinterpret_cast<Bytef*>(buffer.data() + at), &packed, reinterpret_cast<const Bytef*>(raw.data() + begin),
                             static_cast<uLong>(n), e.options.compressionLevel);
    if (rc != Z_OK) fail(e.path, "cannot write: zlib compression failed (" + std::string(zError(rc)) + ")");
    buffer.resize(at + packed);
    for (int k = 0; k < 8; ++k) buffer[8 * (3 + b) + k] = static_cast<char>((uint64_t(packed) >> (8 * k)) & 0xFF);
  }
  appendBase64(out, buffer.data(), headerBytes);
  appendBase64(out, buffer.data() + headerBytes, buffer.size() - headerBytes);
}

void appendArray(std::string& out, Encoding& e, const char* type, const std::string& name, int components, const Block& block) {
  out += "        <DataArray type=\"";
  out += type;
  out += "\" Name=\"" + escapeAttribute(name) + "\"";
  if (components != 1) out += " NumberOfComponents=\"" + std::to_string(components) + "\"";
  out += " format=\"binary\">";
  appendEncoded(out, e, block.bytes());
  out += "</DataArray>\n";
}

// `count` real values get(0 .. count-1) as Float64, or Float32 when the options ask for it.
template <class Get>
void appendReals(std::string& out, Encoding& e, const std::string& name, int components, size_t count, const Get& get) {
  const bool single = e.options.float32;
  Block block((single ? 4 : 8) * static_cast<uint64_t>(count));
  for (size_t i = 0; i < count; ++i)
    if (single) block.putFloat32(static_cast<float>(get(i)));
    else block.putFloat64(get(i));
  appendArray(out, e, single ? "Float32" : "Float64", name, components, block);
}

void appendPoints(std::string& out, Encoding& e, const Eigen::Matrix3Xd& points) {
  appendReals(out, e, "Points", 3, static_cast<size_t>(points.size()), [&](size_t i) { return points.data()[i]; });
}

void appendData(std::string& out, Encoding& e, const char* section, const std::vector<DataArray>& arrays) {
  if (arrays.empty()) return;
  out += std::string("      <") + section + ">\n";
  for (const DataArray& a : arrays)
    appendReals(out, e, a.name, a.components, a.values.size(), [&](size_t i) { return a.values[i]; });
  out += std::string("      </") + section + ">\n";
}

void checkData(const std::string& path, const std::vector<DataArray>& arrays, Eigen::Index entries, const char* noun) {
  for (const DataArray& a : arrays) {
    if (a.components < 1)
      fail(path, std::string("cannot write ") + noun + " data '" + a.name + "': NumberOfComponents must be at least 1, found " +
                     std::to_string(a.components));
    const uint64_t expected = static_cast<uint64_t>(a.components) * static_cast<uint64_t>(entries);
    if (a.values.size() != expected)
      fail(path, std::string("cannot write ") + noun + " data '" + a.name + "': it has " + std::to_string(a.values.size()) +
                     " values, but " + std::to_string(a.components) + " components x " + std::to_string(entries) + " " + noun +
                     "s need " + std::to_string(expected));
  }
}

// The <Cells> section of tetrahedra: connectivity, offsets and types.
void appendCells(std::string& out, Encoding& e, const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets) {
  const Eigen::Index numCells = tets.cols();
  out += "      <Cells>\n";
  // Node indices are ints; the last offset, 4 x #cells, decides whether Int32 holds them all.
  const int indexBytes = e.options.int32Indices && 4 * static_cast<uint64_t>(numCells) <= INT32_MAX ? 4 : 8;
  const char* indexType = indexBytes == 4 ? "Int32" : "Int64";
  Block connectivity(4 * indexBytes * static_cast<uint64_t>(numCells)), offsets(indexBytes * static_cast<uint64_t>(numCells)),
      types(static_cast<uint64_t>(numCells));
  for (Eigen::Index c = 0; c < numCells; ++c) {
    for (int k = 0; k < 4; ++k) connectivity.putInt(tets(k, c), indexBytes);
    offsets.putInt(4 * (c + 1), indexBytes);
    types.putUnsigned(10, 1);  // VTK_TETRA
  }
  appendArray(out, e, indexType, "connectivity", 1, connectivity);
  appendArray(out, e, indexType, "offsets", 1, offsets);
  appendArray(out, e, "UInt8", "types", 1, types);
  out += "      </Cells>\n";
}

}  // namespace

std::string encodeVtuCells(const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets, const VtuWriteOptions& options) {
  VtuWriteOptions once = options;
  once.encodedCells = nullptr;
  const std::string name = "the encoded cells";
  Encoding e{name, once, {}};
  std::string out;
  appendCells(out, e, tets);
  return out;
}

void writeVtu(const std::string& path, const Eigen::Matrix3Xd& points, const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets,
              const std::vector<DataArray>& pointData, const std::vector<DataArray>& cellData, const VtuWriteOptions& options) {
  const Eigen::Index numPoints = points.cols(), numCells = tets.cols();
  for (Eigen::Index c = 0; c < numCells; ++c)
    for (int k = 0; k < 4; ++k)
      if (tets(k, c) < 0 || tets(k, c) >= numPoints)
        fail(path, "cannot write: tetrahedron " + std::to_string(c) + " refers to node " + std::to_string(tets(k, c)) + ", but there are " +
                       std::to_string(numPoints) + " points");
  checkData(path, pointData, numPoints, "point");
  checkData(path, cellData, numCells, "cell");
  if (options.compress) {
    if (options.compressionLevel < 1 || options.compressionLevel > 9)
      fail(path, "cannot write: the zlib compression level must be 1..9, found " + std::to_string(options.compressionLevel));
    if (options.compressionBlockSize < 1024)
      fail(path, "cannot write: the compression block size must be at least 1024 bytes, found " +
                     std::to_string(options.compressionBlockSize));
  }
  Encoding e{path, options, {}};

  std::string out =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\"";
  if (options.compress) out += " compressor=\"vtkZLibDataCompressor\"";
  out +=
      ">\n"
      "  <UnstructuredGrid>\n"
      "    <Piece NumberOfPoints=\"" +
      std::to_string(numPoints) + "\" NumberOfCells=\"" + std::to_string(numCells) + "\">\n";
  appendData(out, e, "PointData", pointData);
  appendData(out, e, "CellData", cellData);

  out += "      <Points>\n";
  appendPoints(out, e, points);
  out += "      </Points>\n";
  if (options.encodedCells) out += *options.encodedCells;
  else appendCells(out, e, tets);
  out +=
      "    </Piece>\n"
      "  </UnstructuredGrid>\n"
      "</VTKFile>\n";
  writeFileAtomic(path, out);
}

void writeVtp(const std::string& path, const Eigen::Matrix3Xd& points, const Eigen::Matrix<int, 3, Eigen::Dynamic>& triangles,
              bool vertexCells, const std::vector<DataArray>& pointData, const VtuWriteOptions& options) {
  const Eigen::Index numPoints = points.cols(), numTris = triangles.cols();
  for (Eigen::Index c = 0; c < numTris; ++c)
    for (int k = 0; k < 3; ++k)
      if (triangles(k, c) < 0 || triangles(k, c) >= numPoints)
        fail(path, "cannot write: triangle " + std::to_string(c) + " refers to point " + std::to_string(triangles(k, c)) +
                       ", but there are " + std::to_string(numPoints) + " points");
  for (Eigen::Index i = 0; i < numPoints; ++i)
    if (!points.col(i).allFinite()) fail(path, "cannot write: point " + std::to_string(i) + " is not finite");
  checkData(path, pointData, numPoints, "point");
  if (options.compress && (options.compressionLevel < 1 || options.compressionLevel > 9 || options.compressionBlockSize < 1024))
    fail(path, "cannot write: bad compression settings (level 1..9, block size >= 1024 bytes)");
  Encoding e{path, options, {}};
  const Eigen::Index numVerts = vertexCells ? numPoints : 0;
  std::string out =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\"";
  if (options.compress) out += " compressor=\"vtkZLibDataCompressor\"";
  out += ">\n  <PolyData>\n    <Piece NumberOfPoints=\"" + std::to_string(numPoints) + "\" NumberOfVerts=\"" +
         std::to_string(numVerts) + "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"" + std::to_string(numTris) +
         "\">\n";
  appendData(out, e, "PointData", pointData);
  out += "      <Points>\n";
  appendPoints(out, e, points);
  out += "      </Points>\n";
  const bool small = options.int32Indices && 3 * static_cast<uint64_t>(std::max(numTris, numVerts)) <= INT32_MAX;
  const int indexBytes = small ? 4 : 8;
  const char* indexType = small ? "Int32" : "Int64";
  if (numVerts > 0) {
    Block connectivity(indexBytes * static_cast<uint64_t>(numVerts)), offsets(indexBytes * static_cast<uint64_t>(numVerts));
    for (Eigen::Index i = 0; i < numVerts; ++i) {
      connectivity.putInt(i, indexBytes);
      offsets.putInt(i + 1, indexBytes);
    }
    out += "      <Verts>\n";
    appendArray(out, e, indexType, "connectivity", 1, connectivity);
    appendArray(out, e, indexType, "offsets", 1, offsets);
    out += "      </Verts>\n";
  }
  if (numTris > 0) {
    Block connectivity(3 * indexBytes * static_cast<uint64_t>(numTris)), offsets(indexBytes * static_cast<uint64_t>(numTris));
    for (Eigen::Index c = 0; c < numTris; ++c) {
      for (int k = 0; k < 3; ++k) connectivity.putInt(triangles(k, c), indexBytes);
      offsets.putInt(3 * (c + 1), indexBytes);
    }
    out += "      <Polys>\n";
    appendArray(out, e, indexType, "connectivity", 1, connectivity);
    appendArray(out, e, indexType, "offsets", 1, offsets);
    out += "      </Polys>\n";
  }
  out +=
      "    </Piece>\n"
      "  </PolyData>\n"
      "</VTKFile>\n";
  writeFileAtomic(path, out);
}

void writePvd(const std::string& path, const std::vector<std::pair<double, std::string>>& entries) {
  std::string out =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
      "  <Collection>\n";
  for (const auto& [time, file] : entries) {
    if (!std::isfinite(time)) fail(path, "cannot write: the time of '" + file + "' is not finite");
    out += "    <DataSet timestep=\"" + formatNumber(time) + "\" group=\"\" part=\"0\" file=\"" + escapeAttribute(file) + "\"/>\n";
  }
  out +=
      "  </Collection>\n"
      "</VTKFile>\n";
  writeFileAtomic(path, out);
}

}  // namespace viscera::io
