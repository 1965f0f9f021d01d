// `viscera audit SCENE --data DATA`: where the scene disagrees with the dataset, which missing
// effect explains it, and the scene with it added (study/Audit.h). Writes OUT/report.json,
// OUT/report.md and OUT/augmented.xml; nothing is written when the inputs are unusable.
#include "apps/viscera/AuditCommand.h"
#include "apps/viscera/AuditBench.h"
#include "apps/viscera/Gnuplot.h"
#include "apps/viscera/Html.h"

#include <CLI/CLI.hpp>
#include <tbb/info.h>

#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Text.h"
#include "io/scene/SceneReader.h"
#include "io/scene/SceneWriter.h"
#include "io/scene/Transform.h"
#include "study/Audit.h"

namespace viscera {
namespace {

namespace fs = std::filesystem;

struct AuditArgs {
  std::string scene, data, out = "audit";
  std::vector<std::string> effects, sets;
  int jobs = 1, rounds = 3, points = 2000, maxEvals = 16, residualFrames = 150;
  double train = 0.6, alpha = 0.05;
  bool noWrench = false, quiet = false, noPlot = false, noResiduals = false;
};

struct Log : study::AuditProgress {
  explicit Log(bool quiet) : quiet_(quiet) {}
  void message(const std::string& line) override {
    if (!quiet_) std::cerr << line << "\n";
  }
  bool quiet_;
};

// residual.csv: each frame's RMS residual (mm) before and after, and its phase.
std::string residualTable(const study::AuditReport& r) {
  std::ostringstream t;
  t << "time,before_mm,after_mm,phase\n";
  const auto& b = r.before;
  const auto& a = r.after;
  for (size_t k = 0; k < b.frameTimes.size(); ++k) {
    t << formatNumber(b.frameTimes[k]) << "," << formatNumber(b.frameRmsMm[k]) << ",";
    if (k < a.frameTimes.size() && a.frameTimes[k] == b.frameTimes[k]) t << formatNumber(a.frameRmsMm[k]);
    t << "," << study::Localisation::phaseName(b.framePhases[k]) << "\n";
  }
  return t.str();
}

// top_residual.csv: the top surface's mean signed residual per grid cell (centre x, y in mm),
// nominal and augmented; NaN where no cloud point fell. Empty without a top surface in view.
std::string topResidualTable(const study::AuditReport& r) {
  if (!r.topBefore || !r.topAfter || r.topBefore->nx != r.topAfter->nx || r.topBefore->ny != r.topAfter->ny) return "";
  const study::TopResidualMap& b = *r.topBefore;
  std::ostringstream t;
  t << "x_mm,y_mm,before_mm,after_mm\n";
  for (int j = 0; j < b.ny; ++j)
    for (int i = 0; i < b.nx; ++i)
      t << formatNumber(b.x0 + (i + 0.5) * b.cell) << "," << formatNumber(b.y0 + (j + 0.5) * b.cell) << ","
        << formatNumber(b.mean(i, j)) << "," << formatNumber(r.topAfter->mean(i, j)) << "\n";
  return t.str();
}

// top_residual.gp: the two maps side by side on one symmetric colour scale (blue: the cloud lies
// inside the simulated surface, red: outside).
std::string topResidualScript(const study::AuditReport& r) {
  double most = 0;
  for (const auto* m : {&*r.topBefore, &*r.topAfter})
    for (int j = 0; j < m->ny; ++j)
      for (int i = 0; i < m->nx; ++i)
        if (std::isfinite(m->mean(i, j))) most = std::max(most, std::abs(m->mean(i, j)));
  if (!(most > 0)) most = 1;
  std::ostringstream g;
  g << "# The top surface's residual before and after, written by viscera audit.\n"
    << "# Re-plot with: gnuplot top_residual.gp (writes top_residual.png next to top_residual.csv)\n"
    << "if (!exists(\"outfile\")) outfile = \"top_residual.png\"\n"
    << "set terminal pngcairo size 1200,520 font \",10\"\n"
    << "set output outfile\n"
    << "set datafile separator \",\"\n"
    << "set datafile missing \"nan\"\n"
    << "set multiplot layout 1,2 title \"Mean signed residual on the top surface, all frames (mm; + the cloud lies outside "
       "the model)\"\n"
    << "set size ratio -1\n"
    << "set palette defined (-1 \"blue\", 0 \"white\", 1 \"red\")\n"
    << "set cbrange [" << -most << ":" << most << "]\n"
    << "set xlabel \"x (mm)\"\nset ylabel \"y (mm)\"\n"
    << "set title \"nominal scene\"\n"
    << "set style fill solid noborder\n"
    << "h = " << r.topBefore->cell / 2 << "  # half a cell (mm)\n"
    << "plot \"top_residual.csv\" skip 1 using 1:2:(h):(h):3 with boxxyerror palette notitle\n"
    << "set title \"augmented scene\"\n"
    << "plot \"top_residual.csv\" skip 1 using 1:2:(h):(h):4 with boxxyerror palette notitle\n"
    << "unset multiplot\n";
  return g.str();
}

// audit.gp: the residual over time before and after, with the noise floor and the training /
// held-out split; below it the first round's ranking (held-out BIC change per candidate).
std::string plotScript(const study::AuditReport& r) {
  std::ostringstream g;
  g << "# The model audit's residual over time and its ranking, written by viscera audit.\n"
    << "# Re-plot with: gnuplot audit.gp (writes audit.png next to residual.csv)\n"
    << "if (!exists(\"outfile\")) outfile = \"audit.png\"\n"
    << "set terminal pngcairo size 1000,900 font \",10\"\n"
    << "set output outfile\n"
    << "set datafile separator \",\"\n"
    << "set multiplot layout 2,1\n"
    << "set grid\n"
    << "set title \"RMS cloud -> surface distance per frame\"\n"
    << "set xlabel \"time (s)\"\n"
    << "set ylabel \"mm\"\n"
    << "set yrange [0:*]\n"
    << "set key bottom right\n"
    << "set arrow from first " << r.splitTime << ", graph 0 to first " << r.splitTime
    << ", graph 1 nohead dt 3 lc rgb \"gray60\"\n"
    << "set label \"held out ->\" at first " << r.splitTime << ", graph 0.95 offset 0.5,0 tc rgb \"gray40\"\n"
    << "plot \"residual.csv\" skip 1 using 1:2 with lines lw 1.2 lc rgb \"red\" title \"nominal scene\", \\\n"
    << "     \"residual.csv\" skip 1 using 1:3 with lines lw 1.2 lc rgb \"blue\" title \"augmented scene\", \\\n"
    << "     " << r.noiseFloorMm << " with lines dt 2 lc rgb \"gray40\" title \"noise floor\"\n"
    << "unset arrow\nunset label\nset autoscale y\n";
  if (!r.rounds.empty() && !r.rounds.front().candidates.empty()) {
    const auto& c = r.rounds.front().candidates;
    g << "set title \"Round 1: held-out BIC change per effect (negative favours the effect)\"\n"
      << "set xlabel \"\"\nset ylabel \"delta BIC\"\n"
      << "set style fill solid 0.6\nset boxwidth 0.6\nunset key\n"
      << "set xtics rotate by -30 noenhanced\n"
      << "set datafile separator whitespace\n"
      << "$ranking << EOD\n";
    for (size_t k = 0; k < c.size(); ++k) g << k << " " << c[k].effect << " " << (c[k].status == "ok" ? c[k].deltaBic : 0.0) << "\n";
    g << "EOD\n"
      << "plot $ranking using 1:3:xtic(2) with boxes lc rgb \"steelblue\"\n";
  }
  g << "unset multiplot\n";
  return g.str();
}

int audit(const AuditArgs& a) {
  SceneDesc scene = io::readScene(a.scene);
  for (const auto& s : a.sets) scene.applySetting(s);
  study::AuditOptions o;
  o.jobs = a.jobs;
  o.rounds = a.rounds;
  o.effects = a.effects;
  o.trainFraction = a.train;
  o.maxEvaluations = a.maxEvals;
  o.alpha = a.alpha;
  o.residualFrames = a.residualFrames;
  o.replay.threads = std::max(1, tbb::info::default_concurrency() / std::max(1, a.jobs));
  o.replay.score.maxPoints = a.points;
  o.replay.score.useWrench = !a.noWrench;
  const study::PreparedDataset data = study::prepareDataset(a.data, o.replay.score);
  const fs::path dir = a.out;
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) throw Error(SourceLoc{a.out}, "--out: is a file, not a folder");
  const fs::path parent = fs::absolute(dir).parent_path();
  if (!fs::is_directory(parent, ec)) throw Error(SourceLoc{a.out}, "--out: the folder " + parent.string() + " does not exist");

  // The scene and the dataset are usable (read above); the residual series are written as the
  // audit replays.
  const FolderLock lock(dir.string());
  if (!a.noResiduals) {
    o.residualsBefore = (dir / "residuals" / "before").string();
    o.residualsAfter = (dir / "residuals" / "after").string();
  }
  Log log(a.quiet);
  const study::AuditReport r = study::runAudit(scene, data, o, &log);

  // The augmented scene goes to OUT; report.json names it.
  SceneDesc augmented = r.augmented;
  const fs::path sceneDir = fs::absolute(a.scene).parent_path();
  const fs::path augmentedPath = fs::absolute(dir) / (fs::path(a.scene).stem().string() + "_audited.xml");
  // Input files are named relative to the scene's folder: absolute in the new file, so that it
  // runs from anywhere. Outputs (exporters, cameras) stay relative to --out.
  absolutiseInputs(augmented.root, sceneDir);
  io::writeScene(augmentedPath.string(), augmented,
                 "Written by viscera audit from " + fs::absolute(a.scene).string() + " and the dataset " +
                     fs::absolute(a.data).string() + "; effects added: " +
                     (r.found.empty() ? std::string("none") : [&] {
                       std::string s;
                       for (const auto& f : r.found) s += (s.empty() ? "" : ", ") + f;
                       return s;
                     }()));
  if (r.cloudCorrection) {
    // The registration effect: the dataset's camera -> scene transform, corrected.
    const RigidTransform corrected = data.data.cameraToScene ? *r.cloudCorrection * *data.data.cameraToScene : *r.cloudCorrection;
    writeTransform((dir / "camera_to_scene_corrected.txt").string(), corrected,
                   "camera -> scene corrected by viscera audit (registration effect)");
  }
  writeFileAtomic((dir / "residual.csv").string(), residualTable(r));
  writeFileAtomic((dir / "report.json").string(),
                  study::auditJson(r, fs::absolute(a.scene).string(), fs::absolute(a.data).string(), augmentedPath.string()));
  const std::string topTable = topResidualTable(r);
  if (!topTable.empty()) writeFileAtomic((dir / "top_residual.csv").string(), topTable);
  std::string md = study::auditMarkdown(r, fs::absolute(a.scene).string(), fs::absolute(a.data).string(), augmentedPath.string());
  if (!a.noPlot && !topTable.empty())
    md += "\n## Residual on the top surface\n\nThe mean signed residual of the cloud points on the top surface over all "
          "frames, nominal and augmented scene (`top_residual.csv`).\n\n![top surface residual](top_residual.png)\n";
  writeFileAtomic((dir / "report.md").string(), md);
  writeFileAtomic((dir / "report.html").string(), markdownPage("Model audit", md, a.noPlot ? "" : "audit.png"));
  if (!a.noPlot) {  // last: a missing gnuplot costs the picture only
    writeFileAtomic((dir / "audit.gp").string(), plotScript(r));
    plotWithGnuplot(dir, "audit.gp", "audit.png");
    if (!topTable.empty()) {
      writeFileAtomic((dir / "top_residual.gp").string(), topResidualScript(r));
      plotWithGnuplot(dir, "top_residual.gp", "top_residual.png");
    }
  }
  std::cout << r.verdict;
  if (!r.found.empty()) {
    std::cout << ":";
    for (const auto& f : r.found) std::cout << " " << f;
  }
  std::cout << " (noise floor " << r.noiseFloorMm << " mm, remaining gap " << r.remainingGapMm << " mm)\n";
  std::cerr << "wrote " << (dir / "report.md").string() << ", report.html, report.json, residual.csv"
            << (topTable.empty() ? "" : ", top_residual.csv") << (a.noPlot ? "" : ", audit.png")
            << (a.noPlot || topTable.empty() ? "" : ", top_residual.png") << " and " << augmentedPath.string() << "\n";
  return kExitOk;
}

}  // namespace

void addAuditCommand(CLI::App& app, std::function<int()>& action) {
  auto a = std::make_shared<AuditArgs>();
  auto* cmd = app.add_subcommand("audit", "find where a scene disagrees with a dataset and which missing effect explains it");
  cmd->footer(
      "Effects: gravity, youngModulus, poissonRatio, inclusion, damping, friction, instrumentRadius,\n"
      "elasticFoundation, registration. Outputs: OUT/report.md, "
      "OUT/report.json and OUT/<scene>_audited.xml (the scene with the effects found). See docs/user-guide.md,\n"
      "\"Model audit\".");
  cmd->add_option("scene", a->scene, "scene file whose instrument is driven by a TrajectoryDriver");
  auto* data = cmd->add_option("--data", a->data, "dataset folder (see `viscera dataset`)");
  cmd->add_option("--out", a->out, "output folder (audit)");
  cmd->add_option("--effects", a->effects, "effects to try (default: all)")->delimiter(',');
  cmd->add_option("--jobs", a->jobs, "effects fitted at once (1)")->check(CLI::Range(1, 1024));
  cmd->add_option("--rounds", a->rounds, "effects added at most (3)")->check(CLI::Range(1, 100));
  cmd->add_option("--train", a->train, "fraction of the measurements' time span used for fitting (0.6)");
  cmd->add_option("--alpha", a->alpha, "family-wise error rate of the confirmation test (0.05)");
  cmd->add_option("--max-evals", a->maxEvals, "replays per fit at most (16)")->check(CLI::Range(2, 10000));
  cmd->add_option("--points", a->points, "points scored per frame (2000)")->check(CLI::Range(0, 100000000));
  cmd->add_option("--set", a->sets, "set a scene attribute before the audit, ADDRESS=VALUE; repeatable");
  cmd->add_flag("--no-wrench", a->noWrench, "score the clouds only, even when the dataset has a wrench");
  cmd->add_flag("--quiet", a->quiet, "no progress lines");
  cmd->add_flag("--no-plot", a->noPlot, "do not run gnuplot");
  cmd->add_flag("--no-residuals", a->noResiduals, "do not write the per-frame residual series (OUT/residuals)");
  cmd->add_option("--residual-frames", a->residualFrames, "frames per residual series at most, evenly spaced (150; 0: all)")
      ->check(CLI::Range(0, 100000000));
  cmd->callback([a, cmd, data, &action] {
    if (cmd->got_subcommand("bench")) return;
    if (a->scene.empty()) throw CLI::RequiredError("scene");
    if (data->count() == 0) throw CLI::RequiredError("--data");
    action = [a] { return audit(*a); };
  });

  auto b = std::make_shared<AuditBenchArgs>();
  auto* bench = cmd->add_subcommand("bench", "plant every effect over seeds and strengths, audit each case, and print the "
                                             "confusion matrix, detection and false-discovery rates");
  bench->footer("Each case: the scene with one effect planted (Effect::plant; controls plant none), filmed by its own depth\n"
                "camera at 10 Hz with the instrument's wrench plus noise, audited with the scene as the nominal model.\n"
                "Writes OUT/bench.md and OUT/bench.json. See docs/user-guide.md, \"Model audit\".");
  bench->add_option("scene", b->scene, "scene file whose instrument is driven by a TrajectoryDriver")->required();
  bench->add_option("--time", b->time, "simulated time of each case, in seconds")->required()->check(CLI::PositiveNumber);
  bench->add_option("--out", b->out, "output folder, must not exist (audit-bench)");
  bench->add_option("--effects", b->effects, "effects to plant (default: every one that applies)")->delimiter(',');
  bench->add_option("--strengths", b->strengths, "planting strengths in (0, 1] (0.5,1)")->delimiter(',');
  bench->add_option("--seeds", b->seeds, "seeds per effect and strength, and controls (2)")->check(CLI::Range(1, 1000));
  bench->add_option("--jobs", b->jobs, "effects fitted at once in each audit (1)")->check(CLI::Range(1, 1024));
  bench->add_option("--force-noise", b->forceNoise, "noise on each force component of the wrench (\"2 mN\")");
  bench->add_flag("--keep", b->keep, "keep each case's truth scene and dataset under OUT");
  bench->callback([b, &action] { action = [b] { return auditBench(*b); }; });
}

}  // namespace viscera
