#include "study/SofaSuite.h"

#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <regex>
#include <sstream>
#include <unistd.h>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "engine/Run.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"

namespace viscera::study {

namespace fs = std::filesystem;

namespace {

std::vector<std::string> splitWords(const std::string& line) {
  std::vector<std::string> w;
  std::istringstream in(line);
  for (std::string s; in >> s;) w.push_back(s);
  return w;
}

// A gzip file's text (plain text passes through zlib unchanged).
std::string readMaybeGzip(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw Error(SourceLoc{path}, "cannot open the file");
  std::string text;
  char buf[1 << 16];
  int n = 0;
  while ((n = gzread(f, buf, sizeof buf)) > 0) {
    text.append(buf, static_cast<size_t>(n));
    if (text.size() > kMaxInputBytes) {
      gzclose(f);
      throw Error(SourceLoc{path}, "decompresses to more than " + std::to_string(kMaxInputBytes >> 20) + " MiB");
    }
  }
  int err = 0;
  const char* msg = gzerror(f, &err);
  const bool bad = n < 0 || (err != Z_OK && err != Z_STREAM_END);
  const std::string why = bad ? msg : "";
  gzclose(f);
  if (bad) throw Error(SourceLoc{path}, "corrupt gzip data: " + why);
  return text;
}

// "needs X" for the errors that mean a component or attribute is missing here.
bool missingPiece(const std::string& message, std::string& what) {
  static const std::regex component("unknown component '([^']+)'");
  static const std::regex attribute("([A-Za-z0-9_]+\\.[A-Za-z0-9_]+): unknown attribute");
  static const std::regex templ("([A-Za-z0-9_]+)\\.template: '([^']+)' is not");
  std::smatch m;
  if (std::regex_search(message, m, component)) what = m[1];
  else if (std::regex_search(message, m, attribute)) what = m[1];
  else if (std::regex_search(message, m, templ)) what = m[1].str() + "<" + m[2].str() + ">";
  else return false;
  return true;
}

void classifyError(const Error& e, SuiteResult& r) {
  std::string what;
  if (missingPiece(e.what(), what)) {
    r.status = SuiteResult::Status::Needs;
    r.detail = what;
  } else {
    r.status = SuiteResult::Status::Error;
    r.detail = e.what();
  }
}

// Where example scenes run: exporters and recorders in them write here, never beside the scene.
// The folder is removed when the process ends.
std::string scratchFolder() {
  struct Scratch {
    fs::path dir;
    Scratch() {
      std::error_code ec;
      dir = fs::temp_directory_path(ec) / ("viscera-sofa-suite-" + std::to_string(::getpid()));
      fs::create_directories(dir, ec);
    }
    ~Scratch() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  };
  static const Scratch scratch;
  return scratch.dir.string();
}

// A scene built from its file, with outputs sent to the scratch folder.
std::unique_ptr<Scene> loadScene(const std::string& path) {
  auto scene = buildScene(io::readScene(path));
  scene->setOutputDirectory(scratchFolder());
  return scene;
}

// The state vectors of a MechanicalObject (Vec3d) or RigidObject, as SOFA dumps them.
bool stateOf(const State& s, const Component& c, std::vector<double>& x, std::vector<double>& v) {
  if (const auto* mo = dynamic_cast<const MechanicalObject*>(&c)) {
    const Eigen::Matrix3Xd &mx = mo->x(s), &mv = mo->v(s);
    x.assign(mx.data(), mx.data() + mx.size());
    v.assign(mv.data(), mv.data() + mv.size());
    return true;
  }
  if (const auto* rigid = dynamic_cast<const RigidObject*>(&c)) {
    const RigidObject::Live& rb = rigid->live(s);
    x = {rb.p.x(), rb.p.y(), rb.p.z(), rb.q.x(), rb.q.y(), rb.q.z(), rb.q.w()};
    v = {rb.v.x(), rb.v.y(), rb.v.z(), rb.w.x(), rb.w.y(), rb.w.z()};
    return true;
  }
  return false;
}

struct DumpFile {
  int index = 0;
  std::string object, path;
};

// The reference files of `scene`, by dump index.
std::vector<DumpFile> referenceDumps(const std::string& referenceDir, const std::string& scene) {
  const fs::path base = fs::path(referenceDir) / scene;
  const std::string prefix = base.filename().string() + ".reference_";
  std::vector<DumpFile> out;
  std::error_code ec;
  if (!fs::is_directory(base.parent_path(), ec)) return out;
  for (const auto& e : fs::directory_iterator(base.parent_path(), ec)) {
    const std::string name = e.path().filename().string();
    const std::string suffix = "_mstate.txt.gz";
    if (name.rfind(prefix, 0) != 0 || name.size() < prefix.size() + suffix.size() ||
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
      continue;
    const std::string middle = name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
    const size_t us = middle.find('_');
    if (us == std::string::npos) continue;
    DumpFile d;
    long long index = 0;
    if (!parseInteger(middle.substr(0, us), index)) continue;
    d.index = static_cast<int>(index);
    d.object = middle.substr(us + 1);
    d.path = e.path().string();
    out.push_back(d);
  }
  std::sort(out.begin(), out.end(), [](const DumpFile& a, const DumpFile& b) { return a.index < b.index; });
  return out;
}

// Records the states of the compared objects at the reference times while the scene runs.
class StateRecorder : public RunObserver {
 public:
  StateRecorder(std::vector<const Component*> objects, std::vector<double> times)
      : objects_(std::move(objects)), times_(std::move(times)) {}
  void begin(const Simulation& sim, int) override { record(sim.state()); }
  void step(const Simulation& sim) override { record(sim.state()); }
  // Per time: per object, (x, v).
  std::map<double, std::vector<std::pair<std::vector<double>, std::vector<double>>>> states;

 private:
  void record(const State& s) {
    const double t = s.time;
    for (double want : times_)
      if (std::abs(want - t) <= 1e-9 * std::max(1.0, std::abs(want))) {
        auto& row = states[want];
        row.clear();
        for (const Component* c : objects_) {
          std::vector<double> x, v;
          stateOf(s, *c, x, v);
          row.emplace_back(std::move(x), std::move(v));
        }
      }
  }
  std::vector<const Component*> objects_;
  std::vector<double> times_;
};

// `v` printed with `digits` significant digits and read back.
double asPrinted(double v, int digits) {
  if (digits >= 17 || v == 0 || !std::isfinite(v)) return v;
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return std::strtod(buf, nullptr);
}

// The significant digits of a number as written ("-16.531" 5, "1.5e-07" 2, "0.00012" 2).
int significantDigits(const std::string& w) {
  int n = 0, trailingZeros = 0;
  bool leading = true;
  for (char c : w) {
    if (c == 'e' || c == 'E') break;
    if (c < '0' || c > '9') continue;
    if (leading && c == '0') continue;
    leading = false;
    ++n;
    trailingZeros = c == '0' ? trailingZeros + 1 : 0;
  }
  return n - trailingZeros;
}

// The mean |a - b| with a (our state) rounded as the reference b was printed, so that the figure
// measures the model, not the references' rounding (SOFA's six digits: up to 5e-5 on coordinates
// of 10 to 100).
double meanAbsDiff(const std::vector<double>& a, const std::vector<double>& b, int digits) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += std::abs(asPrinted(a[i], digits) - b[i]);
  return a.empty() ? 0.0 : s / static_cast<double>(a.size());
}

// SOFA's criterion for recorded states against per-object frames (the references, or another
// run's states), with the largest node distance; `problem` names a time the run does not reach
// or a size that differs.
struct Comparison {
  double error = 0, maxDistance = 0;
  int objects = 0;
  std::string problem;
};

Comparison compare(const std::vector<const Component*>& objects, const StateRecorder& recorder,
                   const std::vector<std::vector<ReferenceFrame>>& refs, bool lastOnly, const RunResult& run) {
  Comparison c;
  double total = 0;
  for (size_t o = 0; o < objects.size(); ++o) {
    double sum = 0;
    int compared = 0;
    for (const auto& f : refs[o]) {
      if (lastOnly && &f != &refs[o].back()) continue;
      auto it = recorder.states.end();
      for (auto s = recorder.states.begin(); s != recorder.states.end(); ++s)
        if (std::abs(s->first - f.t) <= 1e-9 * std::max(1.0, std::abs(f.t))) it = s;
      if (it == recorder.states.end()) {
        c.problem = "the reference has a state at t = " + formatNumber(f.t) + ", which the run (" + std::to_string(run.steps) +
                    " steps of " + formatNumber(run.dt) + ") does not reach";
        return c;
      }
      const auto& [x, v] = it->second[o];
      if (x.size() != f.x.size() || (!f.v.empty() && v.size() != f.v.size())) {
        c.problem = "'" + objects[o]->name() + "' has " + std::to_string(x.size()) + " position values here, " +
                    std::to_string(f.x.size()) + " in the reference";
        return c;
      }
      const int stride = dynamic_cast<const RigidObject*>(objects[o]) ? 7 : 3;
      const double nodes = std::max<double>(1.0, static_cast<double>(x.size() / stride));
      sum += (meanAbsDiff(x, f.x, f.digits) + (f.v.empty() ? 0.0 : meanAbsDiff(v, f.v, f.digits))) / nodes;
      for (size_t i = 0; i + 2 < x.size(); i += stride) {
        const double dx = x[i] - f.x[i], dy = x[i + 1] - f.x[i + 1], dz = x[i + 2] - f.x[i + 2];
        c.maxDistance = std::max(c.maxDistance, std::sqrt(dx * dx + dy * dy + dz * dz));
      }
      ++compared;
    }
    total += sum;
    c.objects += compared > 0;
  }
  c.error = c.objects ? total / c.objects : 0.0;
  return c;
}

// A run's recorded states as frames to compare another run with (at full precision).
std::vector<std::vector<ReferenceFrame>> recorded(const StateRecorder& recorder, size_t objects) {
  std::vector<std::vector<ReferenceFrame>> frames(objects);
  for (const auto& [t, row] : recorder.states)
    for (size_t o = 0; o < objects && o < row.size(); ++o) {
      ReferenceFrame f;
      f.t = t;
      f.x = row[o].first;
      f.v = row[o].second;
      frames[o].push_back(std::move(f));
    }
  return frames;
}

}  // namespace

const char* statusName(SuiteResult::Status s) {
  switch (s) {
    case SuiteResult::Status::Passed: return "passed";
    case SuiteResult::Status::Differs: return "differs";
    case SuiteResult::Status::Runs: return "runs";
    case SuiteResult::Status::Needs: return "needs";
    case SuiteResult::Status::Error: return "error";
    case SuiteResult::Status::Diverged: return "diverged";
    case SuiteResult::Status::NoReference: return "no reference";
  }
  return "?";
}

RegressionList readRegressionList(const std::string& path, const std::string& regressionDir) {
  RegressionList list;
  list.file = path;
  std::istringstream in(readInputFile(path, "the regression list"));
  std::string raw;
  int line = 0;
  for (; std::getline(in, raw); ++line) {
    const auto w = splitWords(raw);
    if (w.empty() || w[0][0] == '#') continue;
    const SourceLoc loc{path, line + 1};
    if (list.referenceDir.empty() && w.size() == 1) {
      std::string dir = w[0];
      const std::string var = "$REGRESSION_DIR";
      if (dir.rfind(var, 0) == 0) {
        std::string root = regressionDir;
        if (root.empty())
          if (const char* env = std::getenv("REGRESSION_DIR")) root = env;
        if (root.empty())
          root = (fs::absolute(fs::path(path)).lexically_normal().parent_path().parent_path() / "regression").string();
        dir = root + dir.substr(var.size());
      } else if (fs::path(dir).is_relative()) {
        dir = (fs::path(path).parent_path() / dir).string();
      }
      list.referenceDir = fs::path(dir).lexically_normal().string();
      continue;
    }
    if (w.size() != 5) throw Error(loc, "expected SCENE STEPS EPSILON MAPPED LAST_ONLY, got " + std::to_string(w.size()) + " words");
    RegressionEntry e;
    e.scene = w[0];
    e.line = line + 1;
    long long steps = 0, mapped = 0, lastOnly = 0;
    if (!parseInteger(w[1], steps) || steps < 0 || steps > 10'000'000) throw Error(loc, "STEPS must be a whole number from 0 to 10000000");
    if (!parseNumber(w[2], e.epsilon) || !(e.epsilon >= 0)) throw Error(loc, "EPSILON must be a non-negative number");
    if (!parseInteger(w[3], mapped) || !parseInteger(w[4], lastOnly)) throw Error(loc, "MAPPED and LAST_ONLY must be 0 or 1");
    e.steps = static_cast<int>(steps);
    e.mapped = mapped != 0;
    e.lastOnly = lastOnly != 0;
    list.entries.push_back(e);
  }
  if (list.referenceDir.empty()) throw Error(SourceLoc{path}, "no reference-folder line");
  return list;
}

std::vector<ReferenceFrame> readStateDump(const std::string& path) {
  std::istringstream in(readMaybeGzip(path));
  std::vector<ReferenceFrame> frames;
  std::string raw;
  int line = 0;
  int digits = 0;
  auto numbers = [&](std::istringstream& ls, std::vector<double>& out) {
    for (std::string w; ls >> w;) {
      double value = 0;
      if (!parseNumber(w, value)) throw Error(SourceLoc{path, line}, "'" + w.substr(0, 40) + "' is not a number");
      out.push_back(value);
      digits = std::max(digits, significantDigits(w));
    }
  };
  while (std::getline(in, raw)) {
    ++line;
    std::istringstream ls(raw);
    std::string key;
    if (!(ls >> key)) continue;
    if (key == "T=") {
      frames.emplace_back();
      std::vector<double> t;
      numbers(ls, t);
      if (t.size() != 1) throw Error(SourceLoc{path, line}, "T= needs one time");
      frames.back().t = t[0];
    } else if (key == "X=" || key == "V=" || key == "F=" || key == "X0=") {
      if (frames.empty()) throw Error(SourceLoc{path, line}, key + " before the first T=");
      // Forces and rest positions (WriteState's writeF, writeX0) are read, not compared.
      std::vector<double> unused;
      numbers(ls, key == "X=" ? frames.back().x : key == "V=" ? frames.back().v : unused);
    } else {
      throw Error(SourceLoc{path, line}, "expected T=, X=, V=, F= or X0=, got '" + key.substr(0, 20) + "'");
    }
  }
  if (frames.empty()) throw Error(SourceLoc{path}, "no T= block");
  // SOFA prints six digits; a dump whose values happen to be shorter is compared at six, one with
  // more at its own precision, and one at double precision (16 or 17 digits) unrounded.
  for (auto& f : frames) f.digits = digits <= 6 ? 6 : digits <= 15 ? digits : 17;
  return frames;
}

SuiteResult runRegressionScene(const RegressionList& list, const RegressionEntry& entry, const std::string& examplesDir,
                               int orderRuns) {
  SuiteResult r;
  r.scene = entry.scene;
  r.epsilon = entry.epsilon;
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const std::vector<DumpFile> dumps = referenceDumps(list.referenceDir, entry.scene);
  try {
    auto scene = loadScene((fs::path(examplesDir) / entry.scene).string());
    scene->init();  // the scene's own errors before its references'
    if (dumps.empty()) {
      r.status = SuiteResult::Status::NoReference;
      r.detail = "no " + entry.scene + ".reference_*_mstate.txt.gz in " + list.referenceDir;
      return r;
    }
    // The reference objects matched with this scene's, by name (SOFA names them in the file).
    std::vector<const Component*> objects;
    std::vector<std::vector<ReferenceFrame>> refs;
    // SOFA dumps its states in scene order and names an unnamed one after its type and a counter
    // ("MechanicalObject1"): a name not found here falls back to the dump's index in that order.
    // Mapped states are dumped (and counted) only when the list asks for them, and states no ODE
    // solver integrates (a fixed obstacle) never are.
    std::vector<const Component*> ours;
    auto integrated = [](const Component& c) {
      for (const Node* n = &c.node(); n; n = n->parent())
        if (n->find<OdeSolver>()) return true;
      return false;
    };
    for (auto* c : scene->all<Component>()) {
      const auto* mo = dynamic_cast<MechanicalObject*>(c);
      if ((mo && integrated(*c) && (entry.mapped || !mo->mappedBy())) || dynamic_cast<RigidObject*>(c)) ours.push_back(c);
    }
    auto taken = [&](const Component* c) { return std::find(objects.begin(), objects.end(), c) != objects.end(); };
    for (const auto& d : dumps) {
      const Component* match = nullptr;
      for (const Component* c : ours)
        if (c->name() == d.object && !taken(c)) {
          match = c;
          break;
        }
      if (!match && d.index >= 0 && d.index < static_cast<int>(ours.size()) && !taken(ours[d.index]))
        match = ours[d.index];
      if (!match) {
        r.status = SuiteResult::Status::Error;
        r.detail = "the reference dumps a MechanicalObject named '" + d.object + "', which this scene does not have";
        return r;
      }
      objects.push_back(match);
      refs.push_back(readStateDump(d.path));
    }
    // Compared times: the last dumped step, or every one.
    std::vector<double> times;
    for (const auto& f : refs.front())
      if (!entry.lastOnly || &f == &refs.front().back()) times.push_back(f.t);
    // One run from the start, the constraint solve visiting its constraints in an order drawn from
    // `seed` (0: as built).
    auto runOnce = [&](std::uint64_t seed, StateRecorder& recorder) {
      Simulation once(*scene);
      if (seed)
        for (const ConstraintSolver* solver : scene->all<ConstraintSolver>()) solver->shuffleOrder(once.state(), seed);
      RunOptions ro;
      ro.steps = entry.steps;
      ro.recordWrench = false;
      ro.observers.push_back(&recorder);
      return viscera::run(once, ro);
    };
    StateRecorder recorder(objects, times);
    const RunResult run = runOnce(0, recorder);
    r.steps = run.steps;
    if (run.failure) {
      r.status = SuiteResult::Status::Diverged;
      r.detail = run.failure->str();
      r.seconds = elapsed();
      return r;
    }
    const Comparison c = compare(objects, recorder, refs, entry.lastOnly, run);
    if (!c.problem.empty()) {
      r.status = SuiteResult::Status::Error;
      r.detail = c.problem;
      r.seconds = elapsed();
      return r;
    }
    r.sofaError = c.error;
    r.maxDistance = c.maxDistance;
    r.objects = c.objects;
    r.status = r.sofaError <= entry.epsilon ? SuiteResult::Status::Passed : SuiteResult::Status::Differs;
    // The same scene with its constraints in other orders, against SOFA and against this run.
    if (orderRuns > 0 && !scene->all<ConstraintSolver>().empty()) {
      const std::vector<std::vector<ReferenceFrame>> ours = recorded(recorder, objects.size());
      r.orderErrorMin = r.orderErrorMax = r.sofaError;
      for (int k = 1; k <= orderRuns; ++k) {
        StateRecorder again(objects, times);
        const RunResult other = runOnce(static_cast<std::uint64_t>(k), again);
        if (other.failure) {  // said beside the figures, which stand for the orders run
          r.detail = "in constraint order " + std::to_string(k) + " the run fails: " + other.failure->str();
          break;
        }
        const Comparison toSofa = compare(objects, again, refs, entry.lastOnly, other);
        const Comparison toThis = compare(objects, again, ours, entry.lastOnly, other);
        r.orderErrorMin = std::min(r.orderErrorMin, toSofa.error);
        r.orderErrorMax = std::max(r.orderErrorMax, toSofa.error);
        r.orderSpread = std::max(r.orderSpread, toThis.error);
        ++r.orderRuns;
      }
    }
  } catch (const Error& e) {
    classifyError(e, r);
  } catch (const std::exception& e) {  // one scene's fault must not end the suite
    r.status = SuiteResult::Status::Error;
    r.detail = std::string("internal error: ") + e.what();
  }
  r.seconds = elapsed();
  return r;
}

SuiteResult runExampleScene(const std::string& path, int steps) {
  SuiteResult r;
  r.scene = path;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    auto scene = loadScene(path);
    Simulation sim(*scene);
    RunOptions ro;
    ro.steps = steps;
    ro.recordWrench = false;
    const RunResult run = viscera::run(sim, ro);
    r.steps = run.steps;
    if (run.failure) {
      r.status = SuiteResult::Status::Diverged;
      r.detail = run.failure->str();
    } else {
      r.status = SuiteResult::Status::Runs;
    }
  } catch (const Error& e) {
    classifyError(e, r);
  } catch (const std::exception& e) {
    r.status = SuiteResult::Status::Error;
    r.detail = std::string("internal error: ") + e.what();
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

std::vector<std::string> exampleScenes(const std::string& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  static const std::regex groupRoot("^\\s*(<\\?xml[^>]*>\\s*)?(<!--[\\s\\S]*?-->\\s*)*<Node[^>]*name\\s*=\\s*\"Group\"");
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    const std::string ext = it->path().extension().string();
    if (ext != ".scn" && ext != ".xml") continue;
    std::string head;
    try {
      head = readInputFile(it->path().string()).substr(0, 4096);
    } catch (const Error&) {
    }
    if (std::regex_search(head, groupRoot)) continue;
    out.push_back(it->path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace viscera::study
