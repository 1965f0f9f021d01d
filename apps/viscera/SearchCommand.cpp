// `viscera search`: finds scene parameters that make a simulation agree with a measured dataset
// (study/Search.h), writing OUT/results.csv as candidates finish, then OUT/summary.json and
// OUT/search.png. Run again with the same arguments, it resumes. `viscera search merge` joins the
// folders of a sharded grid.
#include "apps/viscera/SearchCommand.h"

#include <CLI/CLI.hpp>
#include <tbb/info.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <thread>

#include "apps/viscera/Gnuplot.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Text.h"
#include "core/Units.h"
#include "engine/Run.h"
#include "io/scene/SceneReader.h"
#include "study/Distributed.h"
#include "study/Search.h"

namespace viscera {
namespace {

namespace fs = std::filesystem;

struct SearchArgs {
  std::string scene, data, out = "search", shard;
  std::vector<std::string> params, sets;
  int jobs = 1, points = 2000, maxEvals = 40, finePoints = 0;
  double timeBudget = 0, maxDistance = 0, lengthScale = 0, forceScale = 0, tolerance = 1e-3;
  bool noWrench = false, noPlot = false, quiet = false;
};

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

std::string valuesText(const std::vector<study::ParamSpec>& params, const std::vector<double>& v) {
  std::string s;
  for (size_t j = 0; j < params.size(); ++j) {
    const std::string& a = params[j].address;
    s += (j ? ", " : "") + a.substr(a.rfind('.') + 1) + " " + formatNumber(v[j]);
  }
  return s;
}

// One line per finished candidate, with the stage's ETA.
class ProgressLog : public study::SearchProgress {
 public:
  ProgressLog(const std::vector<study::ParamSpec>& params, bool quiet) : params_(params), quiet_(quiet) {}
  void stage(const std::string& name, int candidates, int already) override {
    start_ = now();
    if (quiet_) return;
    if (name == "minimise") std::cerr << "stage minimise: bounded minimiser around the best so far\n";
    else
      std::cerr << "stage " << name << ": " << candidates << " candidate" << (candidates == 1 ? "" : "s")
                << (already ? " (" + std::to_string(already) + " already in results.csv)" : "") << "\n";
  }
  void finished(const study::CandidateResult& r, int done, int total) override {
    if (quiet_) return;
    const double elapsed = now() - start_;
    std::ostringstream s;
    s << "  [" << done << (total > 0 ? "/" + std::to_string(total) : "") << "] " << valuesText(params_, r.values) << ": " << study::statusName(r.status);
    if (r.ok()) s << ", metric " << formatNumber(r.metric);
    else s << " (" << r.reason << ")";
    s << ", " << formatDuration(r.wallSeconds);
    if (total > 0 && done < total) s << "; ETA " << formatDuration(elapsed / done * (total - done));
    std::cerr << s.str() << "\n";
  }

 private:
  const std::vector<study::ParamSpec>& params_;
  bool quiet_;
  double start_ = now();
};

// search.gp: one panel per parameter, the metric of every finished candidate against the
// parameter (log axis for log-scaled ones), a marker shape per stage, the best and the noise floor.
std::string plotScript(const study::SearchReport& rep, const std::vector<study::ParamSpec>& params) {
  const size_t d = params.size();
  const int status = static_cast<int>(d) + 2, metric = static_cast<int>(d) + 3;
  std::ostringstream g;
  g << "# The metric of every candidate against each parameter, written by viscera search.\n"
    << "# Re-plot with: gnuplot search.gp (writes search.png next to results.csv)\n"
    << "if (!exists(\"outfile\")) outfile = \"search.png\"\n"
    << "set terminal pngcairo size 900," << 380 * d + 60 << " font \",10\"\n"
    << "set output outfile\n"
    << "set datafile separator \",\"\n"
    << "set grid\n"
    << "set key outside right top\n"
    << "set ylabel \"metric\"\n"
    << "set multiplot layout " << d << ",1\n";
  const char* stages[][3] = {{"grid", "7", "black"}, {"decades", "5", "blue"}, {"fine", "9", "dark-green"}, {"minimise", "13", "red"}};
  for (size_t j = 0; j < d; ++j) {
    const auto& p = params[j];
    g << (p.scale == study::Scale::Log ? "set logscale x\n" : "unset logscale x\n");
    g << "set xlabel \"" << p.address << (p.unit.empty() ? "" : " (" + p.unit + ")") << "\" noenhanced\n";
    g << "unset arrow\n";
    const double pad = p.scale == study::Scale::Log ? 1.15 : 0.0;
    if (p.scale == study::Scale::Log)
      g << "set xrange [" << p.lo / pad << ":" << p.hi * pad << "]\n";
    else {
      const double m = p.hi > p.lo ? 0.05 * (p.hi - p.lo) : std::max(1e-3 * std::abs(p.lo), 1e-12);
      g << "set xrange [" << p.lo - m << ":" << p.hi + m << "]\n";
    }
    if (rep.best) {
      const double threshold = rep.best->metric + rep.noiseFloor;
      g << "set arrow from graph 0, first " << threshold << " to graph 1, first " << threshold
        << " nohead dt 2 lc rgb \"gray40\"\n";
      std::ostringstream best;
      best.precision(4);
      best << rep.best->values[j];
      g << "set title \"best " << best.str() << (rep.params[j].identifiable ? "" : " (not identifiable)")
        << "; dashed: best + noise floor\" noenhanced\n";
    }
    g << "plot ";
    bool first = true;
    for (const auto& s : stages) {
      bool any = false;
      for (const auto& r : rep.results) any = any || r.stage == s[0];
      if (!any) continue;
      g << (first ? "" : ", \\\n     ") << "\"results.csv\" skip 2 using ((strcol(1) eq \"" << s[0] << "\" && strcol(" << status
        << ") eq \"ok\") ? $" << j + 2 << " : 1/0):" << metric << " with points pt " << s[1] << " ps 1.3 lc rgb \"" << s[2]
        << "\" title \"" << s[0] << "\"";
      first = false;
    }
    if (rep.best)
      g << ", \\\n     \"+\" using (" << rep.best->values[j] << "):(" << rep.best->metric
        << ") every ::0::0 with points pt 3 ps 3 lc rgb \"orange\" title \"best\"";
    g << "\n";
  }
  g << "unset multiplot\n";
  return g.str();
}

void writeOutputs(const fs::path& dir, const study::SearchReport& rep, const std::vector<study::ParamSpec>& params,
                  const std::string& units, const std::string& scene, const std::string& data, bool wrench, bool plot) {
  writeFileAtomic((dir / "summary.json").string(), study::summaryJson(rep, params, units, scene, data, wrench));
  if (plot && rep.ok > 0) {
    writeFileAtomic((dir / "search.gp").string(), plotScript(rep, params));
    plotWithGnuplot(dir, "search.gp", "search.png");
  }
}

void printReport(const study::SearchReport& rep, const std::vector<study::ParamSpec>& params, const fs::path& dir) {
  std::cerr << rep.results.size() << " candidates: " << rep.ok << " ok, " << rep.diverged << " diverged, " << rep.timeout
            << " timed out\n";
  if (!rep.best) {
    std::cerr << "no candidate finished: see the reasons in " << (dir / "results.csv").string() << "\n";
    return;
  }
  std::cout << "best: " << valuesText(params, rep.best->values) << " (metric " << formatNumber(rep.best->metric)
            << ", noise floor " << formatNumber(rep.noiseFloor) << ")\n";
  for (const auto& p : rep.params) std::cout << p.statement << "\n";
  if (!rep.complete) std::cout << "this is one shard: join the shards with `viscera search merge`\n";
}

int search(const SearchArgs& a) {
  SceneDesc scene = io::readScene(a.scene);
  for (const auto& s : a.sets) scene.applySetting(s);
  std::vector<study::ParamSpec> params;
  for (const auto& p : a.params) params.push_back(study::parseParam(p, scene));
  for (size_t i = 0; i < params.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (params[i].address == params[j].address) throw Error("--param " + params[i].address + ": given twice");

  study::SearchOptions o;
  o.jobs = a.jobs;
  if (!a.shard.empty()) {
    const auto slash = a.shard.find('/');
    long long i = -1, n = 0;
    if (slash == std::string::npos || !parseInteger(a.shard.substr(0, slash), i) || !parseInteger(a.shard.substr(slash + 1), n) ||
        n < 1 || i < 0 || i >= n)
      throw Error("--shard: expected i/N with 0 <= i < N (e.g. 0/4), got " + viscera::quoted(a.shard));
    o.shard = static_cast<int>(i);
    o.shards = static_cast<int>(n);
  }
  o.tolerance = a.tolerance;
  o.maxEvaluations = a.maxEvals;
  o.finePoints = a.finePoints;
  o.replay.timeBudget = a.timeBudget;
  // The cores are shared among the jobs; each candidate's result does not depend on its threads.
  o.replay.threads = std::max(1, tbb::info::default_concurrency() / std::max(1, a.jobs));
  study::ScoreOptions& so = o.replay.score;
  so.maxPoints = a.points;
  if (a.maxDistance > 0) so.maxDistance = a.maxDistance;
  so.lengthScale = a.lengthScale;
  so.forceScale = a.forceScale;
  so.useWrench = !a.noWrench;

  study::validateSearch(params, o);
  // Under mpirun every rank reads the same inputs; rank 0 runs the search, the others evaluate.
  std::unique_ptr<study::MpiSession> mpi;
  if (study::launchedByMpi()) {
    mpi = std::make_unique<study::MpiSession>();
    o.replay.threads = 1;  // the ranks are the parallelism
  }
  const study::PreparedDataset data = study::prepareDataset(a.data, so);
  if (mpi && mpi->rank() != 0) {
    const SceneDesc desc = study::replayDescription(scene, data.data);
    mpi->serve([&](const std::vector<double>& v) { return study::evaluateCandidate(desc, data, params, o.replay, v); });
    return kExitOk;
  }
  // Whatever ends rank 0's search, the other ranks are told to stop.
  struct StopWorkers {
    const study::MpiSession* mpi;
    ~StopWorkers() {
      if (mpi) mpi->stopWorkers();
    }
  } stopWorkers{mpi.get()};
  std::unique_ptr<study::CandidateExecutor> coordinator;
  if (mpi) {
    coordinator = mpi->coordinator();
    o.executor = coordinator.get();
  }
  for (const auto& n : data.data.notes)
    if (!a.quiet) std::cerr << n << "\n";

  const fs::path dir = a.out;
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) throw Error(SourceLoc{a.out}, "--out: is a file, not a folder");
  if (fs::exists(dir, ec) && fs::equivalent(dir, a.data, ec))
    throw Error(SourceLoc{a.out}, "--out: is the dataset folder; a search writes to its own folder");
  const fs::path parent = fs::absolute(dir).parent_path();
  if (!fs::is_directory(parent, ec)) throw Error(SourceLoc{a.out}, "--out: the folder " + parent.string() + " does not exist");

  // What makes two runs the same search: resuming checks it against results.csv.
  std::ostringstream id;
  id << "scene=" << fs::absolute(a.scene).lexically_normal().string();
  for (const auto& s : a.sets) id << " set=" << s;
  id << " data=" << fs::absolute(a.data).lexically_normal().string() << " points=" << so.maxPoints
     << " max_distance=" << formatNumber(so.maxDistance) << " length_scale=" << formatNumber(so.lengthScale)
     << " force_scale=" << formatNumber(a.forceScale) << " wrench=" << (data.scoresWrench() ? "yes" : "no");
  for (const auto& p : params) id << " param=" << p.address << "=" << p.spec;
  if (o.tolerance != 1e-3 || o.maxEvaluations != 40 || o.finePoints != 0)
    id << " tolerance=" << formatNumber(o.tolerance) << " max_evals=" << o.maxEvaluations << " fine=" << o.finePoints;
  // A candidate's reading of a different results.csv is refused before anything runs.
  const fs::path results = dir / "results.csv";
  if (fs::exists(results, ec)) study::readResults(results.string(), params, id.str());

  // results.csv is appended to as candidates finish: one search at a time.
  const FolderLock lock(dir.string());
  if (!a.quiet)
    std::cerr << "search: " << params.size() << " parameter" << (params.size() == 1 ? "" : "s") << ", dataset "
              << data.data.frames.size() << " frames" << (data.scoresWrench() ? " and a wrench" : " (no wrench scored)")
              << ", " << (mpi ? mpi->size() : a.jobs) << (mpi ? " MPI rank" : " job") << ((mpi ? mpi->size() : a.jobs) == 1 ? "" : "s")
              << "\n";
  ProgressLog progress(params, a.quiet);
  const study::SearchReport rep = study::runSearch(scene, data, params, o, results.string(), id.str(), &progress);

  const AttrDesc* u = scene.root.find("units");
  const std::string units = u ? UnitSystem::parse(u->value).str() : UnitSystem().str();
  writeOutputs(dir, rep, params, units, fs::absolute(a.scene).string(), fs::absolute(a.data).string(),
               data.scoresWrench(), !a.noPlot);
  printReport(rep, params, dir);
  std::cerr << "wrote " << results.string() << ", summary.json" << (a.noPlot || rep.ok == 0 ? "" : ", search.gp and search.png")
            << "\n";
  return rep.best ? kExitOk : kExitDiverged;
}

struct MergeArgs {
  std::vector<std::string> shards;
  std::string out;
  bool noPlot = false;
};

int merge(const MergeArgs& a) {
  if (a.shards.empty()) throw Error("search merge: give the shard folders");
  const study::SearchSummary first = study::readSummary((fs::path(a.shards.front()) / "summary.json").string());
  std::string identity;
  std::vector<study::CandidateResult> rows;
  std::map<std::string, bool> seen;
  for (const auto& s : a.shards) {
    const fs::path path = fs::path(s) / "results.csv";
    const study::SearchSummary sum = study::readSummary((fs::path(s) / "summary.json").string());
    std::string line;
    {
      std::ifstream in(path);
      if (!in || !std::getline(in, line)) throw Error(SourceLoc{path.string()}, "cannot be read");
    }
    if (identity.empty()) identity = line.substr(std::min<size_t>(line.size(), 9));
    if (sum.params.size() != first.params.size()) throw Error(SourceLoc{path.string()}, "is a shard of another search");
    for (const auto& r : study::readResults(path.string(), first.params, identity)) {
      std::string k;
      for (double v : r.values) k += formatNumber(v) + ";";
      if (seen.emplace(k, true).second) rows.push_back(r);
    }
  }
  study::SearchReport rep = study::analyse(first.params, rows, first.wrench);
  const fs::path dir = a.out;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(SourceLoc{a.out}, "--out: cannot create the folder: " + ec.message());
  writeFileAtomic((dir / "results.csv").string(), study::formatResults(rep.results, first.params, identity));
  writeOutputs(dir, rep, first.params, first.units, first.scene, first.data, first.wrench, !a.noPlot);
  printReport(rep, first.params, dir);
  return rep.best ? kExitOk : kExitDiverged;
}

}  // namespace

void addSearchCommand(CLI::App& app, std::function<int()>& action) {
  auto a = std::make_shared<SearchArgs>();
  auto* cmd = app.add_subcommand("search", "search scene parameters that reproduce a measured dataset");
  cmd->footer(
      "SPEC: log:LO:HI:N | lin:LO:HI:N | V1,V2,... | refine:LO:HI (decades, finer grid, minimiser, in log) |\n"
      "refine-lin:LO:HI. Values may carry units (10Pa, \"1 MPa\"). Outputs: OUT/results.csv (one row per candidate,\n"
      "appended as they finish; rerunning resumes), OUT/summary.json (best, bracket, identifiability, stages),\n"
      "OUT/search.png. Exit 3 when no candidate finished. See docs/user-guide.md, \"Searching parameters\".");
  cmd->add_option("scene", a->scene, "scene file whose instrument is driven by a TrajectoryDriver");
  cmd->add_option("--data", a->data, "dataset folder (see `viscera dataset`)");
  cmd->add_option("--param", a->params, "ADDRESS=SPEC, e.g. phantom/fem.youngModulus=refine:100Pa:100kPa; repeatable");
  cmd->add_option("--out", a->out, "output folder (search)");
  cmd->add_option("--jobs", a->jobs, "candidates run at once (1)")->check(CLI::Range(1, 1024));
  cmd->add_option("--shard", a->shard, "run share i of N of a grid (i/N), for job arrays; join with `search merge`");
  cmd->add_option("--time-budget", a->timeBudget, "wall seconds a candidate may take before it is recorded as a timeout (0: none)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--points", a->points, "points scored per frame, chosen evenly (2000; 0: all)")->check(CLI::Range(0, 100000000));
  cmd->add_option("--max-distance", a->maxDistance, "leave out cloud points farther than this from the surface (scene units)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--length-scale", a->lengthScale, "length that makes the cloud term dimensionless (scene units; default 1 mm)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--force-scale", a->forceScale, "force that makes the force term dimensionless (scene units; default the RMS measured force)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-wrench", a->noWrench, "score the clouds only, even when the dataset has a wrench");
  cmd->add_option("--tolerance", a->tolerance, "minimiser: relative tolerance on the parameters (1e-3)")->check(CLI::PositiveNumber);
  cmd->add_option("--max-evals", a->maxEvals, "minimiser: evaluations at most (40)")->check(CLI::Range(1, 100000));
  cmd->add_option("--fine-points", a->finePoints, "points per parameter of the finer grid (7 for one parameter, 5 for several)")
      ->check(CLI::Range(0, 1000));
  cmd->add_option("--set", a->sets, "set a fixed scene attribute, ADDRESS=VALUE; repeatable");
  cmd->add_flag("--no-plot", a->noPlot, "do not run gnuplot");
  cmd->add_flag("--quiet", a->quiet, "no progress lines");
  cmd->callback([a, cmd, &action] {
    if (cmd->got_subcommand("merge")) return;
    if (a->scene.empty() || a->data.empty() || a->params.empty())
      throw CLI::ValidationError("search", "needs SCENE, --data and at least one --param");
    action = [a] { return search(*a); };
  });

  auto m = std::make_shared<MergeArgs>();
  auto* mg = cmd->add_subcommand("merge", "join the output folders of a sharded search");
  mg->add_option("shards", m->shards, "the shards' --out folders")->required();
  mg->add_option("--out", m->out, "output folder")->required();
  mg->add_flag("--no-plot", m->noPlot, "do not run gnuplot");
  mg->callback([m, &action] { action = [m] { return merge(*m); }; });
}

}  // namespace viscera
