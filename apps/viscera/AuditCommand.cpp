// `viscera audit SCENE --data DATA`: where the scene disagrees with the dataset, which missing
// effect explains it, and the scene with it added (study/Audit.h). Writes OUT/report.json,
// OUT/report.md and OUT/augmented.xml; nothing is written when the inputs are unusable.
#include "apps/viscera/AuditCommand.h"

#include <CLI/CLI.hpp>
#include <tbb/info.h>

#include <filesystem>
#include <iostream>
#include <memory>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Files.h"
#include "io/scene/SceneReader.h"
#include "io/scene/SceneWriter.h"
#include "study/Audit.h"

namespace viscera {
namespace {

namespace fs = std::filesystem;

struct AuditArgs {
  std::string scene, data, out = "audit";
  std::vector<std::string> effects, sets;
  int jobs = 1, rounds = 3, points = 2000, maxEvals = 16;
  double train = 0.6, alpha = 0.05;
  bool noWrench = false, quiet = false;
};

struct Log : study::AuditProgress {
  explicit Log(bool quiet) : quiet_(quiet) {}
  void message(const std::string& line) override {
    if (!quiet_) std::cerr << line << "\n";
  }
  bool quiet_;
};

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
  o.replay.threads = std::max(1, tbb::info::default_concurrency() / std::max(1, a.jobs));
  o.replay.score.maxPoints = a.points;
  o.replay.score.useWrench = !a.noWrench;
  const study::PreparedDataset data = study::prepareDataset(a.data, o.replay.score);
  const fs::path dir = a.out;
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) throw Error(SourceLoc{a.out}, "--out: is a file, not a folder");
  const fs::path parent = fs::absolute(dir).parent_path();
  if (!fs::is_directory(parent, ec)) throw Error(SourceLoc{a.out}, "--out: the folder " + parent.string() + " does not exist");

  Log log(a.quiet);
  const study::AuditReport r = study::runAudit(scene, data, o, &log);

  fs::create_directories(dir, ec);
  if (ec) throw Error(SourceLoc{a.out}, "--out: cannot create the folder: " + ec.message());
  // The augmented scene goes to OUT; report.json names it.
  SceneDesc augmented = r.augmented;
  const fs::path sceneDir = fs::absolute(a.scene).parent_path();
  const fs::path augmentedPath = fs::absolute(dir) / (fs::path(a.scene).stem().string() + "_audited.xml");
  // Input files are named relative to the scene's folder: absolute in the new file, so that it
  // runs from anywhere. Outputs (exporters, cameras) stay relative to --out.
  std::function<void(ElementDesc&)> absolutise = [&](ElementDesc& el) {
    const ComponentSpec* spec = builtinRegistry().find(el.tag);
    if (spec && spec->category != "output" && spec->category != "sensor")
      for (auto& at : el.attrs) {
        const AttrSpec* a = spec->find(at.name);
        if (a && a->kind == AttrKind::File && !at.value.empty() && fs::path(at.value).is_relative())
          at.value = (sceneDir / at.value).lexically_normal().string();
      }
    for (auto& c : el.children) absolutise(c);
  };
  absolutise(augmented.root);
  io::writeScene(augmentedPath.string(), augmented,
                 "Written by viscera audit from " + fs::absolute(a.scene).string() + " and the dataset " +
                     fs::absolute(a.data).string() + "; effects added: " +
                     (r.found.empty() ? std::string("none") : [&] {
                       std::string s;
                       for (const auto& f : r.found) s += (s.empty() ? "" : ", ") + f;
                       return s;
                     }()));
  writeFileAtomic((dir / "report.json").string(),
                  study::auditJson(r, fs::absolute(a.scene).string(), fs::absolute(a.data).string(), augmentedPath.string()));
  writeFileAtomic((dir / "report.md").string(),
                  study::auditMarkdown(r, fs::absolute(a.scene).string(), fs::absolute(a.data).string(), augmentedPath.string()));
  std::cout << r.verdict;
  if (!r.found.empty()) {
    std::cout << ":";
    for (const auto& f : r.found) std::cout << " " << f;
  }
  std::cout << " (noise floor " << r.noiseFloorMm << " mm, remaining gap " << r.remainingGapMm << " mm)\n";
  std::cerr << "wrote " << (dir / "report.md").string() << ", report.json and " << augmentedPath.string() << "\n";
  return kExitOk;
}

}  // namespace

void addAuditCommand(CLI::App& app, std::function<int()>& action) {
  auto a = std::make_shared<AuditArgs>();
  auto* cmd = app.add_subcommand("audit", "find where a scene disagrees with a dataset and which missing effect explains it");
  cmd->footer(
      "Effects: gravity, youngModulus, poissonRatio, damping, friction, instrumentRadius, elasticFoundation.\nOutputs: OUT/report.md, "
      "OUT/report.json and OUT/<scene>_audited.xml (the scene with the effects found). See docs/user-guide.md,\n"
      "\"Model audit\".");
  cmd->add_option("scene", a->scene, "scene file whose instrument is driven by a TrajectoryDriver")->required();
  cmd->add_option("--data", a->data, "dataset folder (see `viscera dataset`)")->required();
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
  cmd->callback([a, &action] { action = [a] { return audit(*a); }; });
}

}  // namespace viscera
