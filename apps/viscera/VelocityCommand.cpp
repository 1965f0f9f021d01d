// `viscera velocity compare`: the two-encoder bench of dissertation Appendix II in simulation. A
// 600-line encoder (the reference) and a 16-line encoder with imperfections sit on one shaft; the
// host reads both FPGAs at a fixed rate and estimates the 16-line encoder's velocity by each
// method. Writes velocity.csv, summary.json and (through gnuplot) velocity.png like Fig. II-8.
#include "apps/viscera/VelocityCommand.h"
#include "core/Files.h"
#include "apps/viscera/CliText.h"
#include "apps/viscera/Gnuplot.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/scene/CsvTable.h"
#include "robot/encoder/Motion.h"
#include "robot/encoder/VelocityBench.h"
#include "core/Text.h"

namespace viscera {
namespace {

namespace fs = std::filesystem;
namespace enc = robot::encoder;

struct CompareOptions {
  enc::BenchSpec spec;
  std::string out, motion, format = "rev6";
  double duration = enc::kBenchDuration;
  double accThresholdTicks = 2000;
  bool noPlot = false;
};

// Checks an encoder with the library's rules, naming the options instead of the spec's fields.
void checkEncoder(const enc::EncoderSpec& spec, const std::map<std::string, std::string>& options) {
  try {
    enc::validate(spec);
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    const size_t colon = message.find(": ");
    const auto it = options.find(message.substr(0, colon));
    throw Error("velocity compare: " + (it == options.end() ? message : it->second + message.substr(colon)));
  }
}

void requirePositive(double value, const char* option) {
  if (!(std::isfinite(value) && value > 0)) throw Error(std::string("velocity compare: ") + option + ": must be a positive number");
}

struct Motion {
  enc::JointMotion motion;
  double start = 0, end = 0;
  std::string name;
};

Motion loadMotion(const CompareOptions& o) {
  if (o.motion.empty()) {
    requirePositive(o.duration, "--duration");
    return {enc::benchMotion(), 0, o.duration, "built-in"};
  }
  enc::MotionFile file = enc::readMotionCsv(o.motion);
  return {std::move(file.motion), file.start, file.end, o.motion};
}

std::string formatCsv(const enc::BenchResult& r) {
  std::string text = "t,exact,truth";
  for (auto e : r.estimators) {
    text += ',';
    text += enc::benchEstimatorName(e);
  }
  text += '\n';
  for (size_t k = 0; k < r.time.size(); ++k) {
    text += formatNumber(r.time[k]);
    for (double v : {r.exact[k], r.truth[k]}) {
      text += ',';
      text += formatNumber(v);
    }
    for (const auto& series : r.estimates) {
      text += ',';
      text += formatNumber(series[k]);
    }
    text += '\n';
  }
  return text;
}

struct RmsRow {
  std::string name;
  double vsTruth = 0, vsExact = 0;
};

std::vector<RmsRow> rmsRows(const enc::BenchResult& r) {
  std::vector<RmsRow> rows;
  for (size_t e = 0; e < r.estimators.size(); ++e)
    rows.push_back({enc::benchEstimatorName(r.estimators[e]), enc::rms(r.estimates[e], r.truth), enc::rms(r.estimates[e], r.exact)});
  return rows;
}

std::string jsonNumber(double v) { return std::isfinite(v) ? formatNumber(v) : "null"; }

std::string encoderJson(const enc::EncoderSpec& s, size_t edges) {
  return "{\"lines\": " + jsonNumber(s.lines) + ", \"gear_ratio\": " + jsonNumber(s.gearRatio) + ", \"duty_a\": " + jsonNumber(s.dutyA) +
         ", \"duty_b\": " + jsonNumber(s.dutyB) + ", \"phase_deg\": " + jsonNumber(s.phaseB) + ", \"edges\": " + std::to_string(edges) + "}";
}

std::string formatSummary(const CompareOptions& o, const Motion& m, const enc::BenchResult& r, const std::vector<RmsRow>& rows) {
  std::ostringstream j;
  j << "{\n";
  j << "  \"motion\": " << cli::jsonString(m.name) << ",\n";
  j << "  \"start_s\": " << jsonNumber(m.start) << ",\n";
  j << "  \"end_s\": " << jsonNumber(m.end) << ",\n";
  j << "  \"reads\": " << r.time.size() << ",\n";
  j << "  \"read_rate_hz\": " << jsonNumber(o.spec.readRate) << ",\n";
  j << "  \"format\": " << cli::jsonString(o.format) << ",\n";
  j << "  \"clock_hz\": " << jsonNumber(o.spec.test.clockHz) << ",\n";
  j << "  \"acceleration_threshold_ticks\": " << jsonNumber(o.accThresholdTicks) << ",\n";
  j << "  \"truth_encoder\": " << encoderJson(o.spec.truth, r.truthEdges) << ",\n";
  j << "  \"test_encoder\": " << encoderJson(o.spec.test, r.testEdges) << ",\n";
  j << "  \"truth_rms_vs_exact_deg_s\": " << jsonNumber(enc::rms(r.truth, r.exact)) << ",\n";
  j << "  \"rms_deg_s\": {\n";
  for (size_t i = 0; i < rows.size(); ++i)
    j << "    " << cli::jsonString(rows[i].name) << ": {\"vs_truth\": " << jsonNumber(rows[i].vsTruth)
      << ", \"vs_exact\": " << jsonNumber(rows[i].vsExact) << "}" << (i + 1 < rows.size() ? "," : "") << "\n";
  j << "  }\n}\n";
  return j.str();
}

std::string formatTable(const CompareOptions& o, const enc::BenchResult& r, const std::vector<RmsRow>& rows) {
  std::ostringstream t;
  t << std::fixed << std::setprecision(2);
  const std::string truthName = formatNumber(o.spec.truth.lines) + "-line";
  t << "RMS error of the " << formatNumber(o.spec.test.lines) << "-line estimates (deg/s), " << r.time.size() << " reads at "
    << formatNumber(o.spec.readRate) << " Hz, " << o.format << " registers\n";
  t << std::left << std::setw(18) << "estimator" << std::right << std::setw(14) << ("vs " + truthName) << std::setw(12) << "vs exact"
    << "\n";
  for (const auto& row : rows) t << std::left << std::setw(18) << row.name << std::right << std::setw(14) << row.vsTruth << std::setw(12) << row.vsExact << "\n";
  t << "reference (" << truthName << " full cycle) vs exact: " << enc::rms(r.truth, r.exact) << "\n";
  return t.str();
}

// The Fig. II-8 plot: three panels, each an estimate of the encoder under test (red) over the
// reference (black). Runs from the output folder; the PNG name comes in as `outfile`.
std::string formatGnuplot(const CompareOptions& o, const enc::BenchResult& r, const std::vector<RmsRow>& rows) {
  const std::string truthTitle = formatNumber(o.spec.truth.lines) + " lines";
  const std::string testTitle = formatNumber(o.spec.test.lines) + " lines";
  struct Panel {
    enc::BenchEstimator estimator;
    const char* title;
  };
  const Panel panels[] = {{enc::BenchEstimator::Quarter, "(a) quarter cycle"},
                          {enc::BenchEstimator::Full, "(b) full cycle"},
                          {enc::BenchEstimator::FullAcceleration, "(c) full cycle with acceleration"}};
  // One vertical range for the three panels, so that their errors compare at a glance.
  double yLow = 0, yHigh = 0;
  auto widen = [&](const std::vector<double>& series) {
    for (double v : series) yLow = std::min(yLow, v), yHigh = std::max(yHigh, v);
  };
  widen(r.truth);
  for (const Panel& p : panels)
    for (size_t e = 0; e < r.estimators.size(); ++e)
      if (r.estimators[e] == p.estimator) widen(r.estimates[e]);
  const double margin = 0.05 * (yHigh - yLow) + 1;
  yLow -= margin;
  yHigh += margin;

  std::ostringstream g;
  g << "# Velocity of the " << testTitle << " encoder (red) against the " << truthTitle
    << " reference (black), written by viscera velocity compare.\n"
    << "# Re-plot with: gnuplot velocity.gp (writes velocity.png next to velocity.csv)\n"
    << "if (!exists(\"outfile\")) outfile = \"velocity.png\"\n"
    << "set terminal pngcairo size 1000,1100 font \",10\"\n"
    << "set output outfile\n"
    << "set datafile separator \",\"\n"
    << "set grid\n"
    << "set key top right\n"
    << "set ylabel \"velocity (deg/s)\"\n"
    << "set yrange [" << formatNumber(yLow) << ":" << formatNumber(yHigh) << "]\n"
    << "set multiplot layout 3,1\n";
  for (const Panel& p : panels) {
    size_t index = 0;
    while (r.estimators[index] != p.estimator) ++index;
    // Columns: t, exact, truth, then the estimators in order.
    const size_t column = 4 + index;
    g << std::fixed << std::setprecision(2);
    g << "set title \"" << p.title << ": RMS error " << rows[index].vsTruth << " deg/s\"\n";
    if (&p == &panels[2]) g << "set xlabel \"time (s)\"\n";
    g << "plot \"velocity.csv\" skip 1 using 1:3 with lines lw 1.5 lc rgb \"black\" title \"" << truthTitle << "\", \\\n"
      << "     \"velocity.csv\" skip 1 using 1:" << column << " with lines lw 1.2 lc rgb \"red\" title \"" << testTitle << "\"\n";
  }
  g << "unset multiplot\n";
  return g.str();
}

int compare(CompareOptions o) {
  if (o.format == "rev6") o.spec.format = enc::RegisterFormat::Rev6;
  else if (o.format == "rev7") o.spec.format = enc::RegisterFormat::Rev7;
  else throw Error("velocity compare: --format: '" + o.format + "' is not rev6 or rev7");
  requirePositive(o.spec.readRate, "--rate");
  requirePositive(o.spec.maxStep, "--step");
  if (!(std::isfinite(o.accThresholdTicks) && o.accThresholdTicks >= 0))
    throw Error("velocity compare: --acc-threshold: must be a number of clock ticks, 0 or more");
  o.spec.estimator.accelerationMinQuarter = o.accThresholdTicks / enc::kFpgaClockHz;
  checkEncoder(o.spec.test, {{"lines", "--lines"}, {"dutyA", "--duty-a"}, {"dutyB", "--duty-b"}, {"phaseB", "--phase"}});
  checkEncoder(o.spec.truth, {{"lines", "--truth-lines"}});
  const Motion motion = loadMotion(o);
  // The edge search samples the velocity every --step: bounded before the work starts.
  const double samples = (motion.end - motion.start) / o.spec.maxStep;
  if (samples > 1e8)
    throw Error("velocity compare: --step: " + formatNumber(o.spec.maxStep) + " s over the motion's " +
                formatNumber(motion.end - motion.start) + " s makes " + formatNumber(samples) +
                " velocity samples; at most 1e8 (a longer --step or a shorter motion)");

  const fs::path dir = o.out;
  if (fs::exists(dir) && !fs::is_directory(dir)) throw Error(SourceLoc{o.out}, "--out must be a folder, and this is a file");

  enc::BenchResult result;
  try {
    result = enc::runBench(motion.motion, motion.start, motion.end, o.spec);
  } catch (const std::invalid_argument& e) {
    // Only the amount of work is left to reject here (the rest was checked above).
    const std::string message = e.what();
    if (message.rfind("readRate: ", 0) == 0) throw Error("velocity compare: --rate: " + message.substr(10) + "; lower the rate or shorten the motion");
    if (message.rfind("edges: ", 0) == 0)
      throw Error("velocity compare: " + message.substr(7) + "; use fewer --lines / --truth-lines or a shorter motion");
    throw Error("velocity compare: " + message);
  }
  const std::vector<RmsRow> rows = rmsRows(result);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(SourceLoc{o.out}, "cannot create the output folder: " + ec.message());
  writeFileAtomic((dir / "velocity.csv").string(), formatCsv(result));
  writeFileAtomic((dir / "summary.json").string(), formatSummary(o, motion, result, rows));
  std::cout << formatTable(o, result, rows);
  if (!o.noPlot) {
    writeFileAtomic((dir / "velocity.gp").string(), formatGnuplot(o, result, rows));
    plotWithGnuplot(dir, "velocity.gp", "velocity.png");
  }
  std::cerr << "wrote " << (dir / "velocity.csv").string() << ", summary.json" << (o.noPlot ? "" : ", velocity.gp and velocity.png")
            << " (edges: " << result.testEdges << " on " << formatNumber(o.spec.test.lines) << " lines, " << result.truthEdges
            << " on " << formatNumber(o.spec.truth.lines) << ")\n";
  return kExitOk;
}

}  // namespace

void addVelocityCommand(CLI::App& app, std::function<int()>& action) {
  auto* velocity = app.add_subcommand("velocity", "encoder velocity estimation");
  velocity->require_subcommand(1);
  auto o = std::make_shared<CompareOptions>();
  auto& s = o->spec;
  auto* cmd = velocity->add_subcommand("compare", "compare velocity estimators on a simulated two-encoder bench (Appendix II)");
  cmd->footer(
      "One shaft carries a reference encoder (ideal, --truth-lines) and an encoder under test with imperfect channels. The host\n"
      "reads both FPGAs at --rate; the test encoder's velocity is estimated by fixed-time difference, quarter cycle, full cycle,\n"
      "full cycle with acceleration (II.7) and, with rev7 registers, the running-counter form (II.8). Velocities in deg/s.\n"
      "Writes DIR/velocity.csv, DIR/summary.json and, unless --no-plot, DIR/velocity.gp and DIR/velocity.png (needs gnuplot).");
  cmd->add_option("--out", o->out, "output folder (created if missing)")->required();
  auto* motion = cmd->add_option("--motion", o->motion, "joint motion as a CSV of t,theta rows (s, rad); default: the built-in motion");
  cmd->add_option("--duration", o->duration, "length of the built-in motion (s)")->capture_default_str()->excludes(motion);
  cmd->add_option("--rate", s.readRate, "host reads per second")->capture_default_str();
  cmd->add_option("--format", o->format, "register format the host reads: rev6 (3.072 MHz, 2 quadlets) or rev7 (49.152 MHz, 4)")
      ->capture_default_str();
  cmd->add_option("--lines", s.test.lines, "lines per revolution of the encoder under test")->capture_default_str();
  cmd->add_option("--duty-a", s.test.dutyA, "fraction of a cycle that channel A of the encoder under test is high")->capture_default_str();
  cmd->add_option("--duty-b", s.test.dutyB, "fraction of a cycle that channel B of the encoder under test is high")->capture_default_str();
  cmd->add_option("--phase", s.test.phaseB, "electrical degrees from A's rise to B's rise on the encoder under test")->capture_default_str();
  cmd->add_option("--truth-lines", s.truth.lines, "lines per revolution of the reference encoder")->capture_default_str();
  cmd->add_option("--acc-threshold", o->accThresholdTicks,
                  "acceleration is used only when the last quarter cycle lasts at least this many 49.152 MHz ticks")
      ->capture_default_str();
  cmd->add_option("--step", s.maxStep, "velocity sampling step of the edge search (s); reversals must be further apart")
      ->capture_default_str();
  cmd->add_flag("--no-plot", o->noPlot, "do not run gnuplot");
  cmd->callback([o, &action] { action = [o] { return compare(*o); }; });
}

}  // namespace viscera
