// .vtu and .pvd output for ParaView, and the atomic file write every writer goes through.
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "engine/core/Error.h"
#include "io/mesh/Mesh.h"

namespace viscera::io {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) { throw Error(SourceLoc{path, 0, 0}, what); }

// Shortest text that reads back as the same double.
std::string formatDouble(double v) {
  char buffer[32];
  auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, ec == std::errc() ? end : buffer);
}

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

// Little-endian bytes of one DataArray, preceded by the UInt64 byte count VTK expects.
// Bytes are assembled explicitly so the output does not depend on the host's byte order.
class Block {
 public:
  explicit Block(uint64_t payloadBytes) {
    bytes_.reserve(8 + payloadBytes);
    putUnsigned(payloadBytes, 8);
  }
  void putUnsigned(uint64_t v, int size) {
    char le[8];
    for (int k = 0; k < size; ++k) le[k] = static_cast<char>((v >> (8 * k)) & 0xFF);
    bytes_.append(le, static_cast<size_t>(size));
  }
  void putInt64(int64_t v) { putUnsigned(static_cast<uint64_t>(v), 8); }
  void putFloat64(double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    putUnsigned(bits, 8);
  }
  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
};

void appendBase64(std::string& out, const std::string& bytes) {
  static const char kDigits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t n = bytes.size();
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

void appendArray(std::string& out, const char* type, const std::string& name, int components, const Block& block) {
  out += "        <DataArray type=\"";
  out += type;
  out += "\" Name=\"" + escapeAttribute(name) + "\"";
  if (components != 1) out += " NumberOfComponents=\"" + std::to_string(components) + "\"";
  out += " format=\"binary\">";
  appendBase64(out, block.bytes());
  out += "</DataArray>\n";
}

void appendData(std::string& out, const std::string& path, const char* section, const std::vector<DataArray>& arrays, Eigen::Index entries,
                const char* noun) {
  if (arrays.empty()) return;
  out += std::string("      <") + section + ">\n";
  for (const DataArray& a : arrays) {
    if (a.components < 1)
      fail(path, std::string("cannot write ") + noun + " data '" + a.name + "': NumberOfComponents must be at least 1, found " +
                     std::to_string(a.components));
    const uint64_t expected = static_cast<uint64_t>(a.components) * static_cast<uint64_t>(entries);
    if (a.values.size() != expected)
      fail(path, std::string("cannot write ") + noun + " data '" + a.name + "': it has " + std::to_string(a.values.size()) +
                     " values, but " + std::to_string(a.components) + " components x " + std::to_string(entries) + " " + noun +
                     "s need " + std::to_string(expected));
    Block block(8 * expected);
    for (double v : a.values) block.putFloat64(v);
    appendArray(out, "Float64", a.name, a.components, block);
  }
  out += std::string("      </") + section + ">\n";
}

}  // namespace

void writeVtu(const std::string& path, const Eigen::Matrix3Xd& points, const Eigen::Matrix<int, 4, Eigen::Dynamic>& tets,
              const std::vector<DataArray>& pointData, const std::vector<DataArray>& cellData) {
  const Eigen::Index numPoints = points.cols(), numCells = tets.cols();
  for (Eigen::Index c = 0; c < numCells; ++c)
    for (int k = 0; k < 4; ++k)
      if (tets(k, c) < 0 || tets(k, c) >= numPoints)
        fail(path, "cannot write: tetrahedron " + std::to_string(c) + " refers to node " + std::to_string(tets(k, c)) + ", but there are " +
                       std::to_string(numPoints) + " points");

  std::string out =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
      "  <UnstructuredGrid>\n"
      "    <Piece NumberOfPoints=\"" +
      std::to_string(numPoints) + "\" NumberOfCells=\"" + std::to_string(numCells) + "\">\n";
  appendData(out, path, "PointData", pointData, numPoints, "point");
  appendData(out, path, "CellData", cellData, numCells, "cell");

  out += "      <Points>\n";
  Block xyz(24 * static_cast<uint64_t>(numPoints));
  for (Eigen::Index i = 0; i < numPoints; ++i)
    for (int k = 0; k < 3; ++k) xyz.putFloat64(points(k, i));
  appendArray(out, "Float64", "Points", 3, xyz);
  out += "      </Points>\n      <Cells>\n";
  Block connectivity(32 * static_cast<uint64_t>(numCells)), offsets(8 * static_cast<uint64_t>(numCells)),
      types(static_cast<uint64_t>(numCells));
  for (Eigen::Index c = 0; c < numCells; ++c) {
    for (int k = 0; k < 4; ++k) connectivity.putInt64(tets(k, c));
    offsets.putInt64(4 * (c + 1));
    types.putUnsigned(10, 1);  // VTK_TETRA
  }
  appendArray(out, "Int64", "connectivity", 1, connectivity);
  appendArray(out, "Int64", "offsets", 1, offsets);
  appendArray(out, "UInt8", "types", 1, types);
  out +=
      "      </Cells>\n"
      "    </Piece>\n"
      "  </UnstructuredGrid>\n"
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
    out += "    <DataSet timestep=\"" + formatDouble(time) + "\" group=\"\" part=\"0\" file=\"" + escapeAttribute(file) + "\"/>\n";
  }
  out +=
      "  </Collection>\n"
      "</VTKFile>\n";
  writeFileAtomic(path, out);
}

void writeFileAtomic(const std::string& path, const std::string& content) {
  // Same folder as the target, so the rename stays on one file system and is atomic.
  const std::string temp = path + ".tmp." + std::to_string(::getpid());
  auto failWith = [&](int err, const char* step, bool removeTemp) {
    if (removeTemp) ::unlink(temp.c_str());
    fail(path, std::string("cannot write file: ") + step + " " + temp + " failed: " + std::strerror(err));
  };
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) {
    const int err = errno;
    failWith(err, "creating", false);
  }
  size_t done = 0;
  while (done < content.size()) {
    const ssize_t n = ::write(fd, content.data() + done, content.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      failWith(err, "writing", true);
    }
    done += static_cast<size_t>(n);
  }
  if (::close(fd) != 0) {  // deferred write errors (e.g. a full disk on NFS) show up here
    const int err = errno;
    failWith(err, "closing", true);
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    failWith(err, "renaming", true);
  }
}

}  // namespace viscera::io
