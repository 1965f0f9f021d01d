#include "study/Search.h"

#include <algorithm>
#include <atomic>
#include <boost/math/tools/minima.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <nlopt.hpp>
#include <set>
#include <sstream>
#include <thread>

#include "builtin/Builtins.h"
#include "core/Attributes.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Registry.h"
#include "core/Text.h"
#include "core/Units.h"

namespace viscera::study {

namespace fs = std::filesystem;

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == sep) {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

// Full precision, so that a value read back from results.csv is the value that was run.
std::string exact(double v) {
  if (std::isnan(v)) return "nan";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string key(const std::vector<double>& values) {
  std::string k;
  for (double v : values) k += exact(v) + ";";
  return k;
}

// The spec of the attribute an address names, and the scene's units.
const AttrSpec& attributeSpec(const SceneDesc& scene, const std::string& address, const std::string& option) {
  const auto [path, attr] = splitAddress(address);
  const ElementDesc& el = scene.element(path);
  const ComponentSpec* spec = el.tag == "Node" ? &Registry::nodeSpec() : builtinRegistry().find(el.tag);
  if (!spec) throw Error(el.loc, option + ": '" + el.tag + "' is not a known component");
  const AttrSpec* a = spec->find(attr);
  if (!a) throw Error(el.loc, option + ": " + spec->name + " has no attribute '" + attr + "'");
  if (a->kind != AttrKind::Real && a->kind != AttrKind::Reals)
    throw Error(el.loc, option + ": " + spec->name + "." + attr + " is not a real number, so it cannot be searched");
  return *a;
}

// "g mm^-1 s^-2": a dimension in the scene's base units.
std::string unitText(const Dimension& d, const UnitSystem& units) {
  std::istringstream names(units.str());
  std::string length, mass, time, out;
  names >> length >> mass >> time;
  for (const auto& [name, power] : {std::pair{mass, d.M}, std::pair{length, d.L}, std::pair{time, d.T}}) {
    if (power == 0) continue;
    if (!out.empty()) out += ' ';
    out += name;
    if (power == 1) continue;
    out += '^';
    out += std::to_string(power);
  }
  return out;
}

UnitSystem sceneUnits(const SceneDesc& scene) {
  const AttrDesc* u = scene.root.find("units");
  return u ? UnitSystem::parse(u->value) : UnitSystem();
}

std::vector<double> axisGrid(const ParamSpec& p, double a, double b, int n) {
  std::vector<double> v;
  const double ua = toAxis(p, a), ub = toAxis(p, b);
  for (int i = 0; i < n; ++i) v.push_back(fromAxis(p, n == 1 ? ua : ua + (ub - ua) * i / (n - 1)));
  // The ends exactly as given (log and back may round).
  v.front() = a;
  if (n > 1) v.back() = b;
  return v;
}

// Decades within [lo, hi] (and the ends when they are not decades); five values for a linear range.
std::vector<double> coarseValues(const ParamSpec& p) {
  if (p.scale == Scale::Linear) return axisGrid(p, p.lo, p.hi, 5);
  std::vector<double> v = {p.lo};
  for (int k = static_cast<int>(std::ceil(std::log10(p.lo) - 1e-9)); k <= static_cast<int>(std::floor(std::log10(p.hi) + 1e-9)); ++k) {
    const double d = std::pow(10.0, k);
    if (std::abs(std::log10(d / v.back())) > 1e-9 && d < p.hi * (1 - 1e-12)) v.push_back(d);
  }
  if (p.hi != v.back()) v.push_back(p.hi);
  return v;
}

std::vector<std::vector<double>> product(const std::vector<std::vector<double>>& axes) {
  std::vector<std::vector<double>> out = {{}};
  for (const auto& axis : axes) {
    std::vector<std::vector<double>> next;
    for (const auto& partial : out)
      for (double v : axis) {
        auto c = partial;
        c.push_back(v);
        next.push_back(std::move(c));
      }
    out = std::move(next);
  }
  return out;
}

// Sorted distinct values of parameter j among ok results, with the best metric at each.
std::vector<std::pair<double, double>> profile(const std::vector<CandidateResult>& rows, size_t j) {
  std::map<double, double> m;
  for (const auto& r : rows) {
    if (!r.ok() || !std::isfinite(r.metric)) continue;
    auto it = m.find(r.values[j]);
    if (it == m.end() || r.metric < it->second) m[r.values[j]] = r.metric;
  }
  return {m.begin(), m.end()};
}

const CandidateResult* bestOf(const std::vector<CandidateResult>& rows, const std::string& stage = "") {
  const CandidateResult* best = nullptr;
  for (const auto& r : rows)
    if (r.ok() && std::isfinite(r.metric) && (stage.empty() || r.stage == stage) && (!best || r.metric < best->metric))
      best = &r;
  return best;
}

// The neighbours of `v` among the values of `axis` (sorted): the values just below and above it,
// or v itself at an end.
std::pair<double, double> neighbours(const std::vector<double>& axis, double v) {
  auto it = std::lower_bound(axis.begin(), axis.end(), v);
  const size_t i = static_cast<size_t>(it - axis.begin());
  const double a = i > 0 ? axis[i - 1] : axis.front();
  const double b = (i + 1 < axis.size()) ? axis[i + 1] : axis.back();
  return {a, b};
}

CandidateResult fromScore(const std::string& stage, const std::vector<double>& values, const ReplayScore& s) {
  CandidateResult r;
  r.stage = stage;
  r.values = values;
  r.status = s.status;
  r.reason = s.reason;
  r.metric = s.metric;
  r.metricSe = s.metricSe;
  r.cloudTerm = s.cloudTerm;
  r.forceTerm = s.forceTerm;
  r.cloudRms = s.cloudRms;
  r.cloudRmsContact = s.cloudRmsContact;
  r.cloudRmsFree = s.cloudRmsFree;
  r.forceRms = s.forceRms;
  r.forceRmsContact = s.forceRmsContact;
  r.forceRmsFree = s.forceRmsFree;
  int frames = 0;
  for (const auto& f : s.frames) frames += std::isfinite(f.value);
  r.frames = frames;
  r.samples = static_cast<int>(s.samples.size());
  r.steps = s.steps;
  r.wallSeconds = s.wallSeconds;
  return r;
}

const std::vector<std::string> kColumns = {
    "status", "metric", "metric_se", "cloud_term", "force_term", "cloud_rms", "cloud_rms_contact", "cloud_rms_free",
    "force_rms", "force_rms_contact", "force_rms_free", "frames", "samples", "steps", "wall_s", "reason"};

// A reason in one CSV field: commas and line breaks replaced.
std::string field(std::string s) {
  for (char& c : s)
    if (c == ',' || c == '\n' || c == '\r') c = c == ',' ? ';' : ' ';
  return s;
}

// Candidates on `jobs` threads of this process, each run in its own arena.
class ThreadExecutor : public CandidateExecutor {
 public:
  explicit ThreadExecutor(int jobs) : jobs_(jobs) {}
  void run(const std::vector<std::vector<double>>& todo, const Evaluate& evaluate, const Done& done) override {
    std::atomic<size_t> next{0};
    std::mutex mutex;
    std::exception_ptr failure;
    auto work = [&] {
      for (;;) {
        const size_t i = next++;
        if (i >= todo.size()) return;
        try {
          CandidateResult r = evaluate(todo[i]);
          std::lock_guard<std::mutex> lock(mutex);
          done(std::move(r));
        } catch (...) {
          std::lock_guard<std::mutex> lock(mutex);
          if (!failure) failure = std::current_exception();
          next = todo.size();
        }
      }
    };
    const int jobs = std::max(1, std::min<int>(jobs_, static_cast<int>(todo.size())));
    std::vector<std::thread> pool;
    for (int j = 1; j < jobs; ++j) pool.emplace_back(work);
    work();
    for (auto& t : pool) t.join();
    if (failure) std::rethrow_exception(failure);
  }

 private:
  int jobs_;
};

// Runs candidates and keeps the results table.
class Runner {
 public:
  Runner(const SceneDesc& scene, const PreparedDataset& data, const std::vector<ParamSpec>& params,
         const SearchOptions& o, std::string path, std::string identity, SearchProgress* progress)
      : scene_(scene), data_(data), params_(params), options_(o), path_(std::move(path)),
        identity_(std::move(identity)), progress_(progress) {
    std::error_code ec;
    if (fs::exists(path_, ec)) rows_ = readResults(path_, params_, identity_);
    for (size_t i = 0; i < rows_.size(); ++i) done_[key(rows_[i].values)] = i;
  }

  const std::vector<CandidateResult>& rows() const { return rows_; }
  void beginStage() { finished_ = 0; }

  // Runs every candidate of a stage not already in the table (this shard's share of them).
  void batch(const std::string& stage, const std::vector<std::vector<double>>& candidates) {
    std::vector<std::vector<double>> todo;
    int already = 0;
    std::set<std::string> seen;
    for (size_t k = 0; k < candidates.size(); ++k) {
      if (static_cast<int>(k % options_.shards) != options_.shard) continue;
      const std::string kk = key(candidates[k]);
      if (!seen.insert(kk).second) continue;
      if (done_.count(kk)) ++already;
      else todo.push_back(candidates[k]);
    }
    if (progress_) progress_->stage(stage, static_cast<int>(todo.size()) + already, already);
    total_ = static_cast<int>(todo.size());
    finished_ = 0;
    execute(stage, todo);
  }

  // One candidate, from the table when it was run before.
  const CandidateResult& one(const std::string& stage, const std::vector<double>& values) {
    auto it = done_.find(key(values));
    if (it != done_.end()) return rows_[it->second];
    total_ = 0;  // a minimiser's evaluations are not known in advance
    execute(stage, {values});
    return rows_[done_.at(key(values))];
  }

 private:
  // Runs candidates on the executor given, or on `jobs` threads.
  void execute(const std::string& stage, const std::vector<std::vector<double>>& todo) {
    auto evaluate = [&](const std::vector<double>& v) { return evaluateCandidate(scene_, data_, params_, options_.replay, v); };
    auto done = [&](CandidateResult r) {
      r.stage = stage;
      record(std::move(r));
    };
    if (options_.executor) options_.executor->run(todo, evaluate, done);
    else threads_.run(todo, evaluate, done);
  }

  void record(CandidateResult r) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (done_.count(key(r.values))) return;
    done_[key(r.values)] = rows_.size();
    rows_.push_back(std::move(r));
    writeFileAtomic(path_, formatResults(rows_, params_, identity_));
    ++finished_;
    if (progress_) progress_->finished(rows_.back(), finished_, total_);
  }

  const SceneDesc& scene_;
  const PreparedDataset& data_;
  const std::vector<ParamSpec>& params_;
  const SearchOptions& options_;
  std::string path_, identity_;
  SearchProgress* progress_;
  std::vector<CandidateResult> rows_;
  std::map<std::string, size_t> done_;
  std::mutex mutex_;
  ThreadExecutor threads_{options_.jobs};
  int total_ = 0, finished_ = 0;
};

// A metric the minimisers can compare: failed candidates are worse than any finished one.
double objective(const CandidateResult& r) { return r.ok() && std::isfinite(r.metric) ? r.metric : 1e30; }

void minimise(Runner& runner, const std::vector<ParamSpec>& params, const SearchOptions& o) {
  const CandidateResult* best = bestOf(runner.rows());
  if (!best) return;
  const size_t d = params.size();
  std::vector<double> a(d), b(d), x0(d), tol(d);
  for (size_t j = 0; j < d; ++j) {
    std::vector<double> axis;
    for (const auto& [v, m] : profile(runner.rows(), j)) axis.push_back(v);
    const auto [lo, hi] = neighbours(axis, best->values[j]);
    a[j] = toAxis(params[j], lo);
    b[j] = toAxis(params[j], hi);
    x0[j] = toAxis(params[j], best->values[j]);
    const double t = params[j].scale == Scale::Log ? std::log10(1 + o.tolerance)
                                                   : o.tolerance * std::max(std::abs(params[j].lo), std::abs(params[j].hi));
    tol[j] = b[j] > a[j] ? t / (b[j] - a[j]) : 1;
  }
  std::vector<double> values(d);
  // s in [0, 1]^d spans the bracket; the candidate's values are on the parameters' own axes.
  auto at = [&](const std::vector<double>& s) {
    for (size_t j = 0; j < d; ++j) values[j] = fromAxis(params[j], a[j] + s[j] * (b[j] - a[j]));
    return objective(runner.one("minimise", values));
  };
  if (d == 1) {
    if (!(b[0] > a[0])) return;
    // Brent's method on [1, 2] (the bracket shifted away from 0, since its tolerance is relative).
    const int bits = std::clamp(static_cast<int>(std::ceil(1 - std::log2(tol[0]))), 4, 40);
    boost::uintmax_t iterations = static_cast<boost::uintmax_t>(o.maxEvaluations);
    boost::math::tools::brent_find_minima([&](double s) { return at({s - 1}); }, 1.0, 2.0, bits, iterations);
    return;
  }
  std::vector<double> s0(d);
  bool flat = true;
  for (size_t j = 0; j < d; ++j) {
    s0[j] = b[j] > a[j] ? (x0[j] - a[j]) / (b[j] - a[j]) : 0.5;
    flat = flat && !(b[j] > a[j]);
  }
  if (flat) return;
  // BOBYQA, restarted from where it stopped while a run still improves: its trust region shrinks
  // as it follows a curved valley (a stiffer material with a smaller Poisson's ratio fits nearly
  // as well), and it can stop on the valley's floor far from the minimum. The evaluations of all
  // runs share the one budget.
  int left = o.maxEvaluations;
  double last = objective(*best);
  while (left > 2 * static_cast<int>(d) + 1) {
    nlopt::opt opt(nlopt::LN_BOBYQA, static_cast<unsigned>(d));
    opt.set_lower_bounds(std::vector<double>(d, 0.0));
    opt.set_upper_bounds(std::vector<double>(d, 1.0));
    opt.set_xtol_abs(tol);
    opt.set_maxeval(left);
    int used = 0;
    std::function<double(const std::vector<double>&)> f = [&](const std::vector<double>& s) {
      ++used;
      return at(s);
    };
    opt.set_min_objective(
        [](const std::vector<double>& s, std::vector<double>&, void* data) {
          return (*static_cast<std::function<double(const std::vector<double>&)>*>(data))(s);
        },
        &f);
    std::vector<double> s = s0;
    double value = last;
    try {
      opt.optimize(s, value);
    } catch (const nlopt::roundoff_limited&) {
      // Converged as far as the metric's resolution allows: the evaluations are in the table.
    } catch (const nlopt::forced_stop&) {
      return;
    }
    left -= used;
    const CandidateResult* now = bestOf(runner.rows());
    // Another run only where this one moved the best by more than the metric's own noise.
    const double noise = std::isfinite(now->metricSe) ? now->metricSe : 0.0;
    if (!(objective(*now) < last - noise)) return;
    last = objective(*now);
    for (size_t j = 0; j < d; ++j)
      s0[j] = b[j] > a[j] ? std::clamp((toAxis(params[j], now->values[j]) - a[j]) / (b[j] - a[j]), 0.0, 1.0) : 0.5;
  }
}

}  // namespace

CandidateResult evaluateCandidate(const SceneDesc& replayScene, const PreparedDataset& data,
                                  const std::vector<ParamSpec>& params, const ReplayOptions& options,
                                  const std::vector<double>& values) {
  SceneDesc desc = replayScene;
  for (size_t j = 0; j < params.size(); ++j)
    desc.set(params[j].address, exact(values[j]), SourceLoc{"--param " + params[j].address});
  try {
    return fromScore("", values, replay(desc, data, options));
  } catch (const Error&) {
    throw;  // an input error: the same for every candidate, so the search stops
  } catch (const std::exception& e) {
    ReplayScore s;
    s.status = ReplayScore::Status::Diverged;
    s.reason = std::string("failed: ") + e.what();
    return fromScore("", values, s);
  }
}

double toAxis(const ParamSpec& p, double v) { return p.scale == Scale::Log ? std::log10(v) : v; }
double fromAxis(const ParamSpec& p, double u) { return p.scale == Scale::Log ? std::pow(10.0, u) : u; }

ParamSpec parseParam(const std::string& argument, const SceneDesc& scene) {
  const std::string option = "--param " + argument;
  const auto eq = argument.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == argument.size())
    throw Error(option + ": expected ADDRESS=SPEC, e.g. phantom/fem.youngModulus=log:1kPa:100kPa:5");
  ParamSpec p;
  p.address = trim(argument.substr(0, eq));
  p.spec = trim(argument.substr(eq + 1));
  const AttrSpec& attr = attributeSpec(scene, p.address, "--param " + p.address);
  const UnitSystem units = sceneUnits(scene);
  if (attr.hasUnit) p.unit = unitText(attr.dim, units);
  auto number = [&](const std::string& text) {
    AttrValue v;
    try {
      parseAttrText(attr, trim(text), units, v);
    } catch (const std::invalid_argument& e) {
      throw Error("--param " + p.address + ": '" + trim(text) + "': " + e.what());
    }
    if (v.nums.size() != 1) throw Error("--param " + p.address + ": '" + trim(text) + "' is not one number");
    return v.nums.front();
  };
  auto count = [&](const std::string& text) {
    long long n = 0;
    if (!parseInteger(trim(text), n))
      throw Error("--param " + p.address + ": the number of values '" + trim(text) + "' is not an integer");
    if (n < 1 || n > 100000)
      throw Error("--param " + p.address + ": the number of values must be from 1 to 100000, got " + trim(text));
    return static_cast<int>(n);
  };
  const std::vector<std::string> parts = split(p.spec, ':');
  const std::string kind = parts.size() > 1 ? trim(parts[0]) : "";
  if (kind == "log" || kind == "lin") {
    if (parts.size() != 4)
      throw Error("--param " + p.address + ": '" + p.spec + "': a grid is " + kind + ":LO:HI:N (e.g. " + kind + ":1kPa:100kPa:5)");
    p.scale = kind == "log" ? Scale::Log : Scale::Linear;
    p.lo = number(parts[1]);
    p.hi = number(parts[2]);
    const int n = count(parts[3]);
    if (!(p.hi > p.lo) && n > 1) throw Error("--param " + p.address + ": '" + p.spec + "': HI must be above LO");
    if (p.scale == Scale::Log && !(p.lo > 0)) throw Error("--param " + p.address + ": a log grid needs LO > 0");
    p.grid = axisGrid(p, p.lo, p.hi, n);
  } else if (kind == "refine" || kind == "refine-lin") {
    if (parts.size() != 3)
      throw Error("--param " + p.address + ": '" + p.spec + "': a refinement is " + kind + ":LO:HI (e.g. " + kind +
                  (kind == "refine" ? ":10Pa:1MPa)" : ":0.3:0.49)"));
    p.refine = true;
    p.scale = kind == "refine" ? Scale::Log : Scale::Linear;
    p.lo = number(parts[1]);
    p.hi = number(parts[2]);
    if (!(p.hi > p.lo)) throw Error("--param " + p.address + ": '" + p.spec + "': HI must be above LO");
    if (p.scale == Scale::Log && !(p.lo > 0)) throw Error("--param " + p.address + ": refine (log) needs LO > 0; use refine-lin");
  } else if (parts.size() == 1) {
    for (const std::string& v : split(p.spec, ',')) p.grid.push_back(number(v));
    std::sort(p.grid.begin(), p.grid.end());
    p.grid.erase(std::unique(p.grid.begin(), p.grid.end()), p.grid.end());
    p.lo = p.grid.front();
    p.hi = p.grid.back();
    p.scale = p.lo > 0 && p.hi / p.lo >= 10 ? Scale::Log : Scale::Linear;
  } else {
    throw Error("--param " + p.address + ": '" + p.spec + "': SPEC is log:LO:HI:N, lin:LO:HI:N, V1,V2,..., refine:LO:HI or refine-lin:LO:HI");
  }
  return p;
}

std::string resultsHeader(const std::vector<ParamSpec>& params) {
  std::string h = "stage";
  for (const auto& p : params) h += "," + p.address;
  for (const auto& c : kColumns) h += "," + c;
  return h;
}

std::string formatResult(const CandidateResult& r) {
  std::ostringstream s;
  s << r.stage;
  for (double v : r.values) s << "," << exact(v);
  s << "," << statusName(r.status);
  for (double v : {r.metric, r.metricSe, r.cloudTerm, r.forceTerm, r.cloudRms, r.cloudRmsContact, r.cloudRmsFree,
                   r.forceRms, r.forceRmsContact, r.forceRmsFree})
    s << "," << exact(v);
  s << "," << r.frames << "," << r.samples << "," << r.steps << "," << formatNumber(r.wallSeconds) << "," << field(r.reason);
  return s.str();
}

CandidateResult parseResult(const std::string& row, size_t d) {
  const auto f = split(row, ',');
  if (f.size() != 1 + d + kColumns.size())
    throw std::invalid_argument("expected " + std::to_string(1 + d + kColumns.size()) + " fields, got " +
                                std::to_string(f.size()));
  CandidateResult r;
  r.stage = f[0];
  for (size_t j = 0; j < d; ++j) r.values.push_back(std::stod(f[1 + j]));
  const std::string st = f[1 + d];
  if (st == "ok") r.status = ReplayScore::Status::Ok;
  else if (st == "diverged") r.status = ReplayScore::Status::Diverged;
  else if (st == "timeout") r.status = ReplayScore::Status::Timeout;
  else throw std::invalid_argument("status '" + st + "'");
  double* nums[] = {&r.metric, &r.metricSe, &r.cloudTerm, &r.forceTerm, &r.cloudRms, &r.cloudRmsContact,
                    &r.cloudRmsFree, &r.forceRms, &r.forceRmsContact, &r.forceRmsFree};
  for (size_t i = 0; i < 10; ++i) *nums[i] = std::stod(f[2 + d + i]);
  r.frames = std::stoi(f[12 + d]);
  r.samples = std::stoi(f[13 + d]);
  r.steps = std::stoi(f[14 + d]);
  r.wallSeconds = std::stod(f[15 + d]);
  r.reason = f[16 + d];
  return r;
}

std::string formatResults(const std::vector<CandidateResult>& rows, const std::vector<ParamSpec>& params,
                          const std::string& identity) {
  std::string out = "# search " + identity + "\n" + resultsHeader(params) + "\n";
  for (const auto& r : rows) out += formatResult(r) + "\n";
  return out;
}

std::vector<CandidateResult> readResults(const std::string& path, const std::vector<ParamSpec>& params,
                                         const std::string& identity) {
  std::ifstream in(path);
  if (!in) throw Error(SourceLoc{path}, "cannot be read");
  std::string line;
  int n = 0;
  std::vector<CandidateResult> rows;
  const std::string header = resultsHeader(params);
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (n == 1) {
      if (line != "# search " + identity)
        throw Error(SourceLoc{path, 1}, "holds the results of another search (" + viscera::quoted(line) +
                                            "); give this search its own --out folder, or remove the file to start over");
      continue;
    }
    if (n == 2) {
      if (line != header)
        throw Error(SourceLoc{path, 2}, "its columns are not this search's (expected " + viscera::quoted(header) +
                                            "); give this search its own --out folder");
      continue;
    }
    if (trim(line).empty()) continue;
    try {
      rows.push_back(parseResult(line, params.size()));
    } catch (const std::exception& e) {
      throw Error(SourceLoc{path, n}, std::string("malformed row (") + e.what() + ")");
    }
  }
  return rows;
}

void validateSearch(const std::vector<ParamSpec>& params, const SearchOptions& o) {
  if (params.empty()) throw Error("a search needs at least one --param");
  const bool refine = params.front().refine;
  for (const auto& p : params)
    if (p.refine != refine)
      throw Error("--param " + p.address + ": grids and refinements cannot be mixed in one search; make every --param a grid "
                  "or every one a refinement");
  if (o.shards < 1 || o.shard < 0 || o.shard >= o.shards) throw Error("--shard: expected i/N with 0 <= i < N");
  if (refine && o.shards > 1)
    throw Error("--shard: a refinement chooses each stage from the one before, so it cannot be split into shards; shard a grid");
  if (o.jobs < 1) throw Error("--jobs: must be at least 1");
}

SearchReport runSearch(const SceneDesc& scene, const PreparedDataset& data, const std::vector<ParamSpec>& params,
                       const SearchOptions& o, const std::string& results, const std::string& identity,
                       SearchProgress* progress) {
  validateSearch(params, o);
  const bool refine = params.front().refine;
  // Every candidate's values pass the attributes' own checks now, not halfway through the batch.
  {
    SceneDesc probe = replayDescription(scene, data.data);
    for (const auto& p : params) probe.set(p.address, exact(refine ? p.lo : p.grid.front()), SourceLoc{"--param " + p.address});
    buildScene(probe);
  }
  const SceneDesc desc = replayDescription(scene, data.data);
  Runner runner(desc, data, params, o, results, identity, progress);
  if (!refine) {
    std::vector<std::vector<double>> axes;
    for (const auto& p : params) axes.push_back(p.grid);
    runner.batch("grid", product(axes));
  } else {
    std::vector<std::vector<double>> coarse;
    for (const auto& p : params) coarse.push_back(coarseValues(p));
    runner.batch("decades", product(coarse));
    if (const CandidateResult* best = bestOf(runner.rows(), "decades")) {
      const int n = o.finePoints > 0 ? o.finePoints : params.size() == 1 ? 7 : 5;
      std::vector<std::vector<double>> fine;
      for (size_t j = 0; j < params.size(); ++j) {
        const auto [a, b] = neighbours(coarse[j], best->values[j]);
        fine.push_back(axisGrid(params[j], a, b, n));
      }
      runner.batch("fine", product(fine));
      if (progress) progress->stage("minimise", 0, 0);
      runner.beginStage();
      minimise(runner, params, o);
    }
  }
  SearchReport report = analyse(params, runner.rows(), data.scoresWrench());
  report.complete = o.shards == 1;
  return report;
}

SearchReport analyse(const std::vector<ParamSpec>& params, std::vector<CandidateResult> results, bool hasWrench) {
  SearchReport rep;
  rep.results = std::move(results);
  for (const auto& r : rep.results) {
    rep.ok += r.status == ReplayScore::Status::Ok;
    rep.diverged += r.status == ReplayScore::Status::Diverged;
    rep.timeout += r.status == ReplayScore::Status::Timeout;
  }
  for (const std::string stage : {"grid", "decades", "fine", "minimise"}) {
    StageReport s;
    s.name = stage;
    for (const auto& r : rep.results) s.candidates += r.stage == stage;
    if (s.candidates == 0) continue;
    if (const CandidateResult* b = bestOf(rep.results, stage)) {
      s.best = b->values;
      s.metric = b->metric;
    }
    rep.stages.push_back(s);
  }
  const CandidateResult* best = bestOf(rep.results);
  if (!best) return rep;
  rep.best = *best;
  rep.noiseFloor = 2 * (std::isfinite(best->metricSe) ? best->metricSe : 0.0);
  const double threshold = best->metric + rep.noiseFloor;
  for (size_t j = 0; j < params.size(); ++j) {
    const ParamSpec& p = params[j];
    ParamReport pr;
    pr.address = p.address;
    pr.best = best->values[j];
    const auto prof = profile(rep.results, j);
    size_t b = 0;
    while (b < prof.size() && prof[b].first != pr.best) ++b;
    // Where the profile crosses the threshold between an inside point i and an outside point o.
    auto crossing = [&](size_t i, size_t o) {
      const double ui = toAxis(p, prof[i].first), uo = toAxis(p, prof[o].first);
      const double mi = prof[i].second, mo = prof[o].second;
      const double a = mo > mi ? (threshold - mi) / (mo - mi) : 0.0;
      return fromAxis(p, ui + std::clamp(a, 0.0, 1.0) * (uo - ui));
    };
    size_t i = b;
    while (i > 0 && prof[i - 1].second <= threshold) --i;
    pr.loAtEdge = i == 0;
    pr.lo = i == 0 ? prof.front().first : crossing(i, i - 1);
    i = b;
    while (i + 1 < prof.size() && prof[i + 1].second <= threshold) ++i;
    pr.hiAtEdge = i + 1 == prof.size();
    pr.hi = pr.hiAtEdge ? prof.back().first : crossing(i, i + 1);
    if (b > 0 && b + 1 < prof.size()) {
      const double u1 = toAxis(p, prof[b - 1].first), u2 = toAxis(p, prof[b].first), u3 = toAxis(p, prof[b + 1].first);
      const double m1 = prof[b - 1].second, m2 = prof[b].second, m3 = prof[b + 1].second;
      pr.curvature = 2 * ((m3 - m2) / (u3 - u2) - (m2 - m1) / (u2 - u1)) / (u3 - u1);
    }
    pr.identifiable = prof.size() >= 3 && !pr.loAtEdge && !pr.hiAtEdge;
    std::ostringstream s;
    s.precision(4);
    if (pr.identifiable) {
      s << p.address << " = " << pr.best << ", within [" << pr.lo << ", " << pr.hi
        << "]: the metric rises above its noise floor (" << rep.noiseFloor << ") on both sides";
    } else if (prof.size() < 3) {
      s << p.address << ": too few values finished (" << prof.size() << ") to tell whether the data determine it";
    } else {
      s << p.address << " is not identifiable from this dataset: the metric stays within its noise floor ("
        << rep.noiseFloor << ") from " << pr.lo << " to " << pr.hi << ", "
        << (pr.loAtEdge && pr.hiAtEdge ? "both ends" : pr.loAtEdge ? "the lower end" : "the upper end")
        << " of the range searched. ";
      if (!hasWrench)
        s << "Clouds alone barely constrain a stiffness when the instrument imposes the displacements; a measured "
             "force (wrench.csv), loading by gravity or a known load would.";
      else
        s << "Widen the range, or add data that load the tissue differently.";
    }
    pr.statement = s.str();
    rep.params.push_back(pr);
  }
  return rep;
}

std::string summaryJson(const SearchReport& rep, const std::vector<ParamSpec>& params, const std::string& units,
                        const std::string& scene, const std::string& data, bool wrench) {
  using Json = nlohmann::ordered_json;
  auto num = [](double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); };
  Json j;
  j["scene"] = scene;
  j["data"] = data;
  j["units"] = units;
  j["wrench"] = wrench;
  j["complete"] = rep.complete;
  Json ps = Json::array();
  for (const auto& p : params)
    ps.push_back({{"address", p.address}, {"spec", p.spec}, {"scale", p.scale == Scale::Log ? "log" : "linear"},
                  {"refine", p.refine}, {"lo", p.lo}, {"hi", p.hi}});
  j["params"] = ps;
  Json best = Json::object();
  if (rep.best)
    for (size_t k = 0; k < params.size(); ++k) best[params[k].address] = rep.best->values[k];
  j["best"] = rep.best ? best : Json(nullptr);
  j["metric"] = rep.best ? num(rep.best->metric) : Json(nullptr);
  j["metric_se"] = rep.best ? num(rep.best->metricSe) : Json(nullptr);
  j["noise_floor"] = num(rep.noiseFloor);
  if (rep.best) {
    j["cloud_rms"] = num(rep.best->cloudRms);
    j["force_rms"] = num(rep.best->forceRms);
  }
  Json bracket = Json::object();
  for (const auto& p : rep.params)
    bracket[p.address] = {{"lo", num(p.lo)},
                          {"hi", num(p.hi)},
                          {"lo_at_edge", p.loAtEdge},
                          {"hi_at_edge", p.hiAtEdge},
                          {"curvature", num(p.curvature)},
                          {"identifiable", p.identifiable}};
  j["bracket"] = bracket;
  Json statements = Json::array();
  for (const auto& p : rep.params) statements.push_back(p.statement);
  j["identifiability"] = statements;
  Json stages = Json::array();
  for (const auto& s : rep.stages) {
    Json b = Json::object();
    for (size_t k = 0; k < s.best.size(); ++k) b[params[k].address] = s.best[k];
    stages.push_back({{"name", s.name}, {"candidates", s.candidates}, {"best", s.best.empty() ? Json(nullptr) : b},
                      {"metric", num(s.metric)}});
  }
  j["stages"] = stages;
  j["candidates"] = {{"total", rep.results.size()}, {"ok", rep.ok}, {"diverged", rep.diverged}, {"timeout", rep.timeout}};
  return j.dump(2) + "\n";
}

SearchSummary readSummary(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(SourceLoc{path}, "cannot be read (a search folder holds summary.json and results.csv)");
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    SearchSummary s;
    s.units = j.at("units").get<std::string>();
    s.scene = j.at("scene").get<std::string>();
    s.data = j.at("data").get<std::string>();
    s.wrench = j.at("wrench").get<bool>();
    for (const auto& p : j.at("params")) {
      ParamSpec ps;
      ps.address = p.at("address").get<std::string>();
      ps.spec = p.at("spec").get<std::string>();
      ps.scale = p.at("scale").get<std::string>() == "log" ? Scale::Log : Scale::Linear;
      ps.refine = p.at("refine").get<bool>();
      ps.lo = p.at("lo").get<double>();
      ps.hi = p.at("hi").get<double>();
      s.params.push_back(ps);
    }
    if (s.params.empty()) throw std::invalid_argument("no params");
    return s;
  } catch (const std::exception& e) {
    throw Error(SourceLoc{path}, std::string("is not a search summary: ") + e.what());
  }
}

}  // namespace viscera::study
