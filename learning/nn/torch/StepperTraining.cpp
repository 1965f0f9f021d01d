// Training the learned stepper on recorded rollouts (dissertation §4.4.1.3 and §4.4.1.6): L2 between
// the predicted and the FEM's next frame, and after a warm-up half of each batch's inputs replaced by
// the model's own prediction from the frame before, so that it learns to correct its own errors.
// Two more stabilisers from learned simulators (Sanchez-Gonzalez et al. 2020): those predictions
// chain up to `unroll` frames, and every input carries a little smooth random displacement; the
// target stays the FEM's next frame, so the model learns to pull a disturbed state back.
//
// Differences from the dissertation, for training on a CPU in minutes: Adam (not SGD with momentum),
// the rate halved when the held-out rollout error stops improving or following a half cosine over
// the epochs, and the augmented inputs made by the current network (not the last epoch's) as the
// batch is drawn.
#include <Eigen/SparseCore>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "core/Error.h"
#include "core/Files.h"
#include "learning/nn/torch/GraphUNet.h"

namespace viscera::learning {

namespace fs = std::filesystem;

namespace {

struct Sample {
  int rollout = 0, frame = 0;  // input at `frame`, target at frame + 1
};

void checkOptions(const StepperTrainOptions& o) {
  if (o.data.empty()) throw Error("stepper training: give at least one recording folder");
  if (o.out.empty()) throw Error("stepper training: --out is required");
  if (o.epochs < 1 || o.epochs > 1000000) throw Error("--epochs: must be 1 to 1000000, got " + std::to_string(o.epochs));
  if (o.batch < 1 || o.batch > 4096) throw Error("--batch: must be 1 to 4096, got " + std::to_string(o.batch));
  if (!(o.learningRate > 0) || !std::isfinite(o.learningRate)) throw Error("--lr: must be positive");
  if (o.warmup < 0) throw Error("--warmup: must be >= 0 epochs");
  if (o.unroll < 1 || o.unroll > 100) throw Error("--unroll: must be 1 to 100 frames");
  if (!(o.noise >= 0) || !(o.noise < 1)) throw Error("--noise: must be in [0, 1) cells");
  if (!(o.validation > 0) || !(o.validation < 1)) throw Error("--validation: must be a share in (0, 1)");
  if (!(o.validationTime > 0)) throw Error("--validation-time: must be positive");
  if (o.patience < 1) throw Error("--patience: must be >= 1 epoch");
  if (!(o.reachCells >= 0) || !std::isfinite(o.reachCells)) throw Error("--reach: must be >= 0 cells");
  if (o.threads < 0) throw Error("--threads: must be >= 0 (0: every core)");
  const fs::path checkpoint = fs::path(o.out) / "checkpoint" / "state.json";
  if (o.resume && !fs::exists(checkpoint))
    throw Error(SourceLoc{o.out}, "--resume: no checkpoint to resume from (" + checkpoint.string() + " is missing)");
  if (!o.resume && fs::exists(o.out))
    throw Error(SourceLoc{o.out}, "--out: already exists (nothing was changed); --resume continues its training");
}

double lrOf(torch::optim::Adam& opt) {
  return static_cast<torch::optim::AdamOptions&>(opt.param_groups().front().options()).lr();
}
void setLr(torch::optim::Adam& opt, double lr) {
  for (auto& g : opt.param_groups()) static_cast<torch::optim::AdamOptions&>(g.options()).lr(lr);
}

// The cosine schedule's rate for epoch `epoch` of `epochs` (1-based): the initial rate at the first.
double cosineRate(double initial, int epoch, int epochs) {
  return initial * 0.5 * (1 + std::cos(M_PI * (epoch - 1) / epochs));
}

const char* scheduleName(RateSchedule s) { return s == RateSchedule::Cosine ? "cosine" : "plateau"; }

}  // namespace

void torchTrainStepper(const StepperTrainOptions& o, const std::function<void(const EpochReport&)>& progress) {
  checkOptions(o);
  torch::set_num_threads(o.threads > 0 ? o.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));

  // The recordings: one mesh, one frame rate, one unit system.
  std::vector<RolloutSet> sets;
  for (const std::string& d : o.data) sets.push_back(readRolloutSet(d));
  const RolloutSet& first = sets.front();
  const std::uint64_t hash = meshHash(first.mesh);
  for (const RolloutSet& s : sets) {
    if (meshHash(s.mesh) != hash) throw Error(SourceLoc{s.folder}, "another mesh than " + first.folder + "'s: a model learns one mesh");
    if (std::abs(s.frameRate / first.frameRate - 1) > 1e-9)
      throw Error(SourceLoc{s.folder}, "another frame rate than " + first.folder + "'s");
    if (s.units != first.units) throw Error(SourceLoc{s.folder}, "other units than " + first.folder + "'s");
  }
  const int nodes = static_cast<int>(first.mesh.points.cols());
  std::vector<std::vector<RolloutFrame>> rollouts;
  std::vector<std::string> files;
  for (const RolloutSet& s : sets)
    for (const std::string& f : s.files) {
      rollouts.push_back(readRollout(f, nodes));
      files.push_back((fs::path(s.folder).filename() / fs::path(f).filename()).string());
      if (rollouts.back().size() < 2) rollouts.pop_back(), files.pop_back();
    }
  if (rollouts.size() < 2) throw Error("stepper training needs at least two rollouts of two frames or more (one is held out)");
  const int held = std::max(1, static_cast<int>(std::lround(o.validation * rollouts.size())));
  const int trained = static_cast<int>(rollouts.size()) - held;
  if (trained < 1) throw Error("--validation leaves no rollout to train on");

  // Normalisers from the mesh and the training rollouts.
  StepperNormalisers norm;
  norm.cell = meshCellSize(first.mesh);
  norm.boxMin = first.mesh.points.rowwise().minCoeff();
  norm.boxMax = first.mesh.points.rowwise().maxCoeff();
  norm.reach = first.instrumentRadius + o.reachCells * norm.cell.maxCoeff();
  double speed2 = 0;
  long count = 0;
  for (int r = 0; r < trained; ++r)
    for (const RolloutFrame& f : rollouts[r]) speed2 += f.velocity.squaredNorm(), ++count;
  norm.velocityScale = std::max(1e-9, std::sqrt(speed2 / std::max(1L, count)));

  const fs::path out(o.out), checkpointDir = out / "checkpoint";
  int startEpoch = 1, sinceBest = 0, bestEpoch = 0;
  double bestError = std::numeric_limits<double>::infinity(), lr = o.learningRate, initialLr = o.learningRate;
  std::optional<Stepper> model;
  if (o.resume) {
    model.emplace(loadTorchStepper(checkpointDir.string()));
    model->checkMesh(first.mesh, "the recording " + first.folder);
    if (std::abs(model->framePeriod() * first.frameRate - 1) > 1e-9 || model->units() != first.units)
      throw Error(SourceLoc{first.folder}, "the recording's frame rate or units are not the checkpoint model's");
    const std::string statePath = (checkpointDir / "state.json").string();
    try {
      const nlohmann::json st = nlohmann::json::parse(readInputFile(statePath, "checkpoint state"));
      startEpoch = st.at("epoch").get<int>() + 1;
      sinceBest = st.at("sinceBest").get<int>();
      bestEpoch = st.at("bestEpoch").get<int>();
      if (st.contains("bestError")) bestError = st.at("bestError").get<double>();
      lr = st.at("learningRate").get<double>();
      // The schedule goes on as it began: its kind, its initial rate and (cosine) its length are the
      // checkpoint's. A checkpoint from before they were stored ran the plateau schedule.
      const std::string schedule = st.value("schedule", std::string("plateau"));
      if (schedule != scheduleName(o.schedule))
        throw Error(SourceLoc{statePath}, "--schedule: the checkpoint was trained with the " + schedule + " schedule; resume with --schedule " + schedule);
      initialLr = st.value("initialLearningRate", o.learningRate);
      if (o.schedule == RateSchedule::Cosine && st.at("epochs").get<int>() != o.epochs)
        throw Error(SourceLoc{statePath}, "--epochs: the checkpoint's cosine schedule runs over " + std::to_string(st.at("epochs").get<int>()) +
                                              " epochs; resume with --epochs " + std::to_string(st.at("epochs").get<int>()));
    } catch (const nlohmann::json::exception& e) {
      throw Error(SourceLoc{statePath}, std::string("malformed checkpoint state: ") + e.what());
    }
  } else {
    model.emplace(newTorchStepper(first.mesh, o.architecture, norm, 1 / first.frameRate, first.units, o.seed));
  }
  TorchStepper& m = static_cast<TorchStepper&>(model->impl());
  torch::optim::Adam optimizer(m.net->parameters(), torch::optim::AdamOptions(lr));
  if (o.resume) {
    try {
      torch::load(optimizer, (checkpointDir / "optimizer.pt").string());
    } catch (const c10::Error& e) {
      throw Error(SourceLoc{(checkpointDir / "optimizer.pt").string()}, std::string("cannot read the optimiser's state: ") + e.what_without_backtrace());
    }
    setLr(optimizer, lr);
  }

  std::vector<Sample> samples;
  for (int r = 0; r < trained; ++r)
    for (int f = 0; f + 1 < static_cast<int>(rollouts[r].size()); ++f) samples.push_back({r, f});
  std::vector<Sample> validationSamples;  // every third frame of the held-out rollouts
  for (int r = trained; r < static_cast<int>(rollouts.size()); ++r)
    for (int f = 0; f + 1 < static_cast<int>(rollouts[r].size()); f += 3) validationSamples.push_back({r, f});
  const torch::Tensor cell = torch::tensor({float(m.norm.cell[0]), float(m.norm.cell[1]), float(m.norm.cell[2])}).view({1, 1, 3});
  // The scaled update error of a batch; `input` gives the positions each sample starts from.
  auto batchLoss = [&](const std::vector<Sample>& batch, const std::vector<Eigen::Matrix3Xf>& input) {
    const int B = static_cast<int>(batch.size());
    torch::Tensor feats = torch::empty({nodes, B, kStepperInputs});
    torch::Tensor target = torch::empty({nodes, B, 3});
    auto tg = target.accessor<float, 3>();
    for (int b = 0; b < B; ++b) {
      const RolloutFrame& next = rollouts[batch[b].rollout][batch[b].frame + 1];
      m.features(input[b], InstrumentInput{next.tip, next.velocity}, feats, b);
      for (int i = 0; i < nodes; ++i)
        for (int a = 0; a < 3; ++a) tg[i][b][a] = next.x(a, i) - input[b](a, i);
    }
    return ((m.update(feats) - target) / cell).pow(2).mean();
  };

  // Noise on the inputs: white noise smoothed by repeated neighbour means (the drift of a rollout is
  // smooth, not node by node), zero at fixed nodes, scaled to `noise` cells RMS along each axis.
  Eigen::SparseMatrix<float> smoothing(nodes, nodes);
  {
    std::vector<Eigen::Triplet<float>> t;
    std::vector<int> degree(nodes, 1);
    for (auto [a, b] : m.graph.levels[0].edges) ++degree[a], ++degree[b];
    for (int i = 0; i < nodes; ++i) t.emplace_back(i, i, 1.0f / degree[i]);
    for (auto [a, b] : m.graph.levels[0].edges) t.emplace_back(a, b, 1.0f / degree[a]), t.emplace_back(b, a, 1.0f / degree[b]);
    smoothing.setFromTriplets(t.begin(), t.end());
  }
  auto smoothNoise = [&](std::mt19937_64& rng) {
    std::normal_distribution<float> gauss(0.0f, 1.0f);
    Eigen::MatrixX3f w(nodes, 3);
    for (int i = 0; i < nodes; ++i)
      for (int a = 0; a < 3; ++a) w(i, a) = gauss(rng);
    for (int pass = 0; pass < 8; ++pass) w = smoothing * w;
    for (int i = 0; i < nodes; ++i)
      if (m.fixed[i]) w.row(i).setZero();
    Eigen::Matrix3Xf out = w.transpose();
    for (int a = 0; a < 3; ++a) {
      const float rms = std::sqrt(out.row(a).squaredNorm() / nodes);
      if (rms > 0) out.row(a) *= static_cast<float>(o.noise * m.norm.cell[a]) / rms;
    }
    return out;
  };

  const std::string command = o.command;
  nlohmann::ordered_json trainingRecord;
  for (int epoch = startEpoch; epoch <= o.epochs; ++epoch) {
    const auto e0 = std::chrono::steady_clock::now();
    // Each epoch's order from the epoch's own seed: a resumed training draws the batches it would have.
    std::mt19937_64 rng(o.seed * 1000003ull + static_cast<std::uint64_t>(epoch));
    std::vector<Sample> order = samples;
    std::shuffle(order.begin(), order.end(), rng);
    if (o.schedule == RateSchedule::Cosine) setLr(optimizer, cosineRate(initialLr, epoch, o.epochs));
    const bool augment = epoch > o.warmup;
    m.net->train();
    double lossSum = 0;
    long batches = 0;
    for (size_t s0 = 0; s0 < order.size(); s0 += o.batch) {
      const std::vector<Sample> batch(order.begin() + s0, order.begin() + std::min(order.size(), s0 + o.batch));
      std::vector<Eigen::Matrix3Xf> input(batch.size());
      std::vector<int> fromModel, depth;  // samples whose input is the model's own prediction, over `depth` frames
      for (size_t b = 0; b < batch.size(); ++b) {
        input[b] = rollouts[batch[b].rollout][batch[b].frame].x;
        if (augment && batch[b].frame > 0 && (rng() & 1)) {
          fromModel.push_back(static_cast<int>(b));
          depth.push_back(1 + static_cast<int>(rng() % std::min<std::uint64_t>(o.unroll, batch[b].frame)));
        }
      }
      if (!fromModel.empty()) {
        // Chain the model from frame - depth up to frame; samples join as their start comes.
        torch::NoGradGuard noGrad;
        const int A = static_cast<int>(fromModel.size());
        const int longest = *std::max_element(depth.begin(), depth.end());
        std::vector<Eigen::Matrix3Xf> x(A);
        for (int k = 0; k < A; ++k) {
          const Sample& s = batch[fromModel[k]];
          x[k] = rollouts[s.rollout][s.frame - depth[k]].x;
        }
        for (int d = longest; d >= 1; --d) {
          std::vector<int> active;
          for (int k = 0; k < A; ++k)
            if (depth[k] >= d) active.push_back(k);
          torch::Tensor feats = torch::empty({nodes, static_cast<long>(active.size()), kStepperInputs});
          for (size_t j = 0; j < active.size(); ++j) {
            const Sample& s = batch[fromModel[active[j]]];
            const RolloutFrame& to = rollouts[s.rollout][s.frame - d + 1];
            m.features(x[active[j]], InstrumentInput{to.tip, to.velocity}, feats, static_cast<int>(j));
          }
          const torch::Tensor u = m.update(feats).contiguous();
          auto ua = u.accessor<float, 3>();
          for (size_t j = 0; j < active.size(); ++j)
            for (int i = 0; i < nodes; ++i)
              for (int a = 0; a < 3; ++a) x[active[j]](a, i) += ua[i][j][a];
        }
        for (int k = 0; k < A; ++k) input[fromModel[k]] = std::move(x[k]);
      }
      if (o.noise > 0)
        for (auto& x : input) x += smoothNoise(rng);
      const torch::Tensor loss = batchLoss(batch, input);
      optimizer.zero_grad();
      loss.backward();
      optimizer.step();
      lossSum += loss.item<double>();
      ++batches;
    }
    m.net->eval();
    EpochReport rep;
    rep.epoch = epoch;
    rep.epochs = o.epochs;
    rep.trainLoss = lossSum / std::max(1L, batches);
    {
      torch::NoGradGuard noGrad;
      double v = 0;
      long vb = 0;
      for (size_t s0 = 0; s0 < validationSamples.size(); s0 += o.batch) {
        const std::vector<Sample> batch(validationSamples.begin() + s0,
                                        validationSamples.begin() + std::min(validationSamples.size(), s0 + o.batch));
        std::vector<Eigen::Matrix3Xf> input;
        for (const Sample& s : batch) input.push_back(rollouts[s.rollout][s.frame].x);
        v += batchLoss(batch, input).item<double>();
        ++vb;
      }
      rep.validationLoss = v / std::max(1L, vb);
    }
    double err = 0, base = 0;
    for (int r = trained; r < static_cast<int>(rollouts.size()); ++r) {
      const RolloutEvaluation ev = evaluateRollout(*model, rollouts[r], o.validationTime, o.validationTime);
      err += ev.mean;
      base += ev.baselineMean;
    }
    rep.rolloutError = err / held;
    rep.baselineError = base / held;
    rep.learningRate = lrOf(optimizer);
    rep.best = std::isfinite(rep.rolloutError) && rep.rolloutError < bestError;

    trainingRecord = nlohmann::ordered_json::object();
    trainingRecord["command"] = command;
    trainingRecord["data"] = nlohmann::json::array();
    for (const std::string& d : o.data) trainingRecord["data"].push_back(d);  // as given: a model folder names no machine's paths
    trainingRecord["trainingRollouts"] = trained;
    trainingRecord["heldOutRollouts"] = std::vector<std::string>(files.begin() + trained, files.end());
    trainingRecord["samples"] = samples.size();
    trainingRecord["optimizer"] = "Adam";
    trainingRecord["initialLearningRate"] = initialLr;
    trainingRecord["rateSchedule"] = scheduleName(o.schedule);
    trainingRecord["batch"] = o.batch;
    trainingRecord["warmupEpochs"] = o.warmup;
    trainingRecord["unroll"] = o.unroll;
    trainingRecord["noiseCells"] = o.noise;
    trainingRecord["seed"] = o.seed;
    if (rep.best) {
      bestError = rep.rolloutError;
      bestEpoch = epoch;
      sinceBest = 0;
      trainingRecord["epoch"] = epoch;
      trainingRecord["heldOutRolloutError"] = rep.rolloutError;
      trainingRecord["heldOutBaselineError"] = rep.baselineError;
      trainingRecord["heldOutTime"] = o.validationTime;
      model->save(out.string(), trainingRecord.dump());
      saveOptimizer(optimizer, (out / "optimizer.pt").string());
    } else if (++sinceBest >= o.patience && o.schedule == RateSchedule::Plateau) {
      setLr(optimizer, lrOf(optimizer) / 2);
      sinceBest = 0;
    }
    // The checkpoint: this epoch's network and optimiser, to resume from.
    trainingRecord["epoch"] = epoch;
    model->save(checkpointDir.string(), trainingRecord.dump());
    saveOptimizer(optimizer, (checkpointDir / "optimizer.pt").string());
    nlohmann::ordered_json st = {{"epoch", epoch},       {"sinceBest", sinceBest},          {"bestEpoch", bestEpoch},
                                 {"learningRate", lrOf(optimizer)}, {"schedule", scheduleName(o.schedule)},
                                 {"initialLearningRate", initialLr}, {"epochs", o.epochs}};
    if (std::isfinite(bestError)) st["bestError"] = bestError;
    writeFileAtomic((checkpointDir / "state.json").string(), st.dump(2) + "\n");
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - e0).count();
    if (progress) progress(rep);
  }
}

}  // namespace viscera::learning
