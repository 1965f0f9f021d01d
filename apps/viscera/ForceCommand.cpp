// `viscera force simulate` writes a recording with known truth from the PSM dynamics simulator;
// `train` identifies or trains a force model; `eval` reports its errors (NRMSE, Eq. 2.7; RelE,
// Eq. 2.8) per joint and per axis, the stiffness identified from its forces, and plots; `estimate`
// writes the tip wrench it estimates along a joint log; `bench` times its estimate sample by sample.
#include "apps/viscera/ForceCommand.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unistd.h>

#include "apps/viscera/CliText.h"
#include "apps/viscera/Gnuplot.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Text.h"
#include "learning/ArmScene.h"
#include "learning/force/ForceTraining.h"
#include "learning/nn/Stepper.h"
#include "robot/dynamics/ArmSimulator.h"
#include "robot/force/Metrics.h"
#include "robot/force/Stiffness.h"

namespace viscera {

namespace {

namespace fs = std::filesystem;
using learning::ForceModel;
using learning::ForceRecording;

const char* kAxes[] = {"Fx", "Fy", "Fz", "Tx", "Ty", "Tz"};

// An output folder: its parent exists, and it is a folder when it exists (replaced whole).
// An output folder: its parent exists; it is not, and does not hold, one of the inputs; and when it
// exists it is a folder this command wrote before (it holds `marker`), since it is replaced whole.
void requireOutputFolder(const std::string& path, const std::string& option, const std::vector<std::string>& inputs,
                         const std::string& marker) {
  const fs::path parent = fs::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty() && !fs::is_directory(parent, ec)) throw Error(SourceLoc{path}, option + ": the folder " + parent.string() + " does not exist");
  const auto st = fs::symlink_status(path, ec);
  if (fs::is_symlink(st)) throw Error(SourceLoc{path}, option + ": is a symbolic link, and outputs do not follow links");
  if (fs::exists(st) && !fs::is_directory(st)) throw Error(SourceLoc{path}, option + ": is a file, not a folder");
  const fs::path out = fs::weakly_canonical(path, ec);
  for (const std::string& in : inputs) {
    const fs::path p = fs::weakly_canonical(in, ec);
    const auto [a, b] = std::mismatch(out.begin(), out.end(), p.begin(), p.end());
    if (a == out.end()) throw Error(SourceLoc{path}, option + ": holds the input " + in + ", and the output folder is replaced whole");
  }
  if (fs::is_directory(st) && !fs::is_empty(path, ec) && !fs::exists(fs::path(path) / marker))
    throw Error(SourceLoc{path}, option + ": is a folder with other contents (no " + marker + "); it would be replaced whole, so name a new folder");
}

// A folder written whole or not at all: built beside its place, then swapped in. File-system
// failures (a read-only parent, no space) are input errors naming the folder; the partial folder
// is removed.
template <class Write>
void writeFolderAtomically(const std::string& out, Write write) {
  const fs::path target(out), partial(out + ".partial"), old(out + ".old");
  try {
    fs::remove_all(partial);
    write(partial.string());
    if (fs::exists(target)) {
      fs::remove_all(old);
      fs::rename(target, old);
    }
    fs::rename(partial, target);
    fs::remove_all(old);
  } catch (const fs::filesystem_error& e) {
    std::error_code ec;
    fs::remove_all(partial, ec);
    throw Error(SourceLoc{out}, std::string("cannot write the folder: ") + e.code().message());
  } catch (...) {
    std::error_code ec;
    fs::remove_all(partial, ec);
    throw;
  }
}

// ---------------------------------------------------------------- simulate

struct SimulateOptions {
  std::string out, workspace = "full", scene, transform, instrument, depth;
  double duration = 60, rate = 1000, stiffness = 0;  // 0: the phantom's default
  double step = robot::Excitation{}.step;
  std::uint64_t seed = 1;
  bool trocar = false, seal = false, phantom = false, noNoise = false, jacobian = false;
  int digits = 10;
};

int runSimulate(const SimulateOptions& o) {
  requireOutputFolder(o.out, "out", {o.scene, o.transform}, "simulation.json");
  const robot::ArmDynamics arm = robot::psmDynamics();
  robot::ArmSimulationOptions s = robot::psmSimulationDefaults();
  s.duration = o.duration;
  s.rate = o.rate;
  s.seed = o.seed;
  s.trocar.enabled = o.trocar;
  s.seal.enabled = o.seal;
  s.phantom.enabled = o.phantom;
  if (o.stiffness != 0) {
    if (!o.phantom) throw Error("--stiffness: is the phantom's; add --phantom");
    if (!(o.stiffness > 0)) throw Error("--stiffness: must be positive (N/m)");
    s.phantom.stiffness = o.stiffness;
  }
  if (!o.depth.empty() && !o.phantom && o.scene.empty()) throw Error("--depth: is the palpations'; add --phantom or --scene");
  if (o.workspace == "trocar") {
    // Inside a patient the body limits the outer joints (dissertation Fig. 2-22).
    s.excitation.lower = {-0.4, -0.3, 0.10, -1.5, -0.8, -0.8};
    s.excitation.upper = {0.4, 0.3, 0.20, 1.5, 0.8, 0.8};
  } else if (o.workspace != "full") {
    throw Error("--workspace: " + viscera::quoted(o.workspace) + " is neither full nor trocar");
  }
  if (!(o.step > 0 && o.step <= 1)) throw Error("--step: must be in (0, 1] (a share of each joint's range)");
  s.excitation.step = o.step;
  if (o.noNoise) s.measurement.makePerfect();
  if (!o.depth.empty()) {
    const std::vector<std::string> w = cli::words(o.depth);
    const size_t colon = o.depth.find(':');
    double lo = NAN, hi = NAN;
    if (colon != std::string::npos && w.size() == 1) {
      parseNumber(o.depth.substr(0, colon), lo);
      parseNumber(o.depth.substr(colon + 1), hi);
    }
    if (!(lo >= 0 && hi >= lo)) throw Error("--depth: " + viscera::quoted(o.depth) + " is not MIN:MAX with 0 <= MIN <= MAX (m)");
    s.excitation.minDepth = lo;
    s.excitation.maxDepth = hi;
  }
  // A Viscera scene as the environment: its tissue's contact force is the truth; the palpations
  // aim at its body's face towards the arm.
  std::unique_ptr<learning::SceneEnvironment> scene;
  if (!o.scene.empty()) {
    if (o.transform.empty()) throw Error("--scene: needs --transform (robot base -> scene, as PsmJointDriver takes it)");
    scene = std::make_unique<learning::SceneEnvironment>(o.scene, o.transform, o.instrument);
    s.phantom = scene->palpationSurface();
    s.environment = [&scene](double t, const Eigen::Isometry3d& tip, const robot::Vector6d& twist) {
      return (*scene)(t, tip, twist);
    };
  }
  const auto t0 = std::chrono::steady_clock::now();
  // Progress on a terminal, rewritten in place; nothing in a log file.
  const bool terminal = ::isatty(STDERR_FILENO) != 0;
  int lastPercent = -1;
  const robot::ArmRecording r = robot::simulateArm(arm, s, [&](double share) {
    const int p = static_cast<int>(share * 100);
    if (terminal && p / 10 != lastPercent / 10) std::cerr << "\rsimulating " << p << " %" << std::flush;
    lastPercent = p;
  });
  if (terminal) std::cerr << "\n";
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  writeFolderAtomically(o.out, [&](const std::string& dir) {
    fs::create_directories(dir);
    const robot::JointStateLog joints = robot::makeJointStateLog(r.t, r.q, r.qd, r.effort);
    robot::writeSeries(dir + "/joints.csv", joints.series, o.digits);
    robot::writeSeries(dir + "/wrench.csv", robot::wrenchSeries(r.t, r.wrench), o.digits);
    if (o.jacobian) robot::writeSeries(dir + "/jacobian.csv", robot::jacobianSeries(r.t, r.jacobian, r.dof), o.digits);
    robot::Series truth{"", {}, r.t, Eigen::MatrixXd(r.samples(), 3 * r.dof + 3), {}};
    for (const char* part : {"free", "trocar", "external"})
      for (int j = 1; j <= r.dof; ++j) truth.names.push_back(std::string(part) + std::to_string(j));
    for (const char* c : {"x", "y", "z"}) truth.names.push_back(c);
    truth.values << r.freeEffort, r.trocarEffort, r.externalEffort, r.tip;
    robot::writeSeries(dir + "/truth.csv", truth, o.digits);
    nlohmann::ordered_json j = {{"simulator", "viscera force simulate"},
                                {"arm", "dVRK PSM, large needle driver (psmDynamics)"},
                                {"duration", o.duration},
                                {"rate", o.rate},
                                {"seed", o.seed},
                                {"workspace", o.workspace},
                                {"step", s.excitation.step},
                                {"trocar", o.trocar},
                                {"seal", o.seal},
                                {"phantom", o.phantom ? "analytic half-space" : scene ? "the scene" : "none"},
                                {"noise", !o.noNoise},
                                {"samples", r.samples()}};
    if (o.phantom) j["phantomStiffness"] = s.phantom.stiffness;
    if (scene) {
      j["scene"] = o.scene;
      j["transform"] = o.transform;
      j["sceneSteps"] = scene->steps();
      j["palpatedSurface"] = {{"point", {s.phantom.point.x(), s.phantom.point.y(), s.phantom.point.z()}},
                              {"normal", {s.phantom.normal.x(), s.phantom.normal.y(), s.phantom.normal.z()}}};
    }
    j["files"] = {{"joints.csv", "measured joint states t,q1..q6,qd1..qd6,tau1..tau6 (rad, m, rad/s, m/s, N m, N)"},
                  {"wrench.csv", "true tip wrench the tool applies to the environment, base frame (N, N m)"},
                  {"truth.csv", "efforts: free-space dynamics, trocar (wall and seal), external J^T F; true tip position (m)"}};
    if (o.jacobian) j["files"]["jacobian.csv"] = "spatial Jacobian at the measured q, row-major";
    writeFileAtomic(dir + "/simulation.json", j.dump(2) + "\n");
  });
  double peak = 0;
  for (int i = 0; i < r.samples(); ++i) peak = std::max(peak, r.wrench.row(i).head<3>().norm());
  std::cerr << "wrote " << r.samples() << " samples (" << o.duration << " s at " << o.rate << " Hz) to " << o.out << " in "
            << std::setprecision(3) << seconds << " s; peak tip force " << peak << " N\n";
  return kExitOk;
}

// ---------------------------------------------------------------- train

struct TrainOptions {
  std::vector<std::string> data;
  std::string out, columns;
  learning::ForceTrainSpec spec;
  int threads = 0;
  bool quiet = false;
};

std::vector<ForceRecording> readRecordings(const std::vector<std::string>& paths, const std::string& columns, double rate) {
  std::vector<ForceRecording> out;
  for (const std::string& p : paths) out.push_back(learning::resampleRecording(learning::readForceRecording(p, 6, columns), rate));
  return out;
}

int runTrain(const TrainOptions& o) {
  std::vector<std::string> inputs = o.data;
  if (!o.spec.base.empty()) inputs.push_back(o.spec.base);
  requireOutputFolder(o.out, "--out", inputs, "force.json");
  if (!(o.spec.rate > 0)) throw Error("--rate: must be positive");
  if (o.threads > 0 && o.spec.kind != "physical") learning::setTorchThreads(o.threads);
  const auto recordings = readRecordings(o.data, o.columns, o.spec.rate);
  const auto t0 = std::chrono::steady_clock::now();
  const ForceModel model = learning::trainForceModel(o.spec, recordings, [&](const learning::ForceTrainReport& r) {
    if (!o.quiet) std::cerr << r.line << "\n";
  });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  writeFolderAtomically(o.out, [&](const std::string& dir) { model.save(dir); });
  std::cerr << "trained " << model.description << " in " << std::setprecision(3) << seconds << " s; wrote " << o.out << "\n";
  return kExitOk;
}

// ---------------------------------------------------------------- eval

struct EvalOptions {
  std::string model, out, columns;
  std::vector<std::string> data;
  double threshold = 0;  // N, contact for stiffness identification (0: from the forces)
  int threads = 0;
  bool noPlot = false;
};

nlohmann::ordered_json measuresJson(const robot::ErrorMeasures& m, const std::vector<std::string>& names) {
  nlohmann::ordered_json j = nlohmann::ordered_json::object();
  for (size_t c = 0; c < names.size(); ++c) {
    auto num = [](double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); };
    j[names[c]] = {{"rmse", num(m.rmse[c])}, {"nrmse", num(m.nrmse[c])}, {"rele", num(m.rele[c])}, {"range", num(m.range[c])}};
  }
  return j;
}

std::string percent(double v) {
  if (!std::isfinite(v)) return "-";
  std::ostringstream s;
  s << std::fixed << std::setprecision(2) << 100 * v << " %";
  return s.str();
}

int runEval(const EvalOptions& o) {
  std::vector<std::string> inputs = o.data;
  inputs.push_back(o.model);
  requireOutputFolder(o.out, "--out", inputs, "eval.json");
  if (o.threshold < 0) throw Error("--threshold: a force in N, >= 0 (0: from the forces)");
  if (o.threads > 0) learning::setTorchThreads(o.threads);
  const ForceModel model = ForceModel::load(o.model);
  const auto recordings = readRecordings(o.data, o.columns, model.rate);
  const robot::SerialChain psm = robot::psmLargeNeedleDriver();
  nlohmann::ordered_json report = {{"model", o.model}, {"description", model.description}, {"rate", model.rate}};
  std::vector<std::string> jointNames;
  for (int j = 1; j <= model.dof; ++j) jointNames.push_back("joint" + std::to_string(j));
  // Every recording's samples together, for the summary measures.
  Eigen::MatrixXd allEffort, allPredicted, allWrench, allEstimated;
  std::string csv = "recording,t";
  for (int j = 1; j <= model.dof; ++j) csv += ",tau" + std::to_string(j) + ",tau_hat" + std::to_string(j);
  for (const char* a : kAxes) csv += std::string(",") + a + "," + a + "_hat";
  csv += "\n";
  nlohmann::ordered_json perRecording = nlohmann::ordered_json::array();
  double seconds = 0;
  long long predictedSamples = 0;
  for (size_t k = 0; k < recordings.size(); ++k) {
    const ForceRecording& r = recordings[k];
    nlohmann::ordered_json rj = {{"recording", r.name}, {"samples", r.joints.samples()}};
    Eigen::MatrixXd predicted = Eigen::MatrixXd::Constant(r.joints.samples(), model.dof, NAN);
    const auto t0 = std::chrono::steady_clock::now();
    if (model.kind != "direct") {
      predicted = model.freeSpaceEfforts(r.joints);
      const Eigen::MatrixXd effort = r.joints.effort();
      rj["efforts"] = measuresJson(robot::errorMeasures(predicted, effort), jointNames);
      learning::appendRows(allEffort, effort);
      learning::appendRows(allPredicted, predicted);
    }
    Eigen::MatrixXd truth = Eigen::MatrixXd::Constant(r.joints.samples(), 6, NAN), estimated = truth;
    if (r.wrench) {
      truth = learning::wrenchAtJoints(r);
      const Eigen::MatrixXd* J = r.jacobian ? &r.jacobian->values : nullptr;
      estimated = model.wrenches(r.joints, J);
      const int axes = model.kind == "direct" && model.wrenchOutputs == 3 ? 3 : 6;
      rj["wrench"] = measuresJson(robot::errorMeasures(estimated.leftCols(axes), truth.leftCols(axes)),
                                  std::vector<std::string>(kAxes, kAxes + axes));
      learning::appendRows(allWrench, truth);
      learning::appendRows(allEstimated, estimated);
      // Stiffness from force against tool displacement, with the true and the estimated forces.
      Eigen::MatrixXd tips(r.joints.samples(), 3);
      for (int i = 0; i < r.joints.samples(); ++i) tips.row(i) = psm.tipPose(r.joints.q().row(i).transpose()).translation().transpose();
      try {
        const robot::StiffnessFit a = robot::identifyStiffness(tips, truth.leftCols(3), o.threshold);
        const robot::StiffnessFit b = robot::identifyStiffness(tips, estimated.leftCols(3), o.threshold);
        rj["stiffness"] = {{"fromTrueForces", a.stiffness},   {"fromEstimatedForces", b.stiffness},
                           {"relativeDifference", (b.stiffness - a.stiffness) / a.stiffness},
                           {"contacts", {a.episodes, b.episodes}}, {"contactSamples", {a.samples, b.samples}},
                           {"thresholds", {a.threshold, b.threshold}}, {"r2", {a.r2, b.r2}}};
      } catch (const Error& e) {
        rj["stiffness"] = {{"note", e.what()}};
      }
    }
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    predictedSamples += r.joints.samples();
    for (int i = 0; i < r.joints.samples(); ++i) {
      std::ostringstream line;
      line << std::setprecision(7) << k << "," << r.joints.series.t[i];
      for (int j = 0; j < model.dof; ++j) line << "," << r.joints.effort()(i, j) << "," << predicted(i, j);
      for (int a = 0; a < 6; ++a) line << "," << truth(i, a) << "," << estimated(i, a);
      csv += line.str() + "\n";
    }
    perRecording.push_back(rj);
  }
  report["recordings"] = perRecording;
  nlohmann::ordered_json all;
  std::ostringstream table;
  if (allEffort.rows()) {
    const robot::ErrorMeasures m = robot::errorMeasures(allPredicted, allEffort);
    all["efforts"] = measuresJson(m, jointNames);
    table << "free-space efforts (all recordings)\n  joint   NRMSE     RelE      RMSE       range\n";
    for (int j = 0; j < model.dof; ++j)
      table << "  " << j + 1 << "       " << std::setw(9) << std::left << percent(m.nrmse[j]) << " " << std::setw(9) << percent(m.rele[j])
            << " " << std::setw(10) << std::setprecision(4) << m.rmse[j] << " " << m.range[j] << std::right << "\n";
  }
  if (allWrench.rows()) {
    const int axes = model.kind == "direct" && model.wrenchOutputs == 3 ? 3 : 6;
    const robot::ErrorMeasures m = robot::errorMeasures(allEstimated.leftCols(axes), allWrench.leftCols(axes));
    all["wrench"] = measuresJson(m, std::vector<std::string>(kAxes, kAxes + axes));
    table << "tip wrench (all recordings)\n  axis    NRMSE     RelE      RMSE       range\n";
    for (int a = 0; a < axes; ++a)
      table << "  " << kAxes[a] << "      " << std::setw(9) << std::left << percent(m.nrmse[a]) << " " << std::setw(9) << percent(m.rele[a])
            << " " << std::setw(10) << std::setprecision(4) << m.rmse[a] << " " << m.range[a] << std::right << "\n";
  }
  for (const auto& rj : perRecording)
    if (rj.contains("stiffness") && rj["stiffness"].contains("fromTrueForces"))
      table << "stiffness " << rj["recording"].get<std::string>() << ": " << std::setprecision(4)
            << rj["stiffness"]["fromEstimatedForces"].get<double>() << " N/m from estimated forces, "
            << rj["stiffness"]["fromTrueForces"].get<double>() << " N/m from true forces ("
            << percent(rj["stiffness"]["relativeDifference"].get<double>()) << ")\n";
  report["all"] = all;
  report["predictionSecondsPerSample"] = seconds / static_cast<double>(std::max(1LL, predictedSamples));
  writeFolderAtomically(o.out, [&](const std::string& dir) {
    fs::create_directories(dir);
    writeFileAtomic(dir + "/eval.json", report.dump(2) + "\n");
    writeFileAtomic(dir + "/estimates.csv", csv);
    if (!o.noPlot) {
      // Estimate against truth over the first recording: efforts (indirect) and forces (with a wrench).
      std::ostringstream gp;
      gp << "set terminal pngcairo size 1400,900\nset output outfile\nset datafile separator ','\n"
            "set key top right opaque\nset grid\nset xlabel 't (s)'\n";
      const bool efforts = model.kind != "direct", forces = allWrench.rows() > 0;
      gp << "set multiplot layout " << (efforts && forces ? 2 : 1) << ",3 title '" << model.description << "'\n";
      if (efforts)
        for (int j = 1; j <= 3; ++j)
          gp << "set title 'joint " << j << "'\nplot 'estimates.csv' every ::1 using ($1==0?$2:1/0):" << 1 + 2 * j
             << " with lines title 'measured', '' every ::1 using ($1==0?$2:1/0):" << 2 + 2 * j << " with lines title 'estimated'\n";
      if (forces)
        for (int a = 0; a < 3; ++a)
          gp << "set title '" << kAxes[a] << " (N)'\nplot 'estimates.csv' every ::1 using ($1==0?$2:1/0):" << 3 + 2 * model.dof + 2 * a
             << " with lines title 'true', '' every ::1 using ($1==0?$2:1/0):" << 4 + 2 * model.dof + 2 * a
             << " with lines title 'estimated'\n";
      gp << "unset multiplot\n";
      writeFileAtomic(dir + "/eval.gp", gp.str());
      plotWithGnuplot(dir, "eval.gp", "eval.png");
    }
  });
  std::cout << table.str();
  std::cerr << "wrote " << o.out << "/eval.json, estimates.csv" << (o.noPlot ? "" : ", eval.gp and eval.png") << "\n";
  return kExitOk;
}

// ---------------------------------------------------------------- estimate

struct EstimateOptions {
  std::string model, log, out, columns, jacobian;
  double damping = 1e-3;
};

int runEstimate(const EstimateOptions& o) {
  cli::requireParentFolder(o.out, "--out");
  cli::requireNotAnInput(o.out, "--out", {o.log, o.jacobian});
  const ForceModel model = ForceModel::load(o.model);
  if (!(o.damping >= 0)) throw Error("--damping: must be >= 0");
  if (model.kind == "direct" && !o.jacobian.empty()) throw Error("--jacobian: a direct model estimates the force without one");
  ForceRecording raw{o.log, robot::readJointStateLog(o.log, model.dof, o.columns), {}, {}};
  if (!o.jacobian.empty()) raw.jacobian = robot::readJacobianCsv(o.jacobian, model.dof);
  const ForceRecording r = learning::resampleRecording(raw, model.rate);
  const Eigen::MatrixXd w = model.wrenches(r.joints, r.jacobian ? &r.jacobian->values : nullptr, o.damping);
  robot::writeSeries(o.out, robot::wrenchSeries(r.joints.series.t, w), 10);
  std::cerr << "wrote " << w.rows() << " wrenches at " << model.rate << " Hz to " << o.out << "\n";
  return kExitOk;
}

// ---------------------------------------------------------------- bench

struct BenchOptions {
  std::string model, data, columns;
  int samples = 2000, threads = 1;
};

// Latency of estimating sample by sample: for each sample, the model's wrench at that sample from
// the joint states of the last `history` samples only (the network sees one input row; a base
// model recomputes the window's rows, nothing is cached between samples), timed one by one.
int runBench(const BenchOptions& o) {
  if (o.samples < 10) throw Error("--samples: at least 10");
  learning::setTorchThreads(o.threads);
  const ForceModel model = ForceModel::load(o.model);
  const ForceRecording r = learning::resampleRecording(learning::readForceRecording(o.data, model.dof, o.columns), model.rate);
  int history = model.window;
  for (const ForceModel* m = model.base.get(); m; m = m->base.get()) history += m->window;
  history = std::max(history + 2, 3);  // accelerations need neighbours
  if (r.joints.samples() < history + o.samples)
    throw Error(o.data + ": " + std::to_string(r.joints.samples()) + " samples at " + std::to_string(model.rate) +
                " Hz; the benchmark needs " + std::to_string(history + o.samples));
  std::vector<double> micros;
  micros.reserve(static_cast<size_t>(o.samples));
  double sink = 0;
  for (int i = 0; i < o.samples; ++i) {
    const robot::JointStateLog slice = robot::sliceLog(r.joints, i, i + history);
    const auto t0 = std::chrono::steady_clock::now();
    const robot::Vector6d w = model.lastWrench(slice);
    micros.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    sink += w[0];
  }
  std::sort(micros.begin(), micros.end());
  auto at = [&](double share) { return micros[static_cast<size_t>(share * static_cast<double>(micros.size() - 1))]; };
  std::cout << std::fixed << std::setprecision(1) << model.description << "\n  " << o.samples << " samples, " << history
            << " joint states each, " << o.threads << " thread(s): median " << at(0.5) << " us, 90th percentile " << at(0.9)
            << " us, max " << micros.back() << " us per sample (" << (at(0.5) <= 1000 ? "within" : "beyond")
            << " 1 kHz)\n";
  if (!std::isfinite(sink)) std::cerr << "note: a non-finite estimate\n";
  return kExitOk;
}

}  // namespace

void addForceCommand(CLI::App& app, std::function<int()>& action) {
  auto* cmd = app.add_subcommand("force", "force estimation from robot signals: simulate arm data, train, evaluate, estimate, time");
  cmd->require_subcommand(1);

  auto s = std::make_shared<SimulateOptions>();
  auto* sim = cmd->add_subcommand("simulate", "write a PSM recording with known truth (joint dynamics, friction, trocar, phantom)");
  sim->footer(
      "The dVRK PSM's joint-space dynamics under a PID controller follow a teleoperation-like reference (minimum-jerk\n"
      "moves along a random walk of joint waypoints, plus a slow wander). --phantom adds a compliant surface under the tool: half the\n"
      "moves then palpate it. --trocar adds the body wall around the shaft, --seal the cannula seal's friction.\n"
      "Writes OUT/joints.csv (what a dVRK logs), wrench.csv (true tip wrench), truth.csv, simulation.json and, with\n"
      "--jacobian, jacobian.csv.");
  sim->add_option("out", s->out, "output folder")->required();
  sim->add_option("--duration", s->duration, "seconds of motion")->capture_default_str();
  sim->add_option("--rate", s->rate, "samples per second")->capture_default_str();
  sim->add_option("--seed", s->seed, "random seed of the reference and the noise")->capture_default_str();
  sim->add_option("--workspace", s->workspace, "full (free space) or trocar (outer joints confined, as inside a patient)")->capture_default_str();
  sim->add_option("--step", s->step, "largest move between waypoints, as a share of each joint's range (small: a random "
                                     "walk; large: moves across the workspace, for a short calibration recording; "
                                     "waypoints are clamped to the ranges)")
      ->capture_default_str();
  sim->add_flag("--trocar", s->trocar, "the body wall holds the shaft near the remote centre");
  sim->add_flag("--seal", s->seal, "the cannula seal's friction on insertion and roll");
  sim->add_flag("--phantom", s->phantom, "a compliant phantom under the tool, palpated");
  auto* stiffness = sim->add_option("--stiffness", s->stiffness, "the phantom's stiffness (N/m; default 600)");
  auto* sceneOption = sim->add_option("--scene", s->scene, "a Viscera scene as the environment: its instrument (without a driver) "
                                                          "follows the tip, its contact wrench is the true force; palpates its body")
                          ->excludes(stiffness);
  sim->add_option("--transform", s->transform, "robot base -> scene transform file (with --scene)")->needs(sceneOption);
  sim->add_option("--instrument", s->instrument, "the scene's instrument (a Rigid3d MechanicalObject's name)")->needs(sceneOption);
  sim->add_option("--depth", s->depth, "MIN:MAX commanded depth of the palpations below the surface (m; the tip's centre; "
                                       "default 0.004:0.018)");
  sim->add_flag("--no-noise", s->noNoise, "perfect sensors: no noise, no backlash");
  sim->add_flag("--jacobian", s->jacobian, "also write jacobian.csv (the Jacobian at each sample; large)");
  sim->add_option("--digits", s->digits, "significant digits of the written values (1 to 17)")->check(CLI::Range(1, 17))->capture_default_str();
  sim->callback([s, &action] { action = [s] { return runSimulate(*s); }; });

  auto t = std::make_shared<TrainOptions>();
  auto* train = cmd->add_subcommand("train", "identify or train a force model on recordings");
  train->footer(
      "Kinds: physical (least-squares identification of the arm's dynamic parameters), mlp (one network per\n"
      "joint, 12-100-1, Table 2-4), snn (one network for all joints), lstm (per joint, LSTM 64 over 10 samples\n"
      "and two layers), correction (the trocar correction: window 30 of joint states plus the --base model's\n"
      "prediction, 256 hidden, learns the base's residual), direct (window of joint velocities and efforts to\n"
      "the tip force; needs wrench.csv). mlp and lstm with --base learn the base's residual. DATA: recording\n"
      "folders (joints.csv, wrench.csv) or joint logs; free-space kinds take every sample's effort as\n"
      "free-space dynamics. Logs are resampled to --rate.");
  train->add_option("data", t->data, "recordings")->required();
  train->add_option("--out", t->out, "model folder")->required();
  train->add_option("--kind", t->spec.kind, "physical, mlp, snn, lstm, correction or direct")->capture_default_str();
  train->add_option("--base", t->spec.base, "base model folder (correction; residual mlp or lstm)");
  train->add_option("--rate", t->spec.rate, "Hz the model works at")->capture_default_str();
  train->add_option("--window", t->spec.window, "samples per input window (0: the kind's default)")->capture_default_str();
  train->add_option("--hidden", t->spec.hidden, "hidden units (0: the kind's default)")->capture_default_str();
  train->add_option("--epochs", t->spec.epochs, "epochs (0: the kind's default)")->capture_default_str();
  train->add_option("--batch", t->spec.batch, "samples per batch")->capture_default_str();
  train->add_option("--lr", t->spec.learningRate, "Adam's learning rate")->capture_default_str();
  train->add_option("--weight-decay", t->spec.weightDecay, "L2 penalty on the weights (Adam's weight decay)")->capture_default_str();
  train->add_option("--validation", t->spec.validation, "last share of each recording kept for validation")->capture_default_str();
  train->add_option("--patience", t->spec.patience, "stop after this many epochs without a better validation loss (0: never)")->capture_default_str();
  train->add_option("--seed", t->spec.seed, "random seed")->capture_default_str();
  train->add_flag("!--wrench", t->spec.forces, "direct: estimate the whole wrench (forces and torques), not the force alone");
  train->add_option("--columns", t->columns, "column map of the joint logs, e.g. t,q1,...,q7,qd1,...");
  train->add_option("--threads", t->threads, "LibTorch threads (0: its default)")->capture_default_str();
  train->add_flag("--quiet", t->quiet, "no per-epoch lines");
  train->callback([t, &action] { action = [t] { return runTrain(*t); }; });

  auto e = std::make_shared<EvalOptions>();
  auto* ev = cmd->add_subcommand("eval", "a force model's errors on recordings: NRMSE and RelE per joint and axis, stiffness, plots");
  ev->footer(
      "Free-space efforts are compared with each recording's measured efforts (meaningful on free-space recordings);\n"
      "with wrench.csv, the estimated tip wrench with the true one, and the phantom's stiffness identified from force\n"
      "against tool displacement with both. Writes OUT/eval.json, estimates.csv and (unless --no-plot) eval.png.");
  ev->add_option("model", e->model, "force model folder")->required();
  ev->add_option("data", e->data, "recordings")->required();
  ev->add_option("--out", e->out, "output folder")->required();
  ev->add_option("--columns", e->columns, "column map of the joint logs");
  ev->add_option("--threshold", e->threshold, "force above which the tool is in contact, for stiffness (N; 0: a fifth of the 99th percentile)")->capture_default_str();
  ev->add_option("--threads", e->threads, "LibTorch threads (0: its default)")->capture_default_str();
  ev->add_flag("--no-plot", e->noPlot, "no eval.png");
  ev->callback([e, &action] { action = [e] { return runEval(*e); }; });

  auto x = std::make_shared<EstimateOptions>();
  auto* est = cmd->add_subcommand("estimate", "write the tip wrench a force model estimates along a joint log");
  est->add_option("model", x->model, "force model folder")->required();
  est->add_option("log", x->log, "joint state log (t,q1..q6,qd1..qd6,tau1..tau6)")->required();
  est->add_option("--out", x->out, "wrench CSV (t,Fx,Fy,Fz,Tx,Ty,Tz) at the model's rate")->required();
  est->add_option("--columns", x->columns, "column map of the joint log");
  est->add_option("--jacobian", x->jacobian, "Jacobian log (t,J1_1..J6_6, row-major) instead of the PSM's kinematics");
  est->add_option("--damping", x->damping, "damping of the pseudo-inverse J^-T")->capture_default_str();
  est->callback([x, &action] { action = [x] { return runEstimate(*x); }; });

  auto b = std::make_shared<BenchOptions>();
  auto* bench = cmd->add_subcommand("bench", "time a force model's estimate sample by sample (the online latency)");
  bench->add_option("model", b->model, "force model folder")->required();
  bench->add_option("data", b->data, "a recording to take joint states from")->required();
  bench->add_option("--samples", b->samples, "samples timed")->capture_default_str();
  bench->add_option("--threads", b->threads, "LibTorch threads")->capture_default_str();
  bench->add_option("--columns", b->columns, "column map of the joint log");
  bench->callback([b, &action] { action = [b] { return runBench(*b); }; });
}

}  // namespace viscera
