#include "apps/viscera/SofaSuiteCommand.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <regex>
#include <sstream>

#include "apps/viscera/CliText.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Text.h"
#include "study/SofaSuite.h"

namespace viscera {

namespace {

namespace fs = std::filesystem;
using study::SuiteResult;

struct SuiteOptions {
  std::string examples, list, regressionDir, filter, csv;
  bool examplesMode = false, requirePass = false;
  int steps = 20;
  int orderRuns = 0;
};

std::string figure(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
  return q + "\"";
}

int runSuite(const SuiteOptions& o) {
  if (!fs::is_directory(o.examples)) throw Error(SourceLoc{o.examples}, "not a folder (SOFA's examples folder)");
  if (!o.csv.empty()) cli::requireParentFolder(o.csv, "--csv");
  std::regex filter;
  try {
    filter = std::regex(o.filter.empty() ? ".*" : o.filter);
  } catch (const std::regex_error& e) {
    throw Error(SourceLoc{}, "--filter: not a regular expression: " + std::string(e.what()));
  }
  std::vector<SuiteResult> results;
  std::ostringstream csv;
  csv << "scene,status,detail,steps,seconds,sofa_error,epsilon,max_distance,objects,order_runs,order_error_min,"
         "order_error_max,order_spread\n";
  auto report = [&](const SuiteResult& r, const std::string& shown) {
    std::string line = shown + "  " + study::statusName(r.status);
    if (r.status == SuiteResult::Status::Passed || r.status == SuiteResult::Status::Differs)
      line += "  error " + figure(r.sofaError) + " (limit " + figure(r.epsilon) + "), largest node distance " +
              figure(r.maxDistance) + ", " + std::to_string(r.objects) + " object(s)";
    if (r.orderRuns > 0)
      line += "; in " + std::to_string(r.orderRuns + 1) + " constraint orders error " + figure(r.orderErrorMin) + " to " +
              figure(r.orderErrorMax) + ", apart from this run by up to " + figure(r.orderSpread);
    if (!r.detail.empty()) line += "  " + printable(r.detail.substr(0, r.detail.find('\n')));
    line += "  [" + figure(r.seconds) + " s]";
    std::printf("%s\n", line.c_str());
    std::fflush(stdout);
    csv << csvField(shown) << "," << study::statusName(r.status) << "," << csvField(r.detail) << "," << r.steps << ","
        << formatNumber(r.seconds) << "," << formatNumber(r.sofaError) << "," << formatNumber(r.epsilon) << ","
        << formatNumber(r.maxDistance) << "," << r.objects << "," << r.orderRuns << "," << formatNumber(r.orderErrorMin) << ","
        << formatNumber(r.orderErrorMax) << "," << formatNumber(r.orderSpread) << "\n";
    results.push_back(r);
  };

  if (o.examplesMode) {
    for (const auto& path : study::exampleScenes(o.examples)) {
      const std::string shown = fs::relative(path, o.examples).string();
      if (!std::regex_search(shown, filter)) continue;
      report(study::runExampleScene(path, o.steps), shown);
    }
  } else {
    const std::string listPath =
        o.list.empty() ? (fs::path(o.examples) / "RegressionStateScenes.regression-tests").string() : o.list;
    // $REGRESSION_DIR: the option, else the environment variable, else `regression` beside EXAMPLES.
    std::string regressionDir = o.regressionDir;
    if (regressionDir.empty() && !std::getenv("REGRESSION_DIR")) {
      fs::path examples = fs::absolute(o.examples).lexically_normal();
      if (examples.filename().empty()) examples = examples.parent_path();  // "examples/"
      regressionDir = (examples.parent_path() / "regression").string();
    }
    const study::RegressionList list = study::readRegressionList(listPath, regressionDir);
    for (const auto& e : list.entries) {
      if (!std::regex_search(e.scene, filter)) continue;
      report(study::runRegressionScene(list, e, o.examples, o.orderRuns), e.scene);
    }
  }

  // The summary: scenes by status, and what the scenes that cannot load need most.
  std::map<std::string, int> byStatus, needs;
  for (const auto& r : results) {
    ++byStatus[study::statusName(r.status)];
    if (r.status == SuiteResult::Status::Needs) ++needs[r.detail];
  }
  std::printf("\n%zu scenes:", results.size());
  for (const auto& [s, n] : byStatus) std::printf(" %d %s;", n, s.c_str());
  std::printf("\n");
  if (!needs.empty()) {
    std::vector<std::pair<int, std::string>> ranked;
    for (const auto& [what, n] : needs) ranked.emplace_back(n, what);
    std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first != b.first ? a.first > b.first : a.second < b.second; });
    std::printf("most needed:");
    for (size_t i = 0; i < ranked.size() && i < 12; ++i) std::printf("%s %s (%d)", i ? "," : "", ranked[i].second.c_str(), ranked[i].first);
    std::printf("\n");
  }
  if (!o.csv.empty()) writeFileAtomic(o.csv, csv.str());
  if (o.requirePass)
    for (const auto& r : results)
      if (r.status != SuiteResult::Status::Passed && r.status != SuiteResult::Status::Runs) return 1;
  return 0;
}

}  // namespace

void addSofaSuiteCommand(CLI::App& app, std::function<int()>& action) {
  auto o = std::make_shared<SuiteOptions>();
  auto* cmd = app.add_subcommand("sofa-suite", "run SOFA's example scenes or its state-regression suite and compare");
  cmd->footer(
      "Regression (default): every scene of the list (EXAMPLES/RegressionStateScenes.regression-tests unless --list) is\n"
      "run for its steps and compared with SOFA's own states: status passed (SOFA's criterion within the list's EPSILON),\n"
      "differs, needs COMPONENT, error, diverged or no reference; the largest node distance is printed beside it.\n"
      "The references are found from the list's $REGRESSION_DIR line: --regression-dir, else the environment variable\n"
      "REGRESSION_DIR, else the folder `regression` beside EXAMPLES.\n"
      "--order-spread K: each regression scene with a constraint solver is run K more times, its Gauss-Seidel sweeps\n"
      "visiting the constraints in other (seeded) orders; the line adds SOFA's criterion over all those runs and the\n"
      "largest it gives between this run and another. Where the solve stops before it converges the result depends on\n"
      "that order, which SOFA sets by its own bookkeeping: a difference within the spread is the solver's, not the model's.\n"
      "--examples: every .scn/.xml scene under EXAMPLES (include fragments left out) is loaded and run --steps steps.\n"
      "Files the scenes name are found as SOFA finds them (scene folder, then the data search path). Outputs the\n"
      "scenes write (exporters) go to a temporary folder.");
  cmd->add_option("examples", o->examples, "SOFA's examples folder")->required();
  cmd->add_option("--list", o->list, "the regression list (default: EXAMPLES/RegressionStateScenes.regression-tests)");
  cmd->add_option("--regression-dir", o->regressionDir, "the folder $REGRESSION_DIR stands for in the list");
  auto* examplesFlag =
      cmd->add_flag("--examples", o->examplesMode, "load and run every example scene instead of the regression list");
  cmd->add_option("--steps", o->steps, "steps per example scene (20)")->check(CLI::Range(0, 1000000));
  cmd->add_option("--order-spread", o->orderRuns, "run scenes with constraints K more times in other constraint orders (0)")
      ->check(CLI::Range(0, 1000))
      ->excludes(examplesFlag);
  cmd->add_option("--filter", o->filter, "only scenes whose path matches this regular expression");
  cmd->add_option("--csv", o->csv, "also write the table as CSV");
  cmd->add_flag("--require-pass", o->requirePass, "exit 1 unless every scene run passed (or, with --examples, ran)");
  cmd->callback([o, &action] { action = [o] { return runSuite(*o); }; });
}

}  // namespace viscera
