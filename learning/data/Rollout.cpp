#include "learning/data/Rollout.h"

#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/Error.h"
#include "core/Files.h"

namespace viscera::learning {

namespace {

constexpr char kMeshMagic[8] = {'V', 'S', 'C', 'M', 'E', 'S', 'H', '1'};
constexpr char kRolloutMagic[8] = {'V', 'S', 'C', 'R', 'O', 'L', 'L', '1'};
constexpr char kCloudMagic[8] = {'V', 'S', 'C', 'C', 'L', 'O', 'U', '1'};
constexpr std::uint32_t kVersion = 1;
// Bytes of a frame besides the positions: t, tip, orientation (x y z w), velocity, angular
// velocity, force (all float64), contacts (int32).
constexpr size_t kFrameFixedBytes = 8 * (1 + 3 + 4 + 3 + 3 + 3) + 4;

// Little-endian values appended to a byte string (the host's order is not assumed).
class Bytes {
 public:
  template <class T>
  void put(T v) {
    static_assert(std::is_arithmetic_v<T>);
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (!littleEndian()) std::reverse(b, b + sizeof(T));
    out.append(reinterpret_cast<const char*>(b), sizeof(T));
  }
  std::string out;
  static bool littleEndian() {
    const std::uint16_t one = 1;
    unsigned char c;
    std::memcpy(&c, &one, 1);
    return c == 1;
  }
};

// Reads little-endian values from a file's bytes; every short read is an error naming the file
// and the offset.
class Reader {
 public:
  Reader(std::string path, std::string bytes) : path_(std::move(path)), bytes_(std::move(bytes)) {}
  template <class T>
  T get(const char* what) {
    need(sizeof(T), what);
    unsigned char b[sizeof(T)];
    std::memcpy(b, bytes_.data() + pos_, sizeof(T));
    if (!Bytes::littleEndian()) std::reverse(b, b + sizeof(T));
    T v;
    std::memcpy(&v, b, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  void magic(const char (&m)[8], const char* kind) {
    if (bytes_.size() < 8 || std::memcmp(bytes_.data(), m, 8) != 0) fail("not a " + std::string(kind) + " (its first bytes are not " + std::string(m, 8) + ")");
    pos_ = 8;
    const auto version = get<std::uint32_t>("the version");
    if (version != kVersion)
      fail(std::string(kind) + " version " + std::to_string(version) + "; this build reads version " + std::to_string(kVersion));
  }
  void need(size_t n, const std::string& what) const {
    if (bytes_.size() - pos_ < n) fail("ends at byte " + std::to_string(bytes_.size()) + " inside " + what);
  }
  size_t remaining() const { return bytes_.size() - pos_; }
  [[noreturn]] void fail(const std::string& why) const { throw Error(SourceLoc{path_}, why); }

 private:
  std::string path_, bytes_;
  size_t pos_ = 0;
};

}  // namespace

void writeRestMesh(const std::string& path, const RestMesh& m) {
  Bytes b;
  b.out.assign(kMeshMagic, 8);
  b.put(kVersion);
  b.put(static_cast<std::uint32_t>(m.points.cols()));
  b.put(static_cast<std::uint32_t>(m.tets.cols()));
  b.put(static_cast<std::uint32_t>(m.fixed.size()));
  for (Eigen::Index i = 0; i < m.points.size(); ++i) b.put(m.points.data()[i]);
  for (Eigen::Index i = 0; i < m.tets.size(); ++i) b.put(static_cast<std::int32_t>(m.tets.data()[i]));
  for (int f : m.fixed) b.put(static_cast<std::int32_t>(f));
  writeFileAtomic(path, b.out);
}

RestMesh readRestMesh(const std::string& path) {
  Reader r(path, readInputFile(path, "rest mesh"));
  r.magic(kMeshMagic, "rest mesh");
  const auto nodes = r.get<std::uint32_t>("the node count"), tets = r.get<std::uint32_t>("the tetrahedron count"),
             fixed = r.get<std::uint32_t>("the fixed-node count");
  // The counts are checked against the file's size before anything is allocated for them.
  const std::uint64_t want = 24ull * nodes + 16ull * tets + 4ull * fixed;
  if (want != r.remaining())
    r.fail("holds " + std::to_string(r.remaining()) + " bytes after its header; " + std::to_string(nodes) + " nodes, " +
           std::to_string(tets) + " tetrahedra and " + std::to_string(fixed) + " fixed nodes take " + std::to_string(want));
  RestMesh m;
  m.points.resize(3, nodes);
  for (Eigen::Index i = 0; i < m.points.size(); ++i) m.points.data()[i] = r.get<double>("the positions");
  m.tets.resize(4, tets);
  for (Eigen::Index i = 0; i < m.tets.size(); ++i) {
    const auto v = r.get<std::int32_t>("the tetrahedra");
    if (v < 0 || static_cast<std::uint32_t>(v) >= nodes)
      r.fail("tetrahedron " + std::to_string(i / 4) + " refers to node " + std::to_string(v) + " of " + std::to_string(nodes));
    m.tets.data()[i] = v;
  }
  for (std::uint32_t k = 0; k < fixed; ++k) {
    const auto v = r.get<std::int32_t>("the fixed nodes");
    if (v < 0 || static_cast<std::uint32_t>(v) >= nodes) r.fail("fixed node " + std::to_string(v) + " is not one of " + std::to_string(nodes));
    m.fixed.push_back(v);
  }
  return m;
}

RolloutWriter::RolloutWriter(const std::string& path, int nodes) : path_(path), partial_(path + ".partial"), nodes_(nodes) {
  file_ = std::fopen(partial_.c_str(), "wb");
  if (!file_) throw Error(SourceLoc{path}, "cannot write the rollout: " + std::string(std::strerror(errno)));
  Bytes b;
  b.out.assign(kRolloutMagic, 8);
  b.put(kVersion);
  b.put(static_cast<std::uint32_t>(nodes));
  b.put(std::uint32_t{0});  // the frame count, written by close()
  if (std::fwrite(b.out.data(), 1, b.out.size(), file_) != b.out.size())
    throw Error(SourceLoc{path}, "cannot write the rollout: " + std::string(std::strerror(errno)));
}

RolloutWriter::~RolloutWriter() {
  if (file_) {
    std::fclose(file_);
    std::remove(partial_.c_str());
  }
}

void RolloutWriter::add(const RolloutFrame& f) {
  if (f.x.cols() != nodes_) throw Error(SourceLoc{path_}, "a frame of " + std::to_string(f.x.cols()) + " nodes in a rollout of " + std::to_string(nodes_));
  Bytes b;
  b.out.reserve(kFrameFixedBytes + 12 * static_cast<size_t>(nodes_));
  b.put(f.t);
  for (Eigen::Index i = 0; i < f.x.size(); ++i) b.put(f.x.data()[i]);
  for (int k = 0; k < 3; ++k) b.put(f.tip[k]);
  for (double c : {f.orientation.x(), f.orientation.y(), f.orientation.z(), f.orientation.w()}) b.put(c);
  for (int k = 0; k < 3; ++k) b.put(f.velocity[k]);
  for (int k = 0; k < 3; ++k) b.put(f.angularVelocity[k]);
  for (int k = 0; k < 3; ++k) b.put(f.force[k]);
  b.put(f.contacts);
  if (std::fwrite(b.out.data(), 1, b.out.size(), file_) != b.out.size())
    throw Error(SourceLoc{path_}, "cannot write the rollout: " + std::string(std::strerror(errno)));
  ++frames_;
}

void RolloutWriter::close() {
  if (!file_) return;
  Bytes count;
  count.put(static_cast<std::uint32_t>(frames_));
  const bool ok = std::fseek(file_, 16, SEEK_SET) == 0 && std::fwrite(count.out.data(), 1, 4, file_) == 4;
  const bool closed = std::fclose(file_) == 0;
  file_ = nullptr;
  std::error_code ec;
  if (ok && closed) std::filesystem::rename(partial_, path_, ec);
  if (!ok || !closed || ec) {
    std::remove(partial_.c_str());
    throw Error(SourceLoc{path_}, "cannot finish the rollout" + (ec ? ": " + ec.message() : std::string()));
  }
}

std::vector<RolloutFrame> readRollout(const std::string& path, int nodes) {
  Reader r(path, readInputFile(path, "rollout"));
  r.magic(kRolloutMagic, "rollout");
  const auto n = r.get<std::uint32_t>("the node count"), frames = r.get<std::uint32_t>("the frame count");
  if (nodes >= 0 && n != static_cast<std::uint32_t>(nodes))
    r.fail("has " + std::to_string(n) + " nodes a frame; its mesh has " + std::to_string(nodes));
  const std::uint64_t frameBytes = kFrameFixedBytes + 12ull * n;
  if (frameBytes * frames != r.remaining())
    r.fail("holds " + std::to_string(r.remaining()) + " bytes of frames; " + std::to_string(frames) + " frames of " +
           std::to_string(n) + " nodes take " + std::to_string(frameBytes * frames));
  std::vector<RolloutFrame> out(frames);
  for (RolloutFrame& f : out) {
    f.t = r.get<double>("a frame's time");
    f.x.resize(3, n);
    for (Eigen::Index i = 0; i < f.x.size(); ++i) f.x.data()[i] = r.get<float>("a frame's positions");
    for (int k = 0; k < 3; ++k) f.tip[k] = r.get<double>("a frame's instrument position");
    double q[4];
    for (double& c : q) c = r.get<double>("a frame's instrument orientation");
    f.orientation = Eigen::Quaterniond(q[3], q[0], q[1], q[2]);
    for (int k = 0; k < 3; ++k) f.velocity[k] = r.get<double>("a frame's instrument velocity");
    for (int k = 0; k < 3; ++k) f.angularVelocity[k] = r.get<double>("a frame's instrument angular velocity");
    for (int k = 0; k < 3; ++k) f.force[k] = r.get<double>("a frame's contact force");
    f.contacts = r.get<std::int32_t>("a frame's contact count");
  }
  return out;
}

void writeCloudFrames(const std::string& path, const std::vector<Eigen::Matrix3Xf>& clouds) {
  Bytes b;
  b.out.assign(kCloudMagic, 8);
  b.put(kVersion);
  b.put(static_cast<std::uint32_t>(clouds.size()));
  for (const auto& c : clouds) {
    b.put(static_cast<std::uint32_t>(c.cols()));
    for (Eigen::Index i = 0; i < c.size(); ++i) b.put(c.data()[i]);
  }
  writeFileAtomic(path, b.out);
}

std::vector<Eigen::Matrix3Xf> readCloudFrames(const std::string& path) {
  Reader r(path, readInputFile(path, "cloud frames"));
  r.magic(kCloudMagic, "cloud-frames file");
  const auto frames = r.get<std::uint32_t>("the frame count");
  if (frames > r.remaining() / 4) r.fail("announces " + std::to_string(frames) + " frames, more than its size can hold");
  std::vector<Eigen::Matrix3Xf> out(frames);
  for (auto& c : out) {
    const auto n = r.get<std::uint32_t>("a frame's point count");
    r.need(12ull * n, "a frame's points");
    c.resize(3, n);
    for (Eigen::Index i = 0; i < c.size(); ++i) c.data()[i] = r.get<float>("a frame's points");
  }
  if (r.remaining() != 0) r.fail(std::to_string(r.remaining()) + " bytes after the last frame");
  return out;
}

}  // namespace viscera::learning

namespace viscera::learning {

RolloutSet readRolloutSet(const std::string& folder) {
  namespace fs = std::filesystem;
  const std::string indexPath = (fs::path(folder) / "rollouts.json").string();
  nlohmann::json index;
  try {
    index = nlohmann::json::parse(readInputFile(indexPath, "rollout index"));
  } catch (const nlohmann::json::exception& e) {
    throw Error(SourceLoc{indexPath}, std::string("not a rollout index: ") + e.what());
  }
  auto need = [&](const char* key) -> const nlohmann::json& {
    if (!index.is_object() || !index.contains(key)) throw Error(SourceLoc{indexPath}, std::string("the index has no \"") + key + "\"");
    return index.at(key);
  };
  RolloutSet set;
  set.folder = folder;
  try {
    if (need("format").get<std::string>() != "viscera rollouts") throw Error(SourceLoc{indexPath}, "format is not \"viscera rollouts\"");
    set.units = need("units").get<std::string>();
    set.frameRate = need("frameRate").get<double>();
    set.instrumentRadius = need("instrumentRadius").get<double>();
    const std::string meshFile = need("mesh").at("file").get<std::string>();
    set.mesh = readRestMesh((fs::path(folder) / meshFile).string());
    for (const auto& r : need("rollouts")) {
      const std::string file = (fs::path(folder) / r.at("file").get<std::string>()).string();
      if (r.value("status", "ok") != "ok") {
        set.skipped.push_back(file);
        continue;
      }
      if (!fs::is_regular_file(file)) throw Error(SourceLoc{indexPath}, "rollout " + file + " is listed but missing");
      set.files.push_back(file);
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(SourceLoc{indexPath}, std::string("malformed rollout index: ") + e.what());
  }
  if (!(set.frameRate > 0)) throw Error(SourceLoc{indexPath}, "frameRate must be positive");
  return set;
}

}  // namespace viscera::learning
