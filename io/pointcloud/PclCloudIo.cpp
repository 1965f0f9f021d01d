// readCloud / writeCloud through PCL's PCD and PLY readers and writers. Files are read into PCL's
// untyped PCLPointCloud2 so that any field layout (float32 or float64 coordinates, extra fields
// such as rgb, organized or not) is accepted; the coordinates and normals are then copied out.
#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "core/Error.h"
#include "io/pointcloud/CloudIo.h"

namespace viscera::cloud {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const std::string& path, const std::string& what) { throw Error(SourceLoc{path}, what); }

// PCL reports its own failures on stderr; every failure is reported here instead, with the file
// name, so PCL is kept quiet.
void silencePcl() { pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS); }

enum class Format { Pcd, Ply };

Format formatOf(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".pcd") return Format::Pcd;
  if (ext == ".ply") return Format::Ply;
  fail(path, "unknown point-cloud format '" + ext + "': expected a .pcd or .ply file");
}

// The first line of a PLY file's header that starts with "format", e.g. "format ascii 1.0".
std::string plyEncoding(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  for (int n = 0; n < 64 && std::getline(in, line); ++n) {
    if (line.rfind("format ", 0) == 0) {
      std::string word = line.substr(7, line.find(' ', 7) - 7);
      if (!word.empty() && word.back() == '\r') word.pop_back();
      return word;
    }
    if (line.rfind("end_header", 0) == 0) break;
  }
  return "";
}

std::vector<std::string> splitWords(const std::string& line) {
  std::vector<std::string> words;
  std::string word;
  for (char c : line) {
    if (c == ' ' || c == '\t' || c == '\r') {
      if (!word.empty()) words.push_back(word), word.clear();
    } else {
      word += c;
    }
  }
  if (!word.empty()) words.push_back(word);
  return words;
}

// A PLY header checked before PCL reads the file: only header keywords, no list property among
// the vertices', and every element count against the file's size (PCL allocates what the header
// announces: a header claiming billions of vertices would exhaust the memory). A binary property
// takes its type's size, a list at least its count's; an ASCII value at least two bytes.
void checkPlyHeader(const std::string& path, std::uintmax_t fileSize) {
  std::ifstream in(path, std::ios::binary);
  std::string raw, encoding, element;
  unsigned long long count = 0, bytes = 0;
  int line = 0;
  auto sizeOf = [](const std::string& type) -> unsigned {
    if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
    if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
    if (type == "double" || type == "float64" || type == "int64" || type == "uint64") return 8;
    return 4;
  };
  auto close = [&]() {
    if (element.empty()) return;
    const unsigned long long each = std::max<unsigned long long>(1, bytes);
    if (count > fileSize / each)
      throw Error(SourceLoc{path, line}, "the header declares " + std::to_string(count) + " " + element +
                                             " elements of at least " + std::to_string(each) + " bytes, but the file has " +
                                             std::to_string(fileSize) + " bytes (truncated, or a corrupt header)");
  };
  while (line < 10000 && std::getline(in, raw)) {
    ++line;
    const auto w = splitWords(raw);
    if (w.empty()) continue;
    if (w[0] == "end_header") break;
    // PCL's parser passes over lines it does not know, and then may take a later element's
    // properties for the vertices': a header holds these keywords only.
    static const char* const kKeywords[] = {"ply", "format", "comment", "obj_info", "element", "property"};
    if (std::none_of(std::begin(kKeywords), std::end(kKeywords), [&](const char* k) { return w[0] == k; }))
      throw Error(SourceLoc{path, line}, "malformed PLY header: '" + raw.substr(0, 40) + "' is not a header line");
    if (w[0] == "format" && w.size() > 1) encoding = w[1];
    // PCL reads the vertex element's scalar properties only (it aborts on a list there).
    if (w[0] == "property" && element == "vertex" && w.size() > 1 && w[1] == "list")
      throw Error(SourceLoc{path, line}, "a list property in the vertex element is not supported");
    const bool ascii = encoding == "ascii";
    if (w[0] == "element" && w.size() == 3) {
      close();
      element = w[1];
      bytes = 0;
      char* end = nullptr;
      errno = 0;
      count = std::strtoull(w[2].c_str(), &end, 10);
      if (*end != '\0' || errno == ERANGE || w[2][0] == '-')
        throw Error(SourceLoc{path, line}, "element " + element + " needs a non-negative whole count");
    } else if (w[0] == "property" && w.size() >= 3 && !element.empty()) {
      bytes += ascii ? 2 : sizeOf(w[1] == "list" && w.size() >= 5 ? w[2] : w[1]);
    }
  }
  close();
}

const pcl::PCLPointField* findField(const pcl::PCLPointCloud2& c, const char* name) {
  for (const auto& f : c.fields)
    if (f.name == name) return &f;
  return nullptr;
}

size_t typeSize(std::uint8_t datatype) {
  switch (datatype) {
    case pcl::PCLPointField::BOOL:
    case pcl::PCLPointField::INT8:
    case pcl::PCLPointField::UINT8: return 1;
    case pcl::PCLPointField::INT16:
    case pcl::PCLPointField::UINT16: return 2;
    case pcl::PCLPointField::INT32:
    case pcl::PCLPointField::UINT32:
    case pcl::PCLPointField::FLOAT32: return 4;
    case pcl::PCLPointField::INT64:
    case pcl::PCLPointField::UINT64:
    case pcl::PCLPointField::FLOAT64: return 8;
    default: return 0;
  }
}

// One scalar of a field, converted to double. `p` points at the field's first byte in a point;
// the blob is in host byte order (PCL converts big-endian PLY files on reading).
double readScalar(const std::uint8_t* p, std::uint8_t datatype) {
  auto get = [p](auto v) {
    std::memcpy(&v, p, sizeof v);
    return static_cast<double>(v);
  };
  switch (datatype) {
    case pcl::PCLPointField::BOOL:
    case pcl::PCLPointField::UINT8: return get(std::uint8_t{});
    case pcl::PCLPointField::INT8: return get(std::int8_t{});
    case pcl::PCLPointField::INT16: return get(std::int16_t{});
    case pcl::PCLPointField::UINT16: return get(std::uint16_t{});
    case pcl::PCLPointField::INT32: return get(std::int32_t{});
    case pcl::PCLPointField::UINT32: return get(std::uint32_t{});
    case pcl::PCLPointField::INT64: return get(std::int64_t{});
    case pcl::PCLPointField::UINT64: return get(std::uint64_t{});
    case pcl::PCLPointField::FLOAT32: return get(float{});
    default: return get(double{});
  }
}

// The three fields of a vector quantity (x y z, or a normal), checked against the point layout.
struct Vec3Fields {
  const pcl::PCLPointField* f[3];
};

std::optional<Vec3Fields> vectorFields(const std::string& path, const pcl::PCLPointCloud2& c, const char* const names[3]) {
  Vec3Fields v{};
  for (int k = 0; k < 3; ++k) {
    v.f[k] = findField(c, names[k]);
    if (!v.f[k]) return std::nullopt;
    const size_t size = typeSize(v.f[k]->datatype);
    if (size == 0) fail(path, std::string("field ") + names[k] + " has an unknown data type");
    if (v.f[k]->offset + size > c.point_step)
      fail(path, std::string("field ") + names[k] + " lies outside the point record (malformed header)");
  }
  return v;
}

std::string fieldList(const pcl::PCLPointCloud2& c) {
  std::string s;
  for (const auto& f : c.fields) s += (s.empty() ? "" : " ") + f.name;
  return s.empty() ? "none" : s;
}

// The header of a PCD file as far as it is checked here, before PCL reads the file: PCL's reader
// crashes on some non-PCD files and accepts ASCII bodies with missing or non-numeric values (it
// fills in zeros), so the header and an ASCII body are checked first, with line numbers.
struct PcdLayout {
  int valuesPerPoint = 0;  // sum of COUNT over the fields
  long long bytesPerPoint = 0;  // sum of SIZE x COUNT
  long long points = 0;
  std::string data;        // ascii, binary or binary_compressed
  int dataLine = 0;        // line number of the DATA line
};

bool parseInteger(const std::string& text, long long& value) {
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  value = std::strtoll(text.c_str(), &end, 10);
  return end == text.c_str() + text.size() && errno != ERANGE;
}

PcdLayout checkPcdHeader(const std::string& path, std::istream& in) {
  auto fail = [&](int line, const std::string& what) { throw Error(SourceLoc{path, line}, what); };
  PcdLayout layout;
  std::vector<std::string> fields, sizes, types, counts;
  long long width = -1, height = 1;
  bool havePoints = false;
  std::string raw;
  int line = 0;
  while (std::getline(in, raw)) {
    ++line;
    const auto w = splitWords(raw);
    // PCL's reader crashes on a header line of blanks (spaces or tabs) before FIELDS.
    if (w.empty() && !raw.empty() && raw != "\r") fail(line, "a header line holding only blanks (not a PCD header)");
    if (w.empty() || w[0][0] == '#') continue;
    const std::string& key = w[0];
    const std::vector<std::string> args(w.begin() + 1, w.end());
    auto integer = [&](long long& v) {
      if (args.size() != 1 || !parseInteger(args[0], v) || v < 0) fail(line, key + " needs one non-negative whole number");
    };
    if (key == "VERSION" || key == "VIEWPOINT") continue;
    if (key == "FIELDS" || key == "COLUMNS") fields = args;
    else if (key == "SIZE") sizes = args;
    else if (key == "TYPE") types = args;
    else if (key == "COUNT") counts = args;
    else if (key == "WIDTH") integer(width);
    else if (key == "HEIGHT") integer(height);
    else if (key == "POINTS") integer(layout.points), havePoints = true;
    else if (key == "DATA") {
      if (args.size() != 1 || (args[0] != "ascii" && args[0] != "binary" && args[0] != "binary_compressed"))
        fail(line, "DATA must be ascii, binary or binary_compressed");
      layout.data = args[0];
      layout.dataLine = line;
      break;
    } else {
      fail(line, "unexpected line '" + raw.substr(0, 40) + "' in the header (is this a PCD file?)");
    }
  }
  if (layout.dataLine == 0) fail(0, "malformed PCD header: no DATA line (is this a PCD file?)");
  if (fields.empty()) fail(0, "malformed PCD header: no FIELDS line");
  const size_t nf = fields.size();
  if (sizes.size() != nf || types.size() != nf || (!counts.empty() && counts.size() != nf))
    fail(0, "malformed PCD header: FIELDS, SIZE, TYPE and COUNT must list the same number of fields (" +
                std::to_string(nf) + " fields)");
  for (size_t i = 0; i < nf; ++i) {
    long long size = 0, count = 1;
    if (!parseInteger(sizes[i], size) || (size != 1 && size != 2 && size != 4 && size != 8))
      fail(0, "malformed PCD header: SIZE of field " + fields[i] + " must be 1, 2, 4 or 8");
    if (types[i] != "F" && types[i] != "I" && types[i] != "U")
      fail(0, "malformed PCD header: TYPE of field " + fields[i] + " must be F, I or U");
    if (!counts.empty() && (!parseInteger(counts[i], count) || count < 1 || count > 1000000))
      fail(0, "malformed PCD header: COUNT of field " + fields[i] + " must be a whole number from 1 to 1000000");
    layout.valuesPerPoint += static_cast<int>(count);
    layout.bytesPerPoint += size * count;
  }
  if (width < 0 || !havePoints) fail(0, "malformed PCD header: WIDTH and POINTS are required");
  if (height > 0 && width > std::numeric_limits<long long>::max() / height)
    fail(0, "malformed PCD header: WIDTH x HEIGHT (" + std::to_string(width) + " x " + std::to_string(height) + ") is too large");
  if (width * height != layout.points)
    fail(0, "malformed PCD header: WIDTH x HEIGHT (" + std::to_string(width) + " x " + std::to_string(height) +
                ") differs from POINTS (" + std::to_string(layout.points) + ")");
  return layout;
}

// An ASCII body: one line per point with every value a number (nan and inf included).
void checkPcdAsciiBody(const std::string& path, std::istream& in, const PcdLayout& layout) {
  std::string raw;
  long long points = 0;
  for (int line = layout.dataLine + 1; std::getline(in, raw); ++line) {
    const auto w = splitWords(raw);
    if (w.empty()) continue;
    if (points == layout.points)
      throw Error(SourceLoc{path, line}, "more data lines than the " + std::to_string(layout.points) + " POINTS of the header");
    if (static_cast<int>(w.size()) != layout.valuesPerPoint)
      throw Error(SourceLoc{path, line}, "expected " + std::to_string(layout.valuesPerPoint) + " values, got " +
                                             std::to_string(w.size()) + " (truncated or malformed)");
    for (const auto& word : w) {
      char* end = nullptr;
      std::strtod(word.c_str(), &end);
      if (end != word.c_str() + word.size())
        throw Error(SourceLoc{path, line}, "'" + word + "' is not a number");
    }
    ++points;
  }
  if (points < layout.points)
    throw Error(SourceLoc{path}, "the header declares " + std::to_string(layout.points) + " points but the file has " +
                                     std::to_string(points) + " data lines (truncated?)");
}

// Reads the whole file into `blob` and describes its encoding; throws for files PCL cannot read.
void readBlob(const std::string& path, Format format, pcl::PCLPointCloud2& blob, std::string& encoding) {
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  if (format == Format::Pcd) {
    std::ifstream in(path, std::ios::binary);
    const PcdLayout layout = checkPcdHeader(path, in);
    // The body starts after the DATA line.
    const long long bodyStart = in ? static_cast<long long>(in.tellg()) : 0;
    encoding = "pcd " + layout.data;
    if (layout.data == "ascii") checkPcdAsciiBody(path, in, layout);
    // Binary bodies are checked against the bytes after the header before PCL reads what the
    // header announces (it reads past the end of a short body); LZF expands its input at most
    // about 90 times, so a compressed body is bounded by 100.
    const long long size = static_cast<long long>(fs::file_size(path)) - std::max(0LL, bodyStart);
    const long long room = layout.data == "binary" ? size : 100 * size;
    if (layout.data != "ascii" && layout.bytesPerPoint > 0 && layout.points > room / layout.bytesPerPoint)
      fail(path, "the header declares " + std::to_string(layout.points) + " points of " +
                     std::to_string(layout.bytesPerPoint) + " bytes, but the file has " + std::to_string(size) +
                     " bytes after its header (truncated, or a corrupt header)");
    pcl::PCDReader reader;
    int version = 0;
    if (reader.read(path, blob, origin, orientation, version) < 0)
      fail(path, "cannot read the point data of this " + encoding + " file (truncated or corrupt)");
  } else {
    pcl::PLYReader reader;
    int version = 0;
    encoding = "ply " + plyEncoding(path);
    if (encoding == "ply ") fail(path, "malformed PLY header: no 'format' line (is this a PLY file?)");
    checkPlyHeader(path, fs::file_size(path));
    if (reader.read(path, blob, origin, orientation, version) < 0)
      fail(path, "cannot read this " + encoding + " file (malformed header, or truncated or corrupt data)");
  }
  const std::uint64_t points = std::uint64_t(blob.width) * blob.height;
  if (std::uint64_t(blob.row_step) < std::uint64_t(blob.width) * blob.point_step ||
      std::uint64_t(blob.data.size()) < std::uint64_t(blob.height) * blob.row_step)
    fail(path, "the file declares " + std::to_string(points) + " points but holds data for fewer (truncated?)");
}

// Writes with PCL to a temporary name in the target's folder, then renames (atomic on POSIX).
template <typename WriteFn>
void writeAtomically(const std::string& path, WriteFn&& write) {
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !fs::is_directory(parent))
    fail(path, "cannot write file: the folder " + parent.string() + " does not exist");
  const std::string temp = path + ".tmp." + std::to_string(::getpid());
  if (write(temp) < 0) {
    ::unlink(temp.c_str());
    fail(path, "cannot write file: PCL failed to write " + temp);
  }
  // PCL's binary writers create files readable by the owner only; give the file the permissions
  // of any other output (0666 less the umask).
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::chmod(temp.c_str(), 0666 & ~mask);
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(temp.c_str());
    fail(path, std::string("cannot write file: renaming ") + temp + " failed: " + std::strerror(err));
  }
}

}  // namespace

PointCloud readCloud(const std::string& path, const ReadOptions& options, CloudFileInfo* info) {
  silencePcl();
  const Format format = formatOf(path);
  std::error_code ec;
  if (!fs::exists(path, ec)) fail(path, "no such file");
  if (fs::is_directory(path, ec)) fail(path, "is a folder, not a point-cloud file");
  if (!std::ifstream(path, std::ios::binary)) fail(path, std::string("cannot open file: ") + std::strerror(errno));
  if (fs::file_size(path, ec) == 0) fail(path, "the file is empty (0 bytes)");

  pcl::PCLPointCloud2 blob;
  std::string encoding;
  readBlob(path, format, blob, encoding);

  static const char* const kXyz[3] = {"x", "y", "z"};
  static const char* const kNormal[3] = {"normal_x", "normal_y", "normal_z"};
  static const char* const kPlyNormal[3] = {"nx", "ny", "nz"};
  for (const char* name : kXyz)
    if (!findField(blob, name)) fail(path, std::string("has no ") + name + " field (fields: " + fieldList(blob) + ")");
  const Vec3Fields xyz = *vectorFields(path, blob, kXyz);
  std::optional<Vec3Fields> normal = vectorFields(path, blob, kNormal);
  if (!normal) normal = vectorFields(path, blob, kPlyNormal);

  const std::uint64_t total = std::uint64_t(blob.width) * blob.height;
  if (total > std::uint64_t(INT32_MAX)) fail(path, "too many points (" + std::to_string(total) + ")");
  const int n = static_cast<int>(total);
  PointCloud cloud;
  cloud.source = path;
  cloud.points.resize(3, n);
  if (normal) cloud.normals.resize(3, n);
  int kept = 0, nonFinite = 0;
  for (int i = 0; i < n; ++i) {
    // Rows of an organized cloud may be padded: row_step can exceed width * point_step.
    const std::uint8_t* point = blob.data.data() + std::size_t(i / blob.width) * blob.row_step +
                                std::size_t(i % blob.width) * blob.point_step;
    Eigen::Vector3d p, nrm = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) p[k] = readScalar(point + xyz.f[k]->offset, xyz.f[k]->datatype);
    if (normal)
      for (int k = 0; k < 3; ++k) nrm[k] = readScalar(point + normal->f[k]->offset, normal->f[k]->datatype);
    if (!p.allFinite() || !nrm.allFinite()) {
      if (!options.dropNonFinite)
        fail(path, "point " + std::to_string(i) + " has a non-finite " + (p.allFinite() ? "normal" : "coordinate") +
                       " (NaN marks a missing pixel in organized clouds; drop such points with --drop-nan)");
      ++nonFinite;
      continue;
    }
    cloud.points.col(kept) = p;
    if (normal) cloud.normals.col(kept) = nrm;
    ++kept;
  }
  cloud.points.conservativeResize(3, kept);
  if (normal) cloud.normals.conservativeResize(3, kept);
  if (kept == 0 && !options.allowEmpty)
    fail(path, nonFinite ? "every point (" + std::to_string(nonFinite) + ") is non-finite: nothing left" : "the cloud has no points");

  if (info) {
    info->format = encoding;
    info->fields.clear();
    for (const auto& f : blob.fields) info->fields.push_back(f.name);
    info->width = static_cast<int>(blob.width);
    info->height = static_cast<int>(blob.height);
    info->nonFinite = nonFinite;
  }
  return cloud;
}

void writeCloud(const std::string& path, const PointCloud& cloud, CloudEncoding encoding) {
  silencePcl();
  const Format format = formatOf(path);
  const int n = cloud.size();
  if (n == 0) fail(path, "cannot write an empty cloud");
  const bool withNormals = cloud.normals.cols() > 0;
  if (withNormals && cloud.normals.cols() != n)
    fail(path, "cannot write: " + std::to_string(cloud.normals.cols()) + " normals for " + std::to_string(n) + " points");

  // One float32 record per point: x y z [normal_x normal_y normal_z].
  pcl::PCLPointCloud2 blob;
  const char* names[6] = {"x", "y", "z", "normal_x", "normal_y", "normal_z"};
  const int fields = withNormals ? 6 : 3;
  for (int k = 0; k < fields; ++k) {
    pcl::PCLPointField f;
    f.name = names[k];
    f.offset = static_cast<pcl::uindex_t>(4 * k);
    f.datatype = pcl::PCLPointField::FLOAT32;
    f.count = 1;
    blob.fields.push_back(f);
  }
  blob.width = static_cast<pcl::uindex_t>(n);
  blob.height = 1;
  blob.point_step = static_cast<pcl::uindex_t>(4 * fields);
  blob.row_step = blob.point_step * blob.width;
  blob.is_dense = true;
  blob.data.resize(std::size_t(blob.row_step));
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < fields; ++k) {
      const double v = k < 3 ? cloud.points(k, i) : cloud.normals(k - 3, i);
      if (!std::isfinite(v) || std::abs(v) > FLT_MAX)
        fail(path, "cannot write: " + std::string(k < 3 ? "point " : "the normal of point ") + std::to_string(i) +
                       " is not a finite float32 value");
      const float f = static_cast<float>(v);
      std::memcpy(blob.data.data() + std::size_t(i) * blob.point_step + 4 * k, &f, 4);
    }
  }

  // 9 significant digits print every float32 so that it reads back to the same value.
  constexpr int kFloatDigits = 9;
  const bool binary = encoding == CloudEncoding::Binary;
  const Eigen::Vector4f origin = Eigen::Vector4f::Zero();
  const Eigen::Quaternionf orientation = Eigen::Quaternionf::Identity();
  writeAtomically(path, [&](const std::string& temp) {
    if (format == Format::Pcd) {
      pcl::PCDWriter writer;
      return binary ? writer.writeBinary(temp, blob, origin, orientation)
                    : writer.writeASCII(temp, blob, origin, orientation, kFloatDigits);
    }
    // Binary files without PCL's camera element (use_camera = false). PCL's ASCII writer applies
    // the precision only when it writes that element (its other variant formats each line in a
    // stream of its own, with 6 digits), so ASCII files have it; other PLY readers skip it.
    pcl::PLYWriter writer;
    return binary ? writer.writeBinary(temp, blob, origin, orientation, false)
                  : writer.writeASCII(temp, blob, origin, orientation, kFloatDigits, true);
  });
}

}  // namespace viscera::cloud
