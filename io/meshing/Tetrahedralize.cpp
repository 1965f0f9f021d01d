// Tetrahedralization through the TetGen program: the surface goes to a temporary folder as a
// .smesh file, TetGen runs as a child process with its output captured, and its .node/.ele files
// come back as a VolumeMesh.
#include "io/meshing/Tetrahedralize.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>
#include <thread>
#include <unordered_map>
#include <vector>

#include "core/Error.h"

extern char** environ;

namespace viscera::io {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const std::string& source, const std::string& what) { throw Error(SourceLoc{source}, what); }

// A fresh folder under the system temporary folder, removed with its contents when this goes away
// (also when meshing fails).
class TempFolder {
 public:
  TempFolder() {
    std::string pattern = (fs::temp_directory_path() / "viscera-tetgen-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw Error(std::string("cannot create a temporary folder for TetGen: ") + std::strerror(errno));
    path_ = pattern;
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  std::string path() const { return path_.string(); }

 private:
  fs::path path_;
};

struct ProcessResult {
  int exitCode = -1;  // when it exited
  int signal = 0;     // when a signal ended it
  bool timedOut = false;
};

// Runs `args` (args[0] looked up on PATH unless it has a '/') in the folder `workDir` (where a
// crashing program leaves its core file, if any), with stdin from /dev/null and stdout and stderr
// both into `logPath`. Throws for a program that cannot be started.
ProcessResult runProgram(const std::vector<std::string>& args, const std::string& workDir, const std::string& logPath,
                         double timeoutSeconds, const std::string& source) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addchdir_np(&actions, workDir.c_str());
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, logPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int err = ::posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (err == ENOENT)
    fail(source, "the TetGen program '" + args[0] + "' was not found" + (args[0].find('/') == std::string::npos ? " on PATH" : "") +
                     ": install the Debian package tetgen (apt-get install tetgen) or name the program to use");
  if (err != 0) fail(source, "cannot run the TetGen program '" + args[0] + "': " + std::strerror(err));

  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeoutSeconds));
  ProcessResult r;
  int status = 0;
  for (;;) {
    const pid_t done = ::waitpid(pid, &status, timeoutSeconds > 0 ? WNOHANG : 0);
    if (done == pid) break;
    if (done < 0 && errno != EINTR) fail(source, std::string("lost the TetGen process: ") + std::strerror(errno));
    if (timeoutSeconds > 0 && Clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {}
      r.timedOut = true;
      return r;
    }
    if (timeoutSeconds > 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (WIFEXITED(status)) r.exitCode = WEXITSTATUS(status);
  else if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  return r;
}

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The data lines of a TetGen file: '#' starts a comment, blank lines are skipped.
std::vector<std::string> dataLines(const std::string& path, const std::string& source) {
  std::ifstream in(path);
  if (!in) fail(source, "TetGen finished but did not write " + fs::path(path).filename().string());
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    if (line.find_first_not_of(" \t\r") != std::string::npos) lines.push_back(line);
  }
  return lines;
}

// Reads `count` numbers of a TetGen data line, failing with the file name and line otherwise.
template <typename T>
void parseNumbers(const std::string& line, T* out, int count, const std::string& file, size_t lineIndex, const std::string& source) {
  std::istringstream in(line);
  for (int k = 0; k < count; ++k)
    if (!(in >> out[k]))
      fail(source, "cannot read TetGen's " + fs::path(file).filename().string() + " (data line " + std::to_string(lineIndex + 1) + ")");
}

// TetGen's output: .node (points with ids) and .ele (tetrahedra by node id).
VolumeMesh readTetGenOutput(const std::string& nodePath, const std::string& elePath, const std::string& source) {
  const auto nodes = dataLines(nodePath, source);
  long long header[2];
  if (nodes.empty()) fail(source, "TetGen's .node file is empty");
  parseNumbers(nodes[0], header, 2, nodePath, 0, source);
  if (header[1] != 3 || header[0] < 0 || static_cast<size_t>(header[0]) + 1 > nodes.size())
    fail(source, "TetGen's .node file does not hold " + std::to_string(header[0]) + " three-dimensional points");
  VolumeMesh mesh;
  mesh.points.resize(3, header[0]);
  std::unordered_map<long long, int> column;  // TetGen node id -> column of mesh.points
  for (long long i = 0; i < header[0]; ++i) {
    double v[4];
    parseNumbers(nodes[static_cast<size_t>(i) + 1], v, 4, nodePath, static_cast<size_t>(i) + 1, source);
    column[static_cast<long long>(v[0])] = static_cast<int>(i);
    mesh.points.col(i) = Eigen::Vector3d(v[1], v[2], v[3]);
  }
  const auto eles = dataLines(elePath, source);
  if (eles.empty()) fail(source, "TetGen's .ele file is empty");
  parseNumbers(eles[0], header, 2, elePath, 0, source);
  if (header[1] != 4 || header[0] < 0 || static_cast<size_t>(header[0]) + 1 > eles.size())
    fail(source, "TetGen's .ele file does not hold " + std::to_string(header[0]) + " four-node tetrahedra");
  mesh.tets.resize(4, header[0]);
  for (long long e = 0; e < header[0]; ++e) {
    long long v[5];
    parseNumbers(eles[static_cast<size_t>(e) + 1], v, 5, elePath, static_cast<size_t>(e) + 1, source);
    for (int k = 0; k < 4; ++k) {
      const auto it = column.find(v[k + 1]);
      if (it == column.end())
        fail(source,
             "TetGen's tetrahedron " + std::to_string(v[0]) + " refers to node " + std::to_string(v[k + 1]) + ", which it did not write");
      mesh.tets(k, e) = it->second;
    }
  }
  return mesh;
}

// Keeps only the nodes that tetrahedra use (TetGen can leave input points unused, e.g. duplicates;
// a node without elements would be a free node in the FEM), in their order.
void dropUnusedNodes(VolumeMesh& mesh) {
  std::vector<int> newIndex(static_cast<size_t>(mesh.points.cols()), -1);
  for (Eigen::Index e = 0; e < mesh.tets.cols(); ++e)
    for (int k = 0; k < 4; ++k) newIndex[static_cast<size_t>(mesh.tets(k, e))] = 0;
  int count = 0;
  for (int& n : newIndex)
    if (n == 0) n = count++;
  if (count == mesh.points.cols()) return;
  Eigen::Matrix3Xd points(3, count);
  for (Eigen::Index i = 0; i < mesh.points.cols(); ++i)
    if (newIndex[static_cast<size_t>(i)] >= 0) points.col(newIndex[static_cast<size_t>(i)]) = mesh.points.col(i);
  for (Eigen::Index e = 0; e < mesh.tets.cols(); ++e)
    for (int k = 0; k < 4; ++k) mesh.tets(k, e) = newIndex[static_cast<size_t>(mesh.tets(k, e))];
  mesh.points = std::move(points);
}

// TetGen's -d run lists crossing triangles as "(a, b, c) and (d, e, f)", by vertex index of its
// input. Returns the number of pairs and the first pair, or 0 when there are none.
int selfIntersections(const std::string& log, std::array<int, 6>& first) {
  int pairs = 0;
  std::istringstream in(log);
  for (std::string line; std::getline(in, line);) {
    if (line.find(") and (") == std::string::npos) continue;
    std::string digits = line;
    for (char& ch : digits)
      if (!std::isdigit(static_cast<unsigned char>(ch))) ch = ' ';
    std::istringstream numbers(digits);
    std::array<int, 6> pair{};
    bool ok = true;
    for (int& v : pair) ok = ok && static_cast<bool>(numbers >> v);
    if (!ok) continue;
    if (pairs++ == 0) first = pair;
  }
  return pairs;
}

// The last lines of a program's output, for a message.
std::string tail(const std::string& text, size_t maxChars = 600) {
  std::string t = text;
  while (!t.empty() && std::isspace(static_cast<unsigned char>(t.back()))) t.pop_back();
  if (t.size() > maxChars) t = "..." + t.substr(t.size() - maxChars);
  std::replace(t.begin(), t.end(), '\n', ' ');
  return t;
}

// A number for TetGen's command line (all digits) or for a message (six significant ones).
std::string number(double v, int digits = 17) {
  std::ostringstream s;
  s.precision(digits);
  s << v;
  return s.str();
}

std::string shortNumber(double v) { return number(v, 6); }

void checkOptions(const TetOptions& o, const std::string& source) {
  if (!std::isfinite(o.radiusEdgeRatio) || (o.radiusEdgeRatio != 0 && o.radiusEdgeRatio < 1.1))
    fail(source, "radius-edge ratio " + shortNumber(o.radiusEdgeRatio) +
                     " is not usable: give 0 (no quality refinement) or a bound of at least 1.1 (below that TetGen may not terminate)");
  if (!std::isfinite(o.minDihedral) || o.minDihedral < 0 || o.minDihedral > 18)
    fail(source,
         "minimum dihedral angle " + shortNumber(o.minDihedral) + " is out of range [0, 18] degrees (above 18 TetGen may not terminate)");
  if (o.minDihedral > 0 && o.radiusEdgeRatio == 0)
    fail(source, "a minimum dihedral angle needs quality refinement: give a radius-edge ratio too");
  if (!std::isfinite(o.maxVolume) || o.maxVolume < 0)
    fail(source, "maximum tetrahedron volume " + shortNumber(o.maxVolume) + " must be >= 0");
  if (!std::isfinite(o.timeoutSeconds) || o.timeoutSeconds < 0) fail(source, "TetGen time limit must be >= 0 seconds");
  if (o.tetgenProgram.empty()) fail(source, "no TetGen program given");
}

}  // namespace

VolumeMesh tetrahedralize(const SurfaceMesh& surface, const TetOptions& options, const std::string& source) {
  checkOptions(options, source);
  requireClosedSurface(surface, source);

  // TetGen's input: the vertices that triangles use, numbered from 0 (inputIndex maps back).
  std::vector<int> smeshIndex(static_cast<size_t>(surface.points.cols()), -1), inputIndex;
  for (Eigen::Index t = 0; t < surface.triangles.cols(); ++t)
    for (int k = 0; k < 3; ++k) {
      int& i = smeshIndex[static_cast<size_t>(surface.triangles(k, t))];
      if (i < 0) {
        i = static_cast<int>(inputIndex.size());
        inputIndex.push_back(surface.triangles(k, t));
      }
    }
  TempFolder folder;
  const std::string input = folder / "surface.smesh";
  {
    std::ostringstream s;
    s.precision(17);
    s << "# part 1: nodes (index x y z)\n" << inputIndex.size() << " 3 0 0\n";
    for (size_t i = 0; i < inputIndex.size(); ++i) {
      const auto p = surface.points.col(inputIndex[i]);
      s << i << " " << p.x() << " " << p.y() << " " << p.z() << "\n";
    }
    s << "# part 2: facets, one triangle each\n" << surface.triangles.cols() << " 0\n";
    for (Eigen::Index t = 0; t < surface.triangles.cols(); ++t)
      s << "3 " << smeshIndex[static_cast<size_t>(surface.triangles(0, t))] << " "
        << smeshIndex[static_cast<size_t>(surface.triangles(1, t))] << " " << smeshIndex[static_cast<size_t>(surface.triangles(2, t))]
        << "\n";
    s << "# part 3: holes\n0\n# part 4: regions\n0\n";
    std::ofstream out(input);
    out << s.str();
    if (!out.flush()) fail(source, "cannot write TetGen's input file in the temporary folder");
  }

  std::vector<std::string> args = {options.tetgenProgram, "-p", "-z", "-Q"};
  if (options.radiusEdgeRatio > 0)
    args.push_back("-q" + number(options.radiusEdgeRatio) + (options.minDihedral > 0 ? "/" + number(options.minDihedral) : ""));
  if (options.maxVolume > 0) args.push_back("-a" + number(options.maxVolume));
  if (options.keepSurface) args.push_back("-Y");
  args.push_back(input);
  const std::string log = folder / "tetgen.log";
  const ProcessResult run = runProgram(args, folder.path(), log, options.timeoutSeconds, source);
  if (run.timedOut)
    fail(source, "TetGen did not finish within " + shortNumber(options.timeoutSeconds) +
                     " s (a tighter quality bound or a smaller maximum volume asks for more tetrahedra)");
  if (run.exitCode != 0) {
    const std::string said = tail(readText(log));
    // TetGen 1.5 aborts without a word under -Q; its self-intersection check (-d) says why.
    const std::string checkLog = folder / "tetgen-check.log";
    const ProcessResult check =
        runProgram({options.tetgenProgram, "-p", "-z", "-d", input}, folder.path(), checkLog, options.timeoutSeconds, source);
    std::array<int, 6> pair{};
    const int pairs = check.exitCode == 0 ? selfIntersections(readText(checkLog), pair) : 0;
    if (pairs > 0) {
      auto triangle = [&](int first) {
        std::string t = "(";
        for (int k = 0; k < 3; ++k) {
          const int v = pair[static_cast<size_t>(first + k)];
          t += (k ? ", " : "") +
               std::to_string(v >= 0 && static_cast<size_t>(v) < inputIndex.size() ? inputIndex[static_cast<size_t>(v)] : v);
        }
        return t + ")";
      };
      fail(source, "TetGen cannot mesh the surface: it intersects itself (" + std::to_string(pairs) +
                       " crossing pairs of triangles), e.g. the triangles with vertices " + triangle(0) + " and " + triangle(3) +
                       " (numbered from 0)");
    }
    fail(source, "TetGen failed (" +
                     (run.signal ? "ended by signal " + std::to_string(run.signal) + ", " + ::strsignal(run.signal)
                                 : "exit code " + std::to_string(run.exitCode)) +
                     ")" + (said.empty() ? std::string() : ": " + said));
  }

  VolumeMesh mesh = readTetGenOutput(folder / "surface.1.node", folder / "surface.1.ele", source);
  dropUnusedNodes(mesh);
  const std::string what = source + " (TetGen's mesh)";
  if (checkTetMesh(mesh, what) < 0) mesh.tets.row(2).swap(mesh.tets.row(3));
  mesh.triangles = boundaryTriangles(mesh.tets, mesh.points);
  return mesh;
}

TetQuality measureTetMesh(const VolumeMesh& mesh) {
  TetQuality q;
  q.nodes = mesh.points.cols();
  q.tetrahedra = mesh.tets.cols();
  q.triangles = mesh.triangles.cols();
  if (q.tetrahedra == 0) return q;
  constexpr double kDegrees = 180.0 / 3.14159265358979323846;
  q.minVolume = q.minDihedral = std::numeric_limits<double>::infinity();
  for (Eigen::Index e = 0; e < mesh.tets.cols(); ++e) {
    Eigen::Vector3d p[4];
    for (int k = 0; k < 4; ++k) p[k] = mesh.points.col(mesh.tets(k, e));
    const Eigen::Vector3d a = p[1] - p[0], b = p[2] - p[0], c = p[3] - p[0];
    const double det = a.dot(b.cross(c));
    const double volume = std::abs(det) / 6.0;
    q.volume += volume;
    q.minVolume = std::min(q.minVolume, volume);
    q.maxVolume = std::max(q.maxVolume, volume);
    // Circumcentre relative to p0: (|a|^2 b x c + |b|^2 c x a + |c|^2 a x b) / (2 a . (b x c)).
    const double radius =
        (a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) + c.squaredNorm() * a.cross(b)).norm() / (2 * std::abs(det));
    double shortest = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) shortest = std::min(shortest, (p[i] - p[j]).norm());
    const double ratio = radius / shortest;
    q.maxRadiusEdgeRatio = std::max(q.maxRadiusEdgeRatio, ratio);
    q.meanRadiusEdgeRatio += ratio;
    // Outward normal of the face opposite each node; the dihedral angle at the edge shared by the
    // faces opposite nodes i and j is pi minus the angle between their normals.
    Eigen::Vector3d normal[4];
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d &u = p[(k + 1) % 4], &v = p[(k + 2) % 4], &w = p[(k + 3) % 4];
      normal[k] = (v - u).cross(w - u);
      if (normal[k].dot(p[k] - u) > 0) normal[k] = -normal[k];
    }
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        const double between = std::atan2(normal[i].cross(normal[j]).norm(), normal[i].dot(normal[j]));
        const double dihedral = (3.14159265358979323846 - between) * kDegrees;
        q.minDihedral = std::min(q.minDihedral, dihedral);
        q.maxDihedral = std::max(q.maxDihedral, dihedral);
      }
  }
  q.meanVolume = q.volume / static_cast<double>(q.tetrahedra);
  q.meanRadiusEdgeRatio /= static_cast<double>(q.tetrahedra);
  return q;
}

}  // namespace viscera::io
