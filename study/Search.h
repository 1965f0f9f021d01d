// Parameter search against a measured dataset (docs/user-guide.md, "Searching parameters").
//
// Each candidate is the scene with some attributes set by address (the parsed description is
// edited, never the text), replayed through the dataset and scored (study/Replay.h). A search is
// either a grid (the product of every parameter's values) or a refinement that follows the
// dissertation's procedure (§4.2.4): decades first, then a finer grid between the best decade's
// neighbours, then a bracketing minimiser (Brent's method in 1-D, NLopt's BOBYQA in several
// dimensions) to a tolerance. Finished candidates are appended to results.csv atomically, so a
// search that is stopped and run again skips them.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/SceneDesc.h"
#include "study/Replay.h"

namespace viscera::study {

enum class Scale { Linear, Log };

// One searched attribute: "ADDRESS=SPEC", values in the scene's units.
//   log:LO:HI:N        N values spaced evenly in log(value) from LO to HI
//   lin:LO:HI:N        N values spaced evenly from LO to HI
//   V1,V2,...          the values given
//   refine:LO:HI       refinement over [LO, HI] in log(value): decades, finer grid, minimiser
//   refine-lin:LO:HI   the same in value (for bounded quantities such as Poisson's ratio)
// Values may carry units ("10Pa", "1 MPa"); they are converted for the addressed attribute.
struct ParamSpec {
  std::string address;
  std::string spec;               // the SPEC as given
  Scale scale = Scale::Linear;
  bool refine = false;
  std::vector<double> grid;       // grid: the values, increasing
  double lo = 0, hi = 0;          // the range searched
  std::string unit;               // the attribute's unit in the scene's base units ("g mm^-1 s^-2"), for reports
};

// Parses "ADDRESS=SPEC" against the scene: the address must name one element with that
// attribute, a real number. Throws viscera::Error naming the option for a bad spec.
ParamSpec parseParam(const std::string& argument, const SceneDesc& scene);

// The coordinate a parameter is searched in: log10(value) or value.
double toAxis(const ParamSpec& p, double v);
double fromAxis(const ParamSpec& p, double u);

struct CandidateResult;

// Where candidates run: threads of this process (the default), or the ranks of an MPI job
// (study/Distributed.h). Results do not depend on where.
class CandidateExecutor {
 public:
  virtual ~CandidateExecutor() = default;
  using Evaluate = std::function<CandidateResult(const std::vector<double>&)>;
  using Done = std::function<void(CandidateResult)>;
  // Evaluates every candidate (parameter values), calling `done` with each result as it
  // finishes, one call at a time. An input error of a candidate is rethrown after the others stop.
  virtual void run(const std::vector<std::vector<double>>& candidates, const Evaluate& evaluate, const Done& done) = 0;
};

struct SearchOptions {
  ReplayOptions replay;           // score options, time budget (threads is per candidate)
  int jobs = 1;                   // candidates run at once (threads)
  int shard = 0, shards = 1;      // run only candidates k with k % shards == shard (grids only)
  double tolerance = 1e-3;        // minimiser: relative tolerance on the parameters
  int maxEvaluations = 40;        // minimiser: evaluations at most
  int finePoints = 0;             // points per parameter of the finer grid (0: 7 for one parameter, 5 for several)
  CandidateExecutor* executor = nullptr;  // null: `jobs` threads here
};

// One finished candidate, as a results.csv row.
struct CandidateResult {
  std::string stage;              // "grid", "decades", "fine", "minimise"
  std::vector<double> values;     // per parameter, scene units
  ReplayScore::Status status = ReplayScore::Status::Ok;
  std::string reason;
  double metric = ReplayScore::nan, metricSe = ReplayScore::nan, cloudTerm = ReplayScore::nan,
         forceTerm = ReplayScore::nan;
  double cloudRms = ReplayScore::nan, cloudRmsContact = ReplayScore::nan, cloudRmsFree = ReplayScore::nan;
  double forceRms = ReplayScore::nan, forceRmsContact = ReplayScore::nan, forceRmsFree = ReplayScore::nan;
  int frames = 0, samples = 0, steps = 0;
  double wallSeconds = 0;
  bool ok() const { return status == ReplayScore::Status::Ok; }
};

// Builds and replays one candidate: the scene (a replay description) with each parameter set to
// its value. Divergence, timeouts and numerical failures are results; input errors throw.
CandidateResult evaluateCandidate(const SceneDesc& replayScene, const PreparedDataset& data,
                                  const std::vector<ParamSpec>& params, const ReplayOptions& options,
                                  const std::vector<double>& values);

// The results table: a first line "# search <identity>" naming the scene, dataset and scoring, a
// header, then one row per candidate. Values are written with 17 significant digits, so that a
// resumed search finds its candidates exactly.
std::string resultsHeader(const std::vector<ParamSpec>& params);
std::string formatResult(const CandidateResult& r);
// One row back (for `params` parameters); std::invalid_argument for a malformed row.
CandidateResult parseResult(const std::string& row, size_t params);
// Reads a results table written for `params`; Error naming the file and line for another search's
// table (a different identity or header) or a malformed row.
std::vector<CandidateResult> readResults(const std::string& path, const std::vector<ParamSpec>& params,
                                         const std::string& identity);
std::string formatResults(const std::vector<CandidateResult>& rows, const std::vector<ParamSpec>& params,
                          const std::string& identity);

// How well one parameter is determined: the profile of the metric along it (the best metric of
// the candidates with each value) against the noise floor.
struct ParamReport {
  std::string address;
  double best = ReplayScore::nan;
  double lo = ReplayScore::nan, hi = ReplayScore::nan;  // values whose profile stays under best + noise floor
  bool loAtEdge = false, hiAtEdge = false;              // the interval reaches the end of the searched range
  double curvature = ReplayScore::nan;                  // d2 metric / d axis^2 at the best (axis: log10 or value)
  bool identifiable = false;
  std::string statement;                                // a sentence for the user
};

struct StageReport {
  std::string name;
  int candidates = 0;
  std::vector<double> best;  // empty when no candidate of the stage finished ok
  double metric = ReplayScore::nan;
};

struct SearchReport {
  std::vector<CandidateResult> results;  // every candidate of the search, in results.csv order
  std::optional<CandidateResult> best;
  double noiseFloor = ReplayScore::nan;  // 2 x the best candidate's metric standard error
  std::vector<ParamReport> params;
  std::vector<StageReport> stages;
  int ok = 0, diverged = 0, timeout = 0;
  bool complete = true;                  // false for one shard of a refinement
};

// Tells a caller how the search is going.
struct SearchProgress {
  virtual ~SearchProgress() = default;
  virtual void stage(const std::string& name, int candidates, int alreadyDone) {}
  // `total` is 0 where the stage's count is not known in advance (the minimiser).
  virtual void finished(const CandidateResult& r, int done, int total) {}
};

// Checks that the parameters and options make one search (all grids or all refinements; shards
// only of a grid); Error naming the option otherwise. runSearch checks this too.
void validateSearch(const std::vector<ParamSpec>& params, const SearchOptions& options);

// Runs (or resumes) a search. `results` is the results.csv path: rows already there are reused;
// each newly finished candidate is appended (the file rewritten atomically). Errors in the scene
// or a candidate's attribute values throw viscera::Error before any candidate runs.
SearchReport runSearch(const SceneDesc& scene, const PreparedDataset& data, const std::vector<ParamSpec>& params,
                       const SearchOptions& options, const std::string& results, const std::string& identity,
                       SearchProgress* progress = nullptr);

// The report of finished results (also for merged shards).
SearchReport analyse(const std::vector<ParamSpec>& params, std::vector<CandidateResult> results, bool hasWrench);

// summary.json: best (address -> value in the scene's units), metric, noise floor, bracket per
// parameter, identifiability, stages, counts.
// It also lists the parameters (address, spec, scale, range) and whether the force was scored, so
// that `viscera search merge` can analyse shards without the scene.
std::string summaryJson(const SearchReport& report, const std::vector<ParamSpec>& params, const std::string& units,
                        const std::string& scene, const std::string& data, bool wrench);

// What summary.json records of a search, read back (for merging shards).
struct SearchSummary {
  std::vector<ParamSpec> params;
  std::string units, scene, data;
  bool wrench = false;
};
SearchSummary readSummary(const std::string& path);

}  // namespace viscera::study
