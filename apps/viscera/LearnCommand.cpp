#include "apps/viscera/LearnCommand.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/Error.h"
#include "core/Text.h"
#include "engine/Run.h"
#include "apps/viscera/Gnuplot.h"
#include "core/Files.h"
#include "learning/Record.h"
#include "learning/nn/Corrector.h"
#include "learning/nn/Stepper.h"

namespace viscera {

namespace {

// "MIN:MAX" (or one number for both) into the two bounds; errors name the option.
void parseRange(const std::string& text, const std::string& option, double& lo, double& hi) {
  const auto colon = text.find(':');
  const std::string a = text.substr(0, colon), b = colon == std::string::npos ? a : text.substr(colon + 1);
  if (!parseNumber(a, lo) || !parseNumber(b, hi))
    throw Error(option + ": expected MIN:MAX (two numbers in the scene's units), got " + viscera::quoted(text));
}

struct LearnRecordCli {
  learning::RecordOptions options;
  std::string data;
  int points = 4000;
  std::string depth = "2:6", speed = "5:15", faces = "top,x-,x+,y-,y+";
  bool quiet = false;
};

int recordRollouts(LearnRecordCli& c) {
  learning::RecordOptions& o = c.options;
  if (!c.data.empty()) {
    learning::PairOptions p;
    p.scene = o.scene;
    p.data = c.data;
    p.out = o.out;
    p.sets = o.sets;
    p.maxPoints = c.points;
    const learning::PairResult r = learning::recordPairs(p);
    if (!c.quiet)
      std::cerr << "wrote " << r.frames << " pairs (simulated body, measured cloud) to " << o.out << " in "
                << formatDuration(r.wallSeconds) << "; the replay's mean cloud -> surface RMS is " << formatNumber(r.cloudRms) << "\n";
    return kExitOk;
  }
  parseRange(c.depth, "--depth", o.depthMin, o.depthMax);
  parseRange(c.speed, "--speed", o.speedMin, o.speedMax);
  o.faces.clear();
  std::istringstream in(c.faces);
  for (std::string f; std::getline(in, f, ',');) {
    try {
      o.faces.push_back(motion::parseFace(f));
    } catch (const std::invalid_argument& e) {
      throw Error(std::string("--faces: ") + e.what());
    }
  }
  const learning::RecordResult r =
      learning::record(o, c.quiet ? std::function<void(const std::string&)>() : [](const std::string& line) { std::cerr << line << "\n"; });
  if (!c.quiet)
    std::cerr << "wrote " << r.rollouts << " rollouts (" << r.frames << " frames, " << formatNumber(r.simulatedTime)
              << " s simulated) to " << o.out << " in " << formatDuration(r.wallSeconds) << "\n";
  if (r.diverged > 0) {
    std::cerr << o.out << ": " << r.diverged << " rollout" << (r.diverged == 1 ? "" : "s")
              << " diverged (kept up to the divergence; see rollouts.json)\n";
    return kExitDiverged;
  }
  return kExitOk;
}

// Options shared by both kinds of model; 0 means the kind's default.
struct LearnTrainCli {
  learning::StepperTrainOptions options;
  learning::CorrectorTrainOptions corrector;
  int width = 0, epochs = 0, batch = 0;
  double validation = 0, lr = 0;
  // As given (the model's record keeps the words, not the enumerations they become).
  std::string schedule = "plateau", output = "update";
  bool quiet = false;
};

// The command as typed, for the model's record (flags in the order they are declared, each with its values).
std::string trainCommand(const CLI::App& train) {
  std::string s = "viscera learn train";
  for (const std::string& d : train.get_option("data")->results()) s += " " + d;
  for (const CLI::Option* o : train.get_options()) {
    if (o->get_name() == "data" || o->get_name() == "--help" || o->count() == 0) continue;
    s += " " + o->get_name();
    if (o->get_expected_min() > 0)
      for (const std::string& v : o->results()) s += " " + v;
  }
  return s;
}

int trainCorrectorModel(LearnTrainCli& c) {
  learning::CorrectorTrainOptions& o = c.corrector;
  o.data = c.options.data;
  o.out = c.options.out;
  o.seed = c.options.seed;
  o.threads = c.options.threads;
  o.resume = c.options.resume;
  o.command = c.options.command;
  if (c.width) o.architecture.width = c.width;
  if (c.epochs) o.epochs = c.epochs;
  if (c.batch) o.batch = c.batch;
  if (c.validation) o.validation = c.validation;
  if (c.lr) o.learningRate = c.lr;
  learning::trainCorrector(o, [&](const learning::CorrectorEpochReport& r) {
    if (c.quiet) return;
    char line[320];
    std::snprintf(line, sizeof line,
                  "epoch %d/%d: loss %.4g (squared cloud distance), held-out cloud distance %.4f -> %.4f (%+.1f %%), rate %.2g, %s%s",
                  r.epoch, r.epochs, r.trainLoss, r.heldOutBefore, r.heldOutAfter,
                  100 * (r.heldOutAfter - r.heldOutBefore) / std::max(1e-300, r.heldOutBefore), r.learningRate,
                  formatDuration(r.seconds).c_str(), r.best ? "  [saved]" : "");
    std::cerr << line << std::endl;
  });
  if (!c.quiet) std::cerr << "model: " << o.out << " (checkpoint to resume from: " << o.out << "/checkpoint)\n";
  return kExitOk;
}

int trainModel(LearnTrainCli& c) {
  if (c.options.data.size() > 0 && learning::isPairFolder(c.options.data.front())) return trainCorrectorModel(c);
  if (c.width) c.options.architecture.width = c.width;
  if (c.epochs) c.options.epochs = c.epochs;
  if (c.batch) c.options.batch = c.batch;
  if (c.validation) c.options.validation = c.validation;
  if (c.lr) c.options.learningRate = c.lr;
  c.options.schedule = c.schedule == "cosine" ? learning::RateSchedule::Cosine : learning::RateSchedule::Plateau;
  c.options.architecture.output =
      c.output == "offset" ? learning::StepperArchitecture::Output::NextOffset : learning::StepperArchitecture::Output::Update;
  const std::string units = learning::readRolloutSet(c.options.data.front()).units;
  const std::string length = units.substr(0, units.find(' '));
  learning::trainStepper(c.options, [&](const learning::EpochReport& r) {
    if (c.quiet) return;
    char line[320];
    std::snprintf(line, sizeof line,
                  "epoch %d/%d: loss %.3g (held-out %.3g) cells^2, held-out rollout %.3f %s (no motion %.3f %s), "
                  "rate %.2g, %s%s",
                  r.epoch, r.epochs, r.trainLoss, r.validationLoss, r.rolloutError, length.c_str(), r.baselineError,
                  length.c_str(), r.learningRate, formatDuration(r.seconds).c_str(), r.best ? "  [saved]" : "");
    std::cerr << line << std::endl;
  });
  if (!c.quiet) std::cerr << "model: " << c.options.out << " (checkpoint to resume from: " << c.options.out << "/checkpoint)\n";
  return kExitOk;
}

struct LearnEvalCli {
  std::string model, data, out;
  double segment = 10, time = 0;
  int points = 0;
  bool noPlot = false;
};

int evaluateCorrection(const LearnEvalCli& c) {
  namespace fs = std::filesystem;
  const learning::Corrector model = learning::Corrector::load(c.model);
  const learning::PairSet pairs = learning::readPairSet(c.data);
  if (fs::exists(c.out) && !fs::is_directory(c.out)) throw Error(SourceLoc{c.out}, "--out: exists and is not a folder");
  const learning::CorrectionEvaluation ev = learning::evaluateCorrector(model, pairs, c.points);
  fs::create_directories(c.out);
  FolderLock lock(c.out);
  const fs::path dir(c.out);
  std::ostringstream csv;
  csv << "t,before,after,before_squared,after_squared,surface_before,surface_after\n";
  for (size_t k = 0; k < ev.time.size(); ++k)
    csv << ev.time[k] << "," << ev.before[k] << "," << ev.after[k] << "," << ev.beforeSquared[k] << "," << ev.afterSquared[k] << ","
        << ev.surfaceBefore[k] << "," << ev.surfaceAfter[k] << "\n";
  writeFileAtomic((dir / "errors.csv").string(), csv.str());
  const double change = 100 * (ev.meanAfter - ev.meanBefore) / ev.meanBefore;
  const double squaredChange = 100 * (ev.meanSquaredAfter - ev.meanSquaredBefore) / ev.meanSquaredBefore;
  nlohmann::ordered_json j = {{"model", fs::absolute(c.model).string()},
                              {"data", fs::absolute(c.data).string()},
                              {"frames", ev.time.size()},
                              {"meanDistanceBefore", ev.meanBefore},
                              {"meanDistanceAfter", ev.meanAfter},
                              {"changePercent", change},
                              {"improvementStandardError", ev.improvementSe},
                              {"meanSquaredBefore", ev.meanSquaredBefore},
                              {"meanSquaredAfter", ev.meanSquaredAfter},
                              {"squaredChangePercent", squaredChange},
                              {"meanSurfaceDistanceBefore", ev.meanSurfaceBefore},
                              {"meanSurfaceDistanceAfter", ev.meanSurfaceAfter},
                              {"surfaceChangePercent", 100 * (ev.meanSurfaceAfter - ev.meanSurfaceBefore) / ev.meanSurfaceBefore},
                              {"msPerFrame", ev.msPerFrame}};
  writeFileAtomic((dir / "eval.json").string(), j.dump(2) + "\n");
  const std::string unit = model.units().substr(0, model.units().find(' '));
  char line[640];
  std::snprintf(line, sizeof line,
                "%zu frames, uncorrected -> corrected: cloud -> refined-surface vertices, mean squared (the loss; Table 4-3's "
                "measure) %.4f -> %.4f %s^2 (%+.1f %%), mean %.4f -> %.4f %s (%+.1f %%; improvement %.4f +- %.4f %s); "
                "cloud -> exact surface, mean %.4f -> %.4f %s (%+.1f %%); %.2f ms per frame\n",
                ev.time.size(), ev.meanSquaredBefore, ev.meanSquaredAfter, unit.c_str(), squaredChange, ev.meanBefore, ev.meanAfter,
                unit.c_str(), change, ev.meanBefore - ev.meanAfter, ev.improvementSe, unit.c_str(), ev.meanSurfaceBefore,
                ev.meanSurfaceAfter, unit.c_str(), 100 * (ev.meanSurfaceAfter - ev.meanSurfaceBefore) / ev.meanSurfaceBefore,
                ev.msPerFrame);
  std::cout << line;
  if (!c.noPlot) {
    std::ostringstream gp;
    gp << "set datafile separator ','\nset terminal pngcairo size 1100,420 noenhanced\nset output outfile\n"
       << "set xlabel 'time'\nset ylabel 'mean cloud -> refined surface distance (" << unit << ")'\nset key top left\nset grid\n"
       << "plot 'errors.csv' using 1:2 skip 1 with lines lw 2 title 'simulation (refined vertices)', '' using 1:3 skip 1 with lines lw 2 title 'corrected (refined vertices)', "
       << "'' using 1:6 skip 1 with lines dt 2 title 'simulation (surface)', '' using 1:7 skip 1 with lines dt 2 title 'corrected (surface)'\n";
    writeFileAtomic((dir / "eval.gp").string(), gp.str());
    plotWithGnuplot(dir, "eval.gp", "eval.png");
  }
  std::cerr << "wrote " << (dir / "eval.json").string() << ", errors.csv" << (c.noPlot ? "" : ", eval.png") << "\n";
  return kExitOk;
}

int evaluateModel(const LearnEvalCli& c) {
  namespace fs = std::filesystem;
  if (learning::isPairFolder(c.data)) return evaluateCorrection(c);
  const learning::Stepper model = learning::Stepper::load(c.model);
  const learning::RolloutSet data = learning::readRolloutSet(c.data);
  if (fs::exists(c.out) && !fs::is_directory(c.out)) throw Error(SourceLoc{c.out}, "--out: exists and is not a folder");
  const auto evals = learning::evaluateStepper(model, data, c.segment, c.time);
  if (evals.empty()) throw Error(SourceLoc{c.data}, "the recording has no usable rollout");
  fs::create_directories(c.out);
  FolderLock lock(c.out);
  nlohmann::ordered_json report;
  report["model"] = fs::absolute(c.model).string();
  report["data"] = fs::absolute(c.data).string();
  report["units"] = model.units();
  report["segment"] = c.segment;
  std::ostringstream csv, table;
  csv << "rollout,t,model,no_motion\n";
  {
    char header[120];  // aligned with the rows below
    std::snprintf(header, sizeof header, "%-18s %11s   %-27s%9s %8s %7s\n", "rollout", "segment", "model - FEM, mean (sd)", "no motion", "",
                  "ratio");
    table << header;
  }
  double all = 0, allBase = 0, frames = 0, seconds = 0, worst = 0, worstRatio = 1e300;
  // A segment where the FEM stays at rest (its distance from rest at most a thousandth of the
  // recording's mean) has no ratio to speak of: it is marked and left out of the smallest ratio; the
  // model's error there still counts in the worst segment.
  for (const auto& e : evals)
    if (e.time.size() >= 2) allBase += e.baselineMean * (e.time.size() - 1), frames += e.time.size() - 1;
  if (frames == 0) throw Error(SourceLoc{c.data}, "no rollout has two frames or more: nothing to evaluate");
  const double atRest = 1e-3 * allBase / frames;
  auto& list = report["rollouts"] = nlohmann::ordered_json::array();
  for (size_t r = 0; r < evals.size(); ++r) {
    const auto& e = evals[r];
    if (e.time.size() < 2) continue;  // nothing to step
    const std::string name = fs::path(e.file).stem().string();
    nlohmann::ordered_json j = {{"file", e.file}, {"mean", e.mean}, {"noMotionMean", e.baselineMean}};
    auto& segs = j["segments"] = nlohmann::ordered_json::array();
    for (const auto& s : e.segments) {
      const bool still = s.baselineMean <= atRest;
      char ratio[32];
      std::snprintf(ratio, sizeof ratio, still ? "at rest" : "%.1f", s.mean > 0 ? s.baselineMean / s.mean : 0.0);
      char line[200];
      std::snprintf(line, sizeof line, "%-18s %5.0f-%-5.0f   %8.3f (%.3f) %-10s %8.3f %-8s %7s\n", name.c_str(), s.t0, s.t1, s.mean,
                    s.stddev, model.units().substr(0, model.units().find(' ')).c_str(), s.baselineMean, "", ratio);
      table << line;
      segs.push_back({{"t0", s.t0}, {"t1", s.t1}, {"frames", s.frames}, {"mean", s.mean}, {"sd", s.stddev}, {"noMotionMean", s.baselineMean},
                      {"femAtRest", still}});
      worst = std::max(worst, s.mean);
      if (s.mean > 0 && !still) worstRatio = std::min(worstRatio, s.baselineMean / s.mean);
    }
    for (size_t f = 0; f < e.time.size(); ++f) csv << name << "," << e.time[f] << "," << e.error[f] << "," << e.baseline[f] << "\n";
    const double n = static_cast<double>(e.time.size() - 1);
    all += e.mean * n, seconds += e.seconds;
    list.push_back(j);
  }
  report["mean"] = all / frames;
  report["noMotionMean"] = allBase / frames;
  report["worstSegmentMean"] = worst;
  report["smallestSegmentRatio"] = worstRatio < 1e300 ? nlohmann::ordered_json(worstRatio) : nlohmann::ordered_json(nullptr);
  report["msPerFrame"] = 1e3 * seconds / frames;
  std::cout << table.str();
  char line[240];
  char smallest[32];
  std::snprintf(smallest, sizeof smallest, worstRatio < 1e300 ? "%.1f" : "none", worstRatio);
  std::snprintf(line, sizeof line,
                "all: model - FEM %.3f, no motion - FEM %.3f (ratio %.1f); worst segment %.3f, smallest segment ratio %s "
                "(segments where the FEM moves); %.2f ms per frame\n",
                all / frames, allBase / frames, allBase / std::max(1e-300, all), worst, smallest, 1e3 * seconds / frames);
  std::cout << line;
  const fs::path dir(c.out);
  writeFileAtomic((dir / "errors.csv").string(), csv.str());
  writeFileAtomic((dir / "eval.json").string(), report.dump(2) + "\n");
  if (!c.noPlot) {
    std::ostringstream gp;
    gp << "set datafile separator ','\nset terminal pngcairo size 1100,420 noenhanced\nset output outfile\n"
       << "set xlabel 'time in the rollout'\nset ylabel 'mean node distance to the FEM (" << model.units().substr(0, model.units().find(' ')) << ")'\n"
       << "set key top left\nset grid\nplot ";
    for (size_t r = 0; r < evals.size(); ++r) {
      const std::string name = fs::path(evals[r].file).stem().string();
      gp << (r ? ", " : "") << "'errors.csv' using (strcol(1) eq '" << name << "' ? $2 : 1/0):3 with lines lw 2 title '" << name << " model', "
         << "'' using (strcol(1) eq '" << name << "' ? $2 : 1/0):4 with lines dt 2 title '" << name << " no motion'";
    }
    gp << "\n";
    writeFileAtomic((dir / "eval.gp").string(), gp.str());
    plotWithGnuplot(dir, "eval.gp", "eval.png");
  }
  std::cerr << "wrote " << (dir / "eval.json").string() << ", errors.csv" << (c.noPlot ? "" : ", eval.png") << "\n";
  return kExitOk;
}

struct LearnBenchCli {
  std::vector<std::string> scenes;
  std::vector<int> widths = {128, 256};
  std::vector<int> correctorWidths = {16, 64};
  int frames = 60, threads = 1;
};

int benchModels(const LearnBenchCli& c) {
  learning::setTorchThreads(c.threads);
  const learning::GemmSpeed g = learning::measureGemm(2025, 256, 256);
  std::printf("threads: %d\nBLAS: %s\nsgemm 2025x256 by 256x256: %.3f ms, %.1f GFLOP/s\n", c.threads, g.blas.c_str(),
              g.milliseconds, g.gflops);
  for (const std::string& scene : c.scenes) {
    const learning::RestMesh mesh = learning::sceneRestMesh(scene);
    learning::StepperNormalisers norm;
    norm.cell = Eigen::Vector3d::Ones();
    norm.boxMin = mesh.points.rowwise().minCoeff();
    norm.boxMax = mesh.points.rowwise().maxCoeff();
    norm.reach = 10;
    for (int width : c.widths) {
      learning::StepperArchitecture arch;
      arch.width = width;
      const learning::Stepper model(mesh, arch, norm, 1.0 / 30, "mm g s", 1);
      // The instrument pressing the top's centre, as in contact.
      const Eigen::Vector3d tip(0.5 * (norm.boxMin.x() + norm.boxMax.x()), 0.5 * (norm.boxMin.y() + norm.boxMax.y()), norm.boxMax.z() + 2);
      Eigen::Matrix3Xd x = mesh.points;
      for (int i = 0; i < 5; ++i) x = model.step(mesh.points, {tip, Eigen::Vector3d(0, 0, -5)});
      std::vector<double> ms;
      for (int f = 0; f < c.frames; ++f) {
        const auto t0 = std::chrono::steady_clock::now();
        x = model.step(mesh.points, {tip, Eigen::Vector3d(0, 0, -5)});
        ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      }
      std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
      const double med = ms[ms.size() / 2];
      std::printf("stepper %s (%d nodes), width %d (%lld parameters): %.3f ms per frame (median of %d), %.1f x real time at 30 Hz\n",
                  std::filesystem::path(scene).filename().c_str(), static_cast<int>(mesh.points.cols()), width,
                  static_cast<long long>(model.parameters()), med, c.frames, (1000.0 / 30) / med);
    }
    const auto grid = learning::gridOf(mesh);
    if (!grid) continue;
    for (bool threeD : {false, true})
      for (int width : c.correctorWidths) {
        const learning::Corrector corrector(mesh, *grid, Eigen::Vector3d(0, 0, -1), learning::CorrectorArchitecture{threeD, width, 0.5},
                                            "mm g s", 1);
        const Eigen::Vector3d tip(0.5 * (norm.boxMin.x() + norm.boxMax.x()), 0.5 * (norm.boxMin.y() + norm.boxMax.y()), norm.boxMax.z() + 2);
        for (int i = 0; i < 3; ++i) corrector.correct(mesh.points, {tip, Eigen::Vector3d(0, 0, -5)});
        std::vector<double> ms;
        for (int f = 0; f < c.frames; ++f) {
          const auto t0 = std::chrono::steady_clock::now();
          corrector.correct(mesh.points, {tip, Eigen::Vector3d(0, 0, -5)});
          ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        }
        std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
        std::printf("corrector %s (%d x %d x %d grid), %s, width %d (%lld parameters): %.3f ms per frame (median of %d)\n",
                    std::filesystem::path(scene).filename().c_str(), grid->nx, grid->ny, grid->nz, threeD ? "3D" : "2D", width,
                    static_cast<long long>(corrector.parameters()), ms[ms.size() / 2], c.frames);
      }
  }
  return kExitOk;
}

}  // namespace

void addLearnCommand(CLI::App& app, std::function<int()>& action) {
  auto* cmd = app.add_subcommand("learn", "learned components: record rollouts and pairs, train, evaluate and time learned steppers and corrections");
  cmd->require_subcommand(1);
  auto c = std::make_shared<LearnRecordCli>();
  auto* rec = cmd->add_subcommand("record", "write rollouts of randomised palpations (a stepper's data) or, with --data, pairs of "
                                              "simulated body and measured cloud (a corrector's)");
  rec->footer("The scene has one deformable body with tetrahedra and one instrument: a SphereCollisionModel on a rigid body\n"
              "driven by a TrajectoryDriver. Each rollout replaces that trajectory with a generated palpation (pokes on the\n"
              "faces given, depth and speed drawn from their ranges with seed + k) and records the body's nodes and the\n"
              "instrument at --rate frames per unit time. Output: mesh.bin, rollout_NNNN.bin, trajectories/, rollouts.json\n"
              "(docs/user-guide.md, \"Rollouts\"). Exit code 3 when a rollout diverged (its frames up to then are kept).\n"
              "With --data DATASET the scene replays the measured dataset instead and, at each camera frame, its body (on a\n"
              "RegularGridTopology) is written beside the frame's cloud: pairs.json, mesh.bin, states.bin, clouds.bin.");
  rec->add_option("scene", c->options.scene, "scene file (.xml or SOFA .scn)")->required();
  rec->add_option("--out", c->options.out, "the folder to create (must not exist)")->required();
  rec->add_option("--rollouts", c->options.rollouts, "number of rollouts (8)");
  rec->add_option("--time", c->options.time, "simulated time of each rollout, in the scene's time unit (20)");
  rec->add_option("--rate", c->options.rate, "frames per unit time, rounded to a whole number of steps (30)");
  rec->add_option("--depth", c->depth, "range of the poke depth past the face, MIN:MAX in the scene's length unit (2:6)");
  rec->add_option("--speed", c->speed, "range of the press speed, MIN:MAX in length per time unit (5:15)");
  rec->add_option("--faces", c->faces, "faces to poke, comma-separated: top, x-, x+, y-, y+ (all)");
  rec->add_option("--seed", c->options.seed, "rollout k draws from seed + k (1); recordings meant to differ need seeds at least --rollouts apart");
  rec->add_option("--jobs", c->options.jobs, "rollouts run at once (0: one per core)");
  rec->add_option("--data", c->data, "a measured dataset: record pairs for a learned correction instead of rollouts");
  rec->add_option("--points", c->points, "with --data: cloud points kept per frame, chosen evenly (4000)");
  rec->add_flag("--scene-trajectory", c->options.sceneTrajectory,
                "one rollout along the scene's own trajectory (a held-out palpation; with --rollouts 1)");
  rec->add_option("--set", c->options.sets, "set a scene attribute, ADDRESS=VALUE; repeatable");
  rec->add_flag("--quiet", c->quiet, "no progress or summary");
  rec->callback([c, &action] { action = [c] { return recordRollouts(*c); }; });

  auto t = std::make_shared<LearnTrainCli>();
  auto* train = cmd->add_subcommand("train", "train a learned stepper on rollouts, or a learned correction on pairs");
  train->footer("Rollout folders train a stepper (graph U-Net): the last --validation share of the rollouts is held out, and\n"
                "after every epoch the model is rolled out over them for --validation-time. Pair folders train a corrector\n"
                "(2D or 3D U-Net): the last --validation share of each folder's frames is held out. Whenever the held-out\n"
                "error improves the model is written to --out (config.json, weights.pt, mesh.bin); --out/checkpoint holds\n"
                "the last epoch and the optimiser's state, and --resume continues from it. See docs/user-guide.md,\n"
                "\"Learned components\".");
  train->add_option("data", t->options.data, "rollout folders (a stepper) or pair folders (a corrector), from viscera learn record")->required();
  train->add_option("--out", t->options.out, "the model folder to create")->required();
  train->add_option("--width", t->width, "stepper: features of every hidden layer (256); corrector: of the first block (64)");
  train->add_option("--levels", t->options.architecture.levels, "pooling levels of the U-Net (3)");
  train->add_option("--matchings", t->options.architecture.matchings, "node-pair matchings per pooling level (2)");
  train->add_option("--max-step", t->options.architecture.maxStep, "largest update per frame, in cells along each axis (1)");
  train->add_flag("!--no-rest-anchor", t->options.architecture.restAnchored,
                  "do not subtract the network's output at rest (for a body whose rest shape is not its equilibrium)");
  train->add_flag("--instrument-all", t->options.architecture.instrumentAtAllInReach,
                  "every node within reach sees the instrument (default: the nearest only, as the dissertation)");
  train->add_option("--output", t->output,
                    "stepper: what the network predicts per node: its update (update, as the dissertation), or its next offset "
                    "from rest, the update being the difference from the current offset (offset)")
      ->transform(CLI::IsMember({"update", "offset"}, CLI::ignore_case))
      ->default_str("update");
  train->add_option("--epochs", t->epochs, "epochs (stepper 30, corrector 40)");
  train->add_option("--batch", t->batch, "frames per batch (stepper 32, corrector 8)");
  train->add_option("--lr", t->lr, "Adam's initial learning rate (1e-3)");
  train->add_option("--warmup", t->options.warmup, "epochs before half the inputs become the model's own predictions (5)");
  train->add_option("--unroll", t->options.unroll, "those predictions chain 1 to this many frames (3)");
  train->add_option("--noise", t->options.noise, "RMS of the smooth random displacement added to the inputs, in cells (0.03)");
  train->add_option("--validation", t->validation, "stepper: share of the rollouts held out (0.1, at least one); corrector: the last share of each pair folder's frames (0.2)");
  train->add_flag("--3d", t->corrector.architecture.threeD, "corrector: a 3D U-Net over the whole grid (default: 2D over the observed face)");
  train->add_option("--max-correction", t->corrector.architecture.maxCorrection, "corrector: largest correction, in cells along each axis (0.5)");
  train->add_option("--points", t->corrector.maxPoints, "corrector: cloud points per frame in the loss (1000)");
  train->add_option("--validation-time", t->options.validationTime, "time each held-out rollout is rolled out over (20)");
  train->add_option("--schedule", t->schedule,
                    "stepper: the learning rate halves after --patience epochs without a better held-out rollout "
                    "(plateau), or follows a half cosine from --lr towards zero over --epochs (cosine)")
      ->transform(CLI::IsMember({"plateau", "cosine"}, CLI::ignore_case))
      ->default_str("plateau");
  train->add_option("--patience", t->options.patience, "stepper, plateau schedule: epochs without a better held-out rollout before the rate halves (3)");
  train->add_option("--reach", t->options.reachCells, "the instrument is seen within its radius plus this many cells (1)");
  train->add_option("--seed", t->options.seed, "seed of the weights and the batches (1)");
  train->add_option("--threads", t->options.threads, "LibTorch threads (0: every core)");
  train->add_flag("--resume", t->options.resume, "continue the training in --out from its checkpoint");
  train->add_flag("--quiet", t->quiet, "no progress");
  train->callback([t, train, &action] {
    t->options.command = trainCommand(*train);
    action = [t] { return trainModel(*t); };
  });

  auto e = std::make_shared<LearnEvalCli>();
  auto* ev = cmd->add_subcommand("eval", "report a learned stepper's error against the FEM, or a corrector's effect on cloud distances");
  ev->footer("A stepper: each rollout is stepped by the model from its first frame, driven by the recorded instrument; per\n"
             "segment of --segment the mean node distance to the FEM's nodes is reported beside that of the rest mesh (no\n"
             "motion) and their ratio (\"at rest\" where the FEM does not move). A corrector: per frame of the pairs, without\n"
             "and with the correction, the mean squared and the mean distance from the cloud to the vertices of the surface\n"
             "refined three times (the loss; the mean squared one is the dissertation's Table 4-3), and the mean distance to\n"
             "the exact surface. Writes eval.json, errors.csv (per frame) and eval.png into --out.");
  ev->add_option("model", e->model, "model folder")->required();
  ev->add_option("data", e->data, "rollout folder (a stepper) or pair folder (a corrector)")->required();
  ev->add_option("--out", e->out, "folder for the report")->required();
  ev->add_option("--segment", e->segment, "length of a reporting segment (10)");
  ev->add_option("--time", e->time, "roll out at most this time of each rollout (0: all)");
  ev->add_option("--points", e->points, "corrector: cloud points per frame, chosen evenly (0: all)");
  ev->add_flag("--no-plot", e->noPlot, "no eval.png (no gnuplot needed)");
  ev->callback([e, &action] { action = [e] { return evaluateModel(*e); }; });

  auto b = std::make_shared<LearnBenchCli>();
  auto* bench = cmd->add_subcommand("bench", "time LibTorch's matrix product, and a stepper's and a corrector's frame on scenes' bodies");
  bench->add_option("scenes", b->scenes, "scenes whose body's mesh the stepper is timed on");
  bench->add_option("--widths", b->widths, "hidden widths to time (128 256)");
  bench->add_option("--corrector-widths", b->correctorWidths, "corrector widths to time, 2D and 3D, on grid bodies (16 64)");
  bench->add_option("--frames", b->frames, "frames timed per width (60)");
  bench->add_option("--threads", b->threads, "LibTorch threads (1)");
  bench->callback([b, &action] { action = [b] { return benchModels(*b); }; });
}

}  // namespace viscera
