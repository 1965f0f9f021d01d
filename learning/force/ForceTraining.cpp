#include "learning/force/ForceTraining.h"

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/Error.h"

namespace viscera::learning {

namespace fs = std::filesystem;

ForceRecording readForceRecording(const std::string& path, int dof, const std::string& columns) {
  ForceRecording r;
  r.name = path;
  if (fs::is_directory(path)) {
    const fs::path joints = fs::path(path) / "joints.csv";
    if (!fs::exists(joints)) throw Error(path + ": a recording folder holds joints.csv (t,q1..,qd1..,tau1..)");
    r.joints = robot::readJointStateLog(joints.string(), dof, columns);
    if (const fs::path w = fs::path(path) / "wrench.csv"; fs::exists(w)) r.wrench = robot::readWrenchCsv(w.string());
    if (const fs::path j = fs::path(path) / "jacobian.csv"; fs::exists(j)) r.jacobian = robot::readJacobianCsv(j.string(), dof);
  } else {
    r.joints = robot::readJointStateLog(path, dof, columns);
  }
  return r;
}

ForceRecording resampleRecording(const ForceRecording& r, double rate) {
  double start = r.joints.series.t.front(), end = r.joints.series.t.back();
  for (const auto* s : {&r.wrench, &r.jacobian})
    if (*s) {
      const auto span = robot::overlap(r.joints.series, **s);
      start = std::max(start, span.first);
      end = std::min(end, span.second);
    }
  const std::vector<double> times = robot::uniformTimes(start, end, rate);
  ForceRecording out;
  out.name = r.name;
  // Joint states: box-averaged over each new period, centred on the common times.
  out.joints = robot::JointStateLog{r.joints.dof, robot::averageAt(r.joints.series, times, 1 / rate)};
  if (r.wrench) out.wrench = robot::interpolate(*r.wrench, times);
  if (r.jacobian) out.jacobian = robot::interpolate(*r.jacobian, times);
  return out;
}

Eigen::MatrixXd wrenchAtJoints(const ForceRecording& r) {
  if (!r.wrench) throw Error(r.name + ": no wrench (wrench.csv) to compare with or train on");
  return robot::interpolate(*r.wrench, r.joints.series.t).values;
}

ForceModel trainForceModel(const ForceTrainSpec& spec, const std::vector<ForceRecording>& recordings,
                           const std::function<void(const ForceTrainReport&)>& progress) {
  if (recordings.empty()) throw Error("force training: no recordings");
  if (!(spec.validation >= 0 && spec.validation < 1)) throw Error("--validation: a share in [0, 1)");
  const int dof = recordings.front().joints.dof;
  ForceModel model;
  model.rate = spec.rate;
  model.dof = dof;
  const std::string& k = spec.kind;
  auto say = [&](const std::string& s) {
    if (progress) progress({s});
  };

  // Samples [0, cut) of each recording train and [cut, end) validate: a split in time, so that
  // validation samples are not neighbours of training ones.
  std::vector<robot::JointStateLog> trainLogs, validationLogs;
  std::vector<Eigen::MatrixXd> trainWrench, validationWrench;
  for (const ForceRecording& r : recordings) {
    if (r.joints.dof != dof) throw Error(r.name + ": " + std::to_string(r.joints.dof) + " joints, the first recording " + std::to_string(dof));
    const int n = r.joints.samples();
    const int cut = static_cast<int>(std::lround(n * (1 - spec.validation)));
    if (cut < 2) throw Error(r.name + ": too short to train on (" + std::to_string(n) + " samples)");
    trainLogs.push_back(robot::sliceLog(r.joints, 0, cut));
    if (cut < n) validationLogs.push_back(robot::sliceLog(r.joints, cut, n));
    if (k == "direct") {
      const Eigen::MatrixXd w = wrenchAtJoints(r);
      trainWrench.push_back(w.topRows(cut));
      if (cut < n) validationWrench.push_back(w.bottomRows(n - cut));
    }
  }

  if (k == "physical") {
    if (spec.window > 0 || spec.hidden > 0 || spec.epochs > 0 || !spec.base.empty() || spec.weightDecay != 0)
      throw Error("--window, --hidden, --epochs, --weight-decay and --base are for networks; the physical model is identified by "
                  "least squares");
    model.kind = "physical";
    model.description = "physical model (least-squares identification)";
    say("identifying " + std::to_string(robot::PhysicalModel::parameterCount(dof)) + " parameters");
    model.physical = robot::PhysicalModel::identify(robot::psmDynamics(), trainLogs);
    model.training = nlohmann::ordered_json{{"kind", k}, {"rate", spec.rate}, {"samples", [&] {
                                              long long n = 0;
                                              for (const auto& l : trainLogs) n += l.samples();
                                              return n;
                                            }()}}.dump();
    return model;
  }

  RegressorArchitecture a;
  RegressorTrainOptions o;
  o.batch = spec.batch;
  o.learningRate = spec.learningRate;
  o.weightDecay = spec.weightDecay;
  o.patience = spec.patience;
  o.seed = spec.seed;
  int defaultEpochs = 60;
  if (k == "mlp" || k == "snn") {
    a.kind = "mlp";
    a.window = 1;
    a.hidden = 100;
    a.activation = "tanh";
    a.perOutput = k == "mlp";
    if (k == "snn") a.outputScaling = "none";  // one loss over all joints in their own units (Table 2-4's SNN)
  } else if (k == "lstm") {
    a.kind = "lstm";
    a.window = 10;
    a.hidden = 64;
    a.perOutput = true;
    defaultEpochs = 20;
  } else if (k == "correction") {
    a.kind = "mlp";
    a.window = 30;
    a.hidden = 256;
    a.activation = "relu";
    a.perOutput = true;
    defaultEpochs = 20;
  } else if (k == "direct") {
    a.kind = "mlp";
    a.window = 10;
    a.hidden = 100;
    a.layers = 2;
    a.activation = "leakyrelu";
    a.perOutput = false;
    a.outputScaling = "range";
    o.loss = "mae";
  } else {
    throw Error("--kind: " + viscera::quoted(k) + " is not one of physical, mlp, snn, lstm, correction, direct");
  }
  if (!spec.forces && k != "direct") throw Error("--wrench: only a direct model estimates the wrench itself");
  if (spec.window > 0) a.window = spec.window;
  if (spec.hidden > 0) a.hidden = spec.hidden;
  o.epochs = spec.epochs > 0 ? spec.epochs : defaultEpochs;

  model.kind = k == "direct" ? "direct" : "network";
  model.window = a.window;
  if (k == "correction" && spec.base.empty()) throw Error("--base: the correction corrects a free-space model; name its folder");
  if (!spec.base.empty()) {
    if (k == "direct" || k == "snn") throw Error("--base: a " + k + " model has no base");
    model.base = std::make_shared<ForceModel>(ForceModel::load(spec.base));
    if (model.base->kind == "direct") throw Error("--base: " + spec.base + " is a direct model, not a free-space one");
    if (model.base->rate != spec.rate || model.base->dof != dof)
      throw Error("--base: " + spec.base + " works at " + std::to_string(model.base->rate) + " Hz with " +
                  std::to_string(model.base->dof) + " joints, the training at " + std::to_string(spec.rate) + " Hz with " +
                  std::to_string(dof));
    model.baseInputs = k == "correction";
  }
  a.features = k == "direct" ? 2 * dof : (model.baseInputs ? 3 * dof : 2 * dof);
  a.outputs = k == "direct" ? (spec.forces ? 3 : 6) : dof;
  model.wrenchOutputs = a.outputs;

  struct {
    RegressorData train, validation;
  } data;
  auto fill = [&](const std::vector<robot::JointStateLog>& logs, const std::vector<Eigen::MatrixXd>& wrenches, RegressorData& d) {
    for (size_t i = 0; i < logs.size(); ++i) {
      appendRows(d.x, model.networkInputs(logs[i]));
      Eigen::MatrixXd y;
      if (k == "direct") {
        y = wrenches[i].leftCols(a.outputs);
      } else {
        y = logs[i].effort();
        if (model.base) y -= model.base->freeSpaceEfforts(logs[i]);
      }
      appendRows<Eigen::MatrixXf>(d.y, y.cast<float>());
    }
  };
  fill(trainLogs, trainWrench, data.train);
  fill(validationLogs, validationWrench, data.validation);

  std::ostringstream desc;
  desc << (k == "snn" ? "single network" : k == "direct" ? "direct network" : a.perOutput ? "per-joint networks" : "network") << " ("
       << a.kind << ", window " << a.window << ", " << a.features << " inputs per sample, hidden " << a.hidden
       << (model.base ? ", on base " + model.base->description : "") << ")";
  model.description = desc.str();
  say(model.description + ": " + std::to_string(data.train.samples()) + " training and " +
      std::to_string(data.validation.samples()) + " validation samples");
  nlohmann::ordered_json notes = {{"kind", k},
                                  {"trainingSamples", data.train.samples()},
                                  {"validationSamples", data.validation.samples()},
                                  {"rate", spec.rate},
                                  {"epochs", o.epochs},
                                  {"batch", o.batch},
                                  {"learningRate", o.learningRate},
                                  {"weightDecay", o.weightDecay},
                                  {"loss", o.loss},
                                  {"seed", o.seed}};
  double lastValidation = NAN;
  model.network = Regressor::train(a, o, data.train, data.validation, [&](const RegressorEpochReport& r) {
    std::ostringstream s;
    s << "epoch " << r.epoch << "/" << o.epochs << "  train " << r.trainLoss << "  validation " << r.validationLoss << "  "
      << r.seconds << " s" << (r.best ? "  (best)" : "");
    if (r.best) lastValidation = r.validationLoss;
    say(s.str());
  });
  if (std::isfinite(lastValidation)) notes["bestValidationLoss"] = lastValidation;
  model.training = notes.dump();
  return model;
}

}  // namespace viscera::learning
