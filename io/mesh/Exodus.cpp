#include "io/mesh/Exodus.h"

#include <exodusII.h>
#include <netcdf.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <atomic>
#include <cmath>
#include <mutex>

#include "core/Error.h"

namespace viscera::io {
namespace {

// libexodusII and the netCDF/HDF5 libraries under it keep global state and are not built
// thread-safe: every call goes through this lock.
std::mutex& libraryLock() {
  static std::mutex m;
  return m;
}

// Errors come back as return codes (never printed, never aborting); the library's last message
// says what went wrong.
void quiet() {
  static std::once_flag once;
  std::call_once(once, [] { ex_opts(EX_DEFAULT); });
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  const char *msg = nullptr, *func = nullptr;
  int code = 0;
  ex_get_err(&msg, &func, &code);
  std::string detail = msg && *msg ? std::string(": ") + msg : std::string();
  throw Error(SourceLoc{path}, what + detail);
}

void check(int rc, const std::string& path, const char* what) {
  if (rc < 0) fail(path, std::string("cannot write the Exodus series (") + what + ")");
}


void checkNc(int rc, const std::string& path, const char* what) {
  if (rc != NC_NOERR)
    throw Error(SourceLoc{path}, std::string("cannot write the Exodus series (") + what + "): " + nc_strerror(rc));
}

// Frames a chunk of each field holds. Compressed together, the byte planes of consecutive frames
// (after the shuffle) lie within zlib's window, which takes about a fifth off the gel phantom's
// series for the same compression time; a reader decompresses four frames to read one.
constexpr size_t kFramesPerChunk = 4;

// Field variables on the nodes or the cells, defined as libexodusII defines them (the same
// dimensions, names and layout, so that it and every Exodus reader find them), with the chunking
// and compression chosen here: the library (6.02) chunks one frame at a time and leaves cell
// variables uncompressed, and cell values are the largest part of a tetrahedral frame.
void defineVariables(int file, bool onNodes, const std::vector<std::string>& names, const ExodusLayout& layout,
                     const std::string& path) {
  const size_t n = names.size();
  const std::string what = onNodes ? "node field" : "cell field";
  checkNc(nc_redef(file), path, "define mode");
  int time = 0, entries = 0, nameLength = 0, vars = 0;
  checkNc(nc_inq_dimid(file, "time_step", &time), path, "time dimension");
  checkNc(nc_inq_dimid(file, onNodes ? "num_nodes" : "num_el_in_blk1", &entries), path, "entry dimension");
  checkNc(nc_inq_dimid(file, "len_name", &nameLength), path, "name length");
  checkNc(nc_def_dim(file, onNodes ? "num_nod_var" : "num_elem_var", n, &vars), path, "field count");
  int namesId = 0, tableId = -1;
  const int namesDims[2] = {vars, nameLength};
  checkNc(nc_def_var(file, onNodes ? "name_nod_var" : "name_elem_var", NC_CHAR, 2, namesDims, &namesId), path, "field names");
  if (!onNodes) {
    int blocks = 0;
    checkNc(nc_inq_dimid(file, "num_el_blk", &blocks), path, "block dimension");
    const int tableDims[2] = {blocks, vars};
    checkNc(nc_def_var(file, "elem_var_tab", NC_INT, 2, tableDims, &tableId), path, "cell field table");
  }
  size_t count = 0;
  checkNc(nc_inq_dimlen(file, entries, &count), path, "entry count");
  for (size_t i = 0; i < n; ++i) {
    int id = 0;
    const int dims[2] = {time, entries};
    const size_t chunk[2] = {kFramesPerChunk, count};
    const std::string name = onNodes ? "vals_nod_var" + std::to_string(i + 1) : "vals_elem_var" + std::to_string(i + 1) + "eb1";
    checkNc(nc_def_var(file, name.c_str(), layout.float32 ? NC_FLOAT : NC_DOUBLE, 2, dims, &id), path, what.c_str());
    checkNc(nc_def_var_chunking(file, id, NC_CHUNKED, chunk), path, "field chunks");
    checkNc(nc_def_var_deflate(file, id, 1, 1, layout.compressionLevel), path, "field compression");
  }
  checkNc(nc_enddef(file), path, "define mode");
  size_t length = 0;
  checkNc(nc_inq_dimlen(file, nameLength, &length), path, "name length");
  for (size_t i = 0; i < n; ++i) {
    std::string padded = names[i];
    if (padded.empty() || padded.size() + 1 > length)
      throw Error(SourceLoc{path}, "cannot write the Exodus series: field name '" + padded + "' is empty or too long");
    padded.resize(length, '\0');
    const size_t start[2] = {i, 0}, extent[2] = {1, length};
    checkNc(nc_put_vara_text(file, namesId, start, extent, padded.data()), path, "field names");
  }
  if (tableId >= 0) {
    const std::vector<int> truth(n, 1);
    checkNc(nc_put_var_int(file, tableId, truth.data()), path, "cell field table");
  }
}

}  // namespace

ExodusWriter::ExodusWriter(const std::string& path, const ExodusLayout& layout) : path_(path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0 && (S_ISLNK(st.st_mode) || !S_ISREG(st.st_mode)))
    throw Error(SourceLoc{path}, "cannot write the Exodus series: the path exists and is not a regular file "
                                 "(outputs do not follow links or replace devices)");
  if (layout.compressionLevel < 1 || layout.compressionLevel > 9)
    throw Error(SourceLoc{path}, "cannot write the Exodus series: the zlib level must be 1..9, found " +
                                     std::to_string(layout.compressionLevel));
  nodes_ = layout.rest.cols();
  const bool tets = layout.tets.cols() > 0, tris = !tets && layout.triangles.cols() > 0;
  cells_ = tets ? layout.tets.cols() : tris ? layout.triangles.cols() : nodes_;
  vectors_ = layout.nodeVectors.size();
  scalars_ = layout.cellScalars.size();

  // Named like writeFileAtomic's temporaries, so that a run killed mid-series leaves one that the
  // next run holding the folder removes.
  // The second number is this process's count of series, so that two writers of one name in one
  // thread (two exporters with the same filename) never share a temporary.
  static std::atomic<unsigned> series{0};
  temporary_ = path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(series++ % 1000000);
  std::lock_guard<std::mutex> lock(libraryLock());
  quiet();
  int computeWordSize = 8, ioWordSize = layout.float32 ? 4 : 8;
  file_ = ex_create(temporary_.c_str(), EX_CLOBBER | EX_NETCDF4 | EX_NOSHARE, &computeWordSize, &ioWordSize);
  if (file_ < 0) fail(path, "cannot create the Exodus series' temporary " + temporary_);
  try {
    check(ex_set_option(file_, EX_OPT_COMPRESSION_LEVEL, layout.compressionLevel), path, "compression");
    check(ex_set_option(file_, EX_OPT_COMPRESSION_SHUFFLE, 1), path, "byte shuffle");
    check(ex_put_init(file_, "Viscera", 3, nodes_, cells_, 1, 0, 0), path, "sizes");
    // Coordinates as three arrays, one per axis.
    Eigen::VectorXd c[3];
    for (int k = 0; k < 3; ++k) c[k] = layout.rest.row(k).transpose();
    check(ex_put_coord(file_, c[0].data(), c[1].data(), c[2].data()), path, "coordinates");
    char xyz[3][2] = {"x", "y", "z"};
    char* axes[3] = {xyz[0], xyz[1], xyz[2]};
    check(ex_put_coord_names(file_, axes), path, "axis names");
    // One block of cells; node numbers are 1-based.
    std::vector<int> conn;
    const char* type = tets ? "TETRA4" : tris ? "TRI3" : "SPHERE";
    const int per = tets ? 4 : tris ? 3 : 1;
    conn.reserve(static_cast<size_t>(cells_) * per);
    for (long e = 0; e < cells_; ++e)
      for (int k = 0; k < per; ++k)
        conn.push_back(1 + (tets ? layout.tets(k, e) : tris ? layout.triangles(k, e) : static_cast<int>(e)));
    for (int v : conn)
      if (v < 1 || v > nodes_) throw Error(SourceLoc{path}, "cannot write the Exodus series: a cell names node " +
                                                                std::to_string(v - 1) + " of " + std::to_string(nodes_));
    check(ex_put_block(file_, EX_ELEM_BLOCK, 1, type, cells_, per, 0, 0, 0), path, "cell block");
    check(ex_put_conn(file_, EX_ELEM_BLOCK, 1, conn.data(), nullptr, nullptr), path, "connectivity");
    // Vector fields as name_x, name_y, name_z: ParaView and VTK join them into one vector.
    std::vector<std::string> nodeNames;
    for (const auto& n : layout.nodeVectors)
      for (const char* axis : {"_x", "_y", "_z"}) nodeNames.push_back(n + axis);
    if (!nodeNames.empty()) defineVariables(file_, true, nodeNames, layout, path);
    if (scalars_ > 0) defineVariables(file_, false, layout.cellScalars, layout, path);
  } catch (...) {
    close();
    std::remove(temporary_.c_str());
    throw;
  }
}

ExodusWriter::~ExodusWriter() {
  if (file_ < 0) return;
  std::lock_guard<std::mutex> lock(libraryLock());
  close();
  std::remove(temporary_.c_str());
}

void ExodusWriter::close() {
  if (file_ >= 0) ex_close(file_);
  file_ = -1;
}

void ExodusWriter::append(double time, const std::vector<Eigen::Matrix3Xd>& nodeVectors,
                          const std::vector<Eigen::VectorXd>& cellScalars) {
  if (file_ < 0) throw Error(SourceLoc{path_}, "the Exodus series is already finished");
  if (nodeVectors.size() != vectors_ || cellScalars.size() != scalars_)
    throw Error(SourceLoc{path_}, "an Exodus frame has other fields than the series");
  for (const auto& v : nodeVectors)
    if (v.cols() != nodes_) throw Error(SourceLoc{path_}, "an Exodus frame's node field has the wrong size");
  for (const auto& s : cellScalars)
    if (s.size() != cells_) throw Error(SourceLoc{path_}, "an Exodus frame's cell field has the wrong size");
  std::lock_guard<std::mutex> lock(libraryLock());
  const int step = frames_ + 1;  // Exodus counts steps from 1
  check(ex_put_time(file_, step, &time), path_, "time");
  Eigen::VectorXd column(nodes_);
  for (size_t i = 0; i < nodeVectors.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      column = nodeVectors[i].row(k).transpose();
      check(ex_put_var(file_, step, EX_NODAL, static_cast<int>(3 * i + k + 1), 1, nodes_, column.data()), path_, "node field");
    }
  for (size_t i = 0; i < cellScalars.size(); ++i)
    check(ex_put_var(file_, step, EX_ELEM_BLOCK, static_cast<int>(i + 1), 1, cells_, cellScalars[i].data()), path_,
          "cell field");
  ++frames_;
}

void ExodusWriter::finish() {
  if (file_ < 0) return;
  std::lock_guard<std::mutex> lock(libraryLock());
  const int rc = ex_close(file_);
  file_ = -1;
  if (rc < 0) {
    std::remove(temporary_.c_str());
    fail(path_, "cannot write the Exodus series (closing it)");
  }
  struct stat st {};
  if (::lstat(path_.c_str(), &st) == 0 && (S_ISLNK(st.st_mode) || !S_ISREG(st.st_mode))) {
    std::remove(temporary_.c_str());
    throw Error(SourceLoc{path_}, "cannot write the Exodus series: the path is no longer a regular file");
  }
  if (std::rename(temporary_.c_str(), path_.c_str()) != 0) {
    const int err = errno;
    std::remove(temporary_.c_str());
    throw Error(SourceLoc{path_}, std::string("cannot put the Exodus series in place: ") + std::strerror(err));
  }
}

// ---------------------------------------------------------------------------------------------

namespace {
// What the file says that cannot be read as a series (no library error involved).
[[noreturn]] void badFile(const std::string& path, const std::string& what) {
  throw Error(SourceLoc{path}, "cannot read the Exodus file: " + what);
}
// A library call that failed, with the library's own message.
[[noreturn]] void failRead(const std::string& path, const std::string& what) {
  const char *msg = nullptr, *func = nullptr;
  int code = 0;
  ex_get_err(&msg, &func, &code);
  throw Error(SourceLoc{path}, "cannot read the Exodus file: " + what + (msg && *msg ? std::string(" (") + msg + ")" : ""));
}

std::vector<std::string> variableNames(int file, ex_entity_type type, const std::string& path) {
  int n = 0;
  if (ex_get_variable_param(file, type, &n) < 0) failRead(path, "its field list");
  std::vector<std::string> out;
  if (n <= 0) return out;
  std::vector<std::vector<char>> buf(static_cast<size_t>(n), std::vector<char>(MAX_STR_LENGTH + 1, '\0'));
  std::vector<char*> ptrs;
  for (auto& b : buf) ptrs.push_back(b.data());
  if (ex_get_variable_names(file, type, n, ptrs.data()) < 0) failRead(path, "its field names");
  for (auto& b : buf) out.emplace_back(b.data());
  return out;
}
}  // namespace

ExodusReader::ExodusReader(const std::string& path) : path_(path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw Error(SourceLoc{path}, std::string("cannot open the Exodus file: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw Error(SourceLoc{path}, "cannot open the Exodus file: it is not a regular file");
  std::lock_guard<std::mutex> lock(libraryLock());
  quiet();
  int computeWordSize = 8, ioWordSize = 0;
  float version = 0;
  file_ = ex_open(path.c_str(), EX_READ, &computeWordSize, &ioWordSize, &version);
  if (file_ < 0) failRead(path, "not an Exodus II / netCDF file");
  try {
    char title[MAX_LINE_LENGTH + 1] = {};
    int64_t dim = 0, nodes = 0, elems = 0, blocks = 0, nsets = 0, ssets = 0;
    ex_set_int64_status(file_, EX_ALL_INT64_API);
    if (ex_get_init(file_, title, &dim, &nodes, &elems, &blocks, &nsets, &ssets) < 0) failRead(path, "its sizes");
    if (dim != 3) badFile(path, "it has " + std::to_string(dim) + " dimensions, 3 expected");
    if (blocks != 1) badFile(path, "it has " + std::to_string(blocks) + " cell blocks, 1 expected (as Viscera writes it)");
    if (nodes <= 0 || nodes > 10'000'000) badFile(path, "its node count " + std::to_string(nodes) + " is out of range");
    Eigen::VectorXd c[3];
    for (auto& v : c) v.resize(nodes);
    if (ex_get_coord(file_, c[0].data(), c[1].data(), c[2].data()) < 0) failRead(path, "its coordinates");
    mesh_.points.resize(3, nodes);
    for (int k = 0; k < 3; ++k) mesh_.points.row(k) = c[k].transpose();
    int64_t id = 0;
    if (ex_get_ids(file_, EX_ELEM_BLOCK, &id) < 0) failRead(path, "its cell block");
    blockId_ = static_cast<long>(id);
    char type[MAX_STR_LENGTH + 1] = {};
    int64_t count = 0, per = 0, edges = 0, faces = 0, attrs = 0;
    if (ex_get_block(file_, EX_ELEM_BLOCK, id, type, &count, &per, &edges, &faces, &attrs) < 0) failRead(path, "its cell block");
    if (count < 0 || per < 1 || per > 8 || count * per > 100'000'000)
      badFile(path, "its cell block has " + std::to_string(count) + " cells of " + std::to_string(per) + " nodes");
    std::vector<int64_t> conn(static_cast<size_t>(count * per));
    if (count > 0 && ex_get_conn(file_, EX_ELEM_BLOCK, id, conn.data(), nullptr, nullptr) < 0) failRead(path, "its connectivity");
    for (int64_t v : conn)
      if (v < 1 || v > nodes) badFile(path, "a cell names node " + std::to_string(v) + " of " + std::to_string(nodes));
    const std::string t = type;
    if (t.rfind("TET", 0) == 0 && per == 4) {
      mesh_.tets.resize(4, count);
      for (int64_t e = 0; e < count; ++e)
        for (int k = 0; k < 4; ++k) mesh_.tets(k, e) = static_cast<int>(conn[e * 4 + k] - 1);
    } else if (t.rfind("TRI", 0) == 0 && per == 3) {
      mesh_.triangles.resize(3, count);
      for (int64_t e = 0; e < count; ++e)
        for (int k = 0; k < 3; ++k) mesh_.triangles(k, e) = static_cast<int>(conn[e * 3 + k] - 1);
    } else if (!(t.rfind("SPHERE", 0) == 0 && per == 1)) {
      badFile(path, "its cells are " + t + " with " + std::to_string(per) + " nodes (tetrahedra, triangles or points expected)");
    }
    const int64_t steps = ex_inquire_int(file_, EX_INQ_TIME);
    if (steps < 0) failRead(path, "its number of frames");
    if (steps > 100'000'000) badFile(path, "it claims " + std::to_string(steps) + " frames");
    times_.resize(static_cast<size_t>(steps));
    if (steps > 0 && ex_get_all_times(file_, times_.data()) < 0) failRead(path, "its times");
    for (size_t i = 0; i < times_.size(); ++i)
      // Equal times are accepted: Float32 times of a long run with a fine step may round together.
      if (!std::isfinite(times_[i]) || (i > 0 && times_[i] < times_[i - 1]))
        badFile(path, "frame " + std::to_string(i) + "'s time " + std::to_string(times_[i]) +
                          " is not finite or goes back");
    nodeVars_ = variableNames(file_, EX_NODAL, path);
    cellVars_ = variableNames(file_, EX_ELEM_BLOCK, path);
  } catch (...) {
    ex_close(file_);
    file_ = -1;
    throw;
  }
}

ExodusReader::~ExodusReader() {
  if (file_ < 0) return;
  std::lock_guard<std::mutex> lock(libraryLock());
  ex_close(file_);
}

Eigen::VectorXd ExodusReader::nodeVariable(int frame, const std::string& name) const {
  const auto it = std::find(nodeVars_.begin(), nodeVars_.end(), name);
  if (it == nodeVars_.end()) throw Error(SourceLoc{path_}, "the Exodus file has no node field '" + name + "'");
  if (frame < 0 || frame >= static_cast<int>(times_.size()))
    throw Error(SourceLoc{path_}, "the Exodus file has no frame " + std::to_string(frame));
  Eigen::VectorXd v(mesh_.points.cols());
  std::lock_guard<std::mutex> lock(libraryLock());
  if (ex_get_var(file_, frame + 1, EX_NODAL, static_cast<int>(it - nodeVars_.begin()) + 1, 1, v.size(), v.data()) < 0)
    failRead(path_, "node field '" + name + "' of frame " + std::to_string(frame));
  return v;
}

Eigen::VectorXd ExodusReader::cellVariable(int frame, const std::string& name) const {
  const auto it = std::find(cellVars_.begin(), cellVars_.end(), name);
  if (it == cellVars_.end()) throw Error(SourceLoc{path_}, "the Exodus file has no cell field '" + name + "'");
  if (frame < 0 || frame >= static_cast<int>(times_.size()))
    throw Error(SourceLoc{path_}, "the Exodus file has no frame " + std::to_string(frame));
  const long cells = mesh_.tets.cols() > 0 ? mesh_.tets.cols() : mesh_.triangles.cols() > 0 ? mesh_.triangles.cols() : mesh_.points.cols();
  Eigen::VectorXd v(cells);
  std::lock_guard<std::mutex> lock(libraryLock());
  if (ex_get_var(file_, frame + 1, EX_ELEM_BLOCK, static_cast<int>(it - cellVars_.begin()) + 1, blockId_, cells, v.data()) < 0)
    failRead(path_, "cell field '" + name + "' of frame " + std::to_string(frame));
  return v;
}

Eigen::Matrix3Xd ExodusReader::positions(int frame) const {
  Eigen::Matrix3Xd x = mesh_.points;
  if (std::find(nodeVars_.begin(), nodeVars_.end(), "displacement_x") == nodeVars_.end()) return x;
  const char* axes[3] = {"displacement_x", "displacement_y", "displacement_z"};
  for (int k = 0; k < 3; ++k) x.row(k) += nodeVariable(frame, axes[k]).transpose();
  return x;
}

}  // namespace viscera::io
