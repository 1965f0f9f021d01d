// The learned correction's network, loss, training and model folders (LibTorch).
#include "learning/nn/Corrector.h"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <thread>

#include "core/Error.h"
#include "core/Files.h"
#include "learning/nn/torch/ModelFolder.h"
#include "learning/nn/torch/MeshGraph.h"
#include "learning/nn/torch/GridUNet.h"

namespace viscera::learning {

namespace fs = std::filesystem;

torch::Tensor chamferLoss(const torch::Tensor& cloud, const torch::Tensor& surface) {
  return std::get<0>(torch::cdist(cloud, surface).pow(2).min(1)).mean();
}

std::unique_ptr<Corrector::Impl> newTorchCorrector(const RestMesh& mesh, const GridShape& grid, const Eigen::Vector3d& view,
                                                   const CorrectorArchitecture& arch, const std::string& units, std::uint64_t seed) {
  torch::manual_seed(seed);
  return std::make_unique<TorchCorrector>(mesh, grid, view, arch, units);
}

std::int64_t TorchCorrector::parameters() const {
  std::int64_t n = 0;
  for (const auto& p : net->parameters()) n += p.numel();
  return n;
}

Eigen::Matrix3Xd TorchCorrector::correct(const Eigen::Matrix3Xd& x, const InstrumentInput& tool) const {
  const TorchCorrector& m = *this;
  if (x.cols() != m.shape.nodes()) throw Error("corrector: " + std::to_string(x.cols()) + " nodes given, the model has " + std::to_string(m.shape.nodes()));
  torch::NoGradGuard noGrad;
  const Eigen::Matrix3Xf xf = x.cast<float>();
  const torch::Tensor c = m.corrections(m.nodeFeatures({&xf}), m.poseFeatures({tool})).contiguous();
  const float* d = c.data_ptr<float>();
  Eigen::Matrix3Xd out = x;
  for (int i : m.movable)
    for (int a = 0; a < 3; ++a) out(a, i) += d[3 * i + a];
  return out;
}

Eigen::Matrix3Xd TorchCorrector::refinedSurface(const Eigen::Matrix3Xd& x) const {
  const torch::Tensor xt = torch::from_blob(const_cast<double*>(x.data()), {x.cols(), 3}, torch::kFloat64).to(torch::kFloat32);
  const torch::Tensor p = torch::mm(refine, xt).contiguous();
  Eigen::Matrix3Xd out(3, p.size(0));
  const float* d = p.data_ptr<float>();
  for (int64_t k = 0; k < p.size(0); ++k)
    for (int a = 0; a < 3; ++a) out(a, k) = d[3 * k + a];
  return out;
}

// ---------------------------------------------------------------------------------------------
// Model folders

void TorchCorrector::save(const std::string& folder, const std::string& training) const {
  const TorchCorrector& m = *this;
  fs::create_directories(folder);
  writeRestMesh((fs::path(folder) / "mesh.bin").string(), m.rest);
  saveParameters(*m.net, (fs::path(folder) / "weights.pt").string());
  nlohmann::ordered_json c;
  c["format"] = "viscera model";
  c["version"] = 1;
  c["kind"] = "corrector";
  c["architecture"] = {{"network", m.arch.threeD ? "3D U-Net" : "2D U-Net (observed face)"},
                       {"dimensions", m.arch.threeD ? 3 : 2},
                       {"inputs", kCorrectorInputs},
                       {"poseInputs", kPoseInputs},
                       {"width", m.arch.width},
                       {"maxCorrection", m.arch.maxCorrection},
                       {"parameters", parameters()}};
  c["grid"] = {m.shape.nx, m.shape.ny, m.shape.nz};
  c["viewDirection"] = {m.view.x(), m.view.y(), m.view.z()};
  c["observedFace"] = {{"axis", std::string(1, "xyz"[m.faceAxis])}, {"side", m.faceSide ? "max" : "min"}};
  c["normalisers"] = {{"cell", {m.cell.x(), m.cell.y(), m.cell.z()}}, {"velocityScale", m.velocityScale}};
  c["mesh"] = meshEntry(m.rest, m.hash);
  c["units"] = m.unitSystem;
  c["training"] = training.empty() ? nlohmann::ordered_json::object() : nlohmann::ordered_json::parse(training);
  writeFileAtomic((fs::path(folder) / "config.json").string(), c.dump(2) + "\n");
}

std::unique_ptr<Corrector::Impl> loadTorchCorrector(const std::string& folder) {
  std::string configPath;
  const nlohmann::json c = readModelConfig(folder, "corrector", configPath, 1);
  std::unique_ptr<TorchCorrector> impl;
  try {
    const auto& a = c.at("architecture");
    if (a.at("inputs").get<int>() != kCorrectorInputs || a.at("poseInputs").get<int>() != kPoseInputs)
      throw Error(SourceLoc{configPath}, "the network's inputs are not this version's corrector's");
    CorrectorArchitecture arch;
    const int dims = a.at("dimensions").get<int>();
    if (dims != 2 && dims != 3) throw Error(SourceLoc{configPath}, "architecture.dimensions must be 2 or 3");
    arch.threeD = dims == 3;
    arch.width = a.at("width").get<int>();
    arch.maxCorrection = a.at("maxCorrection").get<double>();
    const auto& g = c.at("grid");
    const GridShape grid{g.at(0).get<int>(), g.at(1).get<int>(), g.at(2).get<int>()};
    const auto& v = c.at("viewDirection");
    const Eigen::Vector3d view(v.at(0).get<double>(), v.at(1).get<double>(), v.at(2).get<double>());
    if (!(view.norm() > 0)) throw Error(SourceLoc{configPath}, "viewDirection must not be zero");
    RestMesh mesh = readRestMesh((fs::path(folder) / c.at("mesh").at("file").get<std::string>()).string());
    try {
      impl = std::make_unique<TorchCorrector>(std::move(mesh), grid, view, arch, c.at("units").get<std::string>());
    } catch (const Error& e) {
      throw Error(SourceLoc{configPath}, e.what());
    }
    impl->velocityScale = c.at("normalisers").at("velocityScale").get<double>();
    if (!(impl->velocityScale > 0)) throw Error(SourceLoc{configPath}, "normalisers.velocityScale must be positive");
    checkMeshEntry(c, impl->hash, configPath);
    if (c.contains("training")) impl->trainingRecord = c.at("training").dump();
  } catch (const nlohmann::json::exception& e) {
    throw Error(SourceLoc{configPath}, std::string("malformed model configuration: ") + e.what());
  }
  loadParameters(*impl->net, (fs::path(folder) / "weights.pt").string(), configPath);
  return impl;
}

void TorchCorrector::checkMesh(const RestMesh& mesh, const std::string& what) const {
  const TorchCorrector& m = *this;
  const std::uint64_t h = meshHash(mesh);
  if (h == m.hash) return;
  std::ostringstream s;
  s << "the corrector was trained on a grid of " << m.shape.nx << " x " << m.shape.ny << " x " << m.shape.nz << " nodes ("
    << m.rest.tets.cols() << " tetrahedra, " << m.rest.fixed.size() << " fixed nodes, fingerprint " << hexFingerprint(m.hash) << "); "
    << what << " has " << mesh.points.cols() << " nodes, " << mesh.tets.cols() << " tetrahedra and " << mesh.fixed.size()
    << " fixed nodes (fingerprint " << hexFingerprint(h) << ")";
  throw Error(s.str());
}

// ---------------------------------------------------------------------------------------------
// Training

void torchTrainCorrector(const CorrectorTrainOptions& o, const std::function<void(const CorrectorEpochReport&)>& progress) {
  if (o.data.empty()) throw Error("corrector training: give at least one pair folder");
  if (o.out.empty()) throw Error("corrector training: --out is required");
  if (o.epochs < 1 || o.batch < 1) throw Error("--epochs and --batch must be at least 1");
  if (!(o.learningRate > 0)) throw Error("--lr: must be positive");
  if (!(o.validation > 0) || !(o.validation < 1)) throw Error("--validation: must be a share in (0, 1)");
  if (o.maxPoints < 1) throw Error("--points: must be at least 1");
  const fs::path out(o.out), checkpointDir = out / "checkpoint";
  if (o.resume && !fs::exists(checkpointDir / "state.json"))
    throw Error(SourceLoc{o.out}, "--resume: no checkpoint to resume from (" + (checkpointDir / "state.json").string() + " is missing)");
  if (!o.resume && fs::exists(out)) throw Error(SourceLoc{o.out}, "--out: already exists (nothing was changed); --resume continues its training");
  torch::set_num_threads(o.threads > 0 ? o.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));

  std::vector<PairSet> sets;
  for (const std::string& d : o.data) sets.push_back(readPairSet(d));
  const PairSet& first = sets.front();
  for (const PairSet& s : sets) {
    if (meshHash(s.mesh) != meshHash(first.mesh)) throw Error(SourceLoc{s.folder}, "another mesh than " + first.folder + "'s");
    if (s.units != first.units) throw Error(SourceLoc{s.folder}, "other units than " + first.folder + "'s");
  }
  struct Frame {
    const RolloutFrame* state;
    Eigen::Matrix3Xf cloud;
  };
  std::vector<Frame> train, held;
  double speed2 = 0;
  for (const PairSet& s : sets) {
    const size_t cut = s.states.size() - static_cast<size_t>(std::lround(o.validation * s.states.size()));
    for (size_t k = 0; k < s.states.size(); ++k) {
      const Eigen::Matrix3Xf& c = s.clouds[k];
      if (c.cols() == 0) continue;
      Frame f{&s.states[k], c};
      if (c.cols() > o.maxPoints) {
        f.cloud.resize(3, o.maxPoints);
        for (int i = 0; i < o.maxPoints; ++i) f.cloud.col(i) = c.col(static_cast<Eigen::Index>(i) * c.cols() / o.maxPoints);
      }
      speed2 += s.states[k].velocity.squaredNorm();
      (k < cut ? train : held).push_back(std::move(f));
    }
  }
  if (train.empty() || held.empty()) throw Error("corrector training needs frames with clouds both to train on and to hold out");

  std::optional<Corrector> model;
  int startEpoch = 1;
  double bestError = std::numeric_limits<double>::infinity(), lr = o.learningRate;
  if (o.resume) {
    model.emplace(loadTorchCorrector(checkpointDir.string()));
    model->checkMesh(first.mesh, "the pairs " + first.folder);
    if (model->units() != first.units) throw Error(SourceLoc{first.folder}, "the pairs are in " + first.units + ", the model in " + model->units());
    const std::string statePath = (checkpointDir / "state.json").string();
    try {
      const auto st = nlohmann::json::parse(readInputFile(statePath, "checkpoint state"));
      startEpoch = st.at("epoch").get<int>() + 1;
      if (st.contains("bestError")) bestError = st.at("bestError").get<double>();
      lr = st.at("learningRate").get<double>();
    } catch (const nlohmann::json::exception& e) {
      throw Error(SourceLoc{statePath}, std::string("malformed checkpoint state: ") + e.what());
    }
  } else {
    model.emplace(newTorchCorrector(first.mesh, first.grid, first.viewDirection, o.architecture, first.units, o.seed));
    static_cast<TorchCorrector&>(model->impl()).velocityScale = std::max(1e-9, std::sqrt(speed2 / (train.size() + held.size())));
  }
  TorchCorrector& m = static_cast<TorchCorrector&>(model->impl());
  torch::optim::Adam optimizer(m.net->parameters(), torch::optim::AdamOptions(lr));
  if (o.resume) {
    try {
      torch::load(optimizer, (checkpointDir / "optimizer.pt").string());
    } catch (const c10::Error& e) {
      throw Error(SourceLoc{(checkpointDir / "optimizer.pt").string()}, std::string("cannot read the optimiser's state: ") + e.what_without_backtrace());
    }
  }

  // The loss of a batch: per frame the mean squared distance from its cloud to the refined surface.
  auto batchLoss = [&](const std::vector<const Frame*>& batch) {
    std::vector<const Eigen::Matrix3Xf*> xs;
    std::vector<InstrumentInput> tools;
    for (const Frame* f : batch) xs.push_back(&f->state->x), tools.push_back({f->state->tip, f->state->velocity});
    const torch::Tensor feats = m.nodeFeatures(xs);
    const torch::Tensor corr = m.corrections(feats, m.poseFeatures(tools));
    torch::Tensor loss = torch::zeros({});
    for (size_t b = 0; b < batch.size(); ++b) {
      const Eigen::Matrix3Xf& x = *xs[b];
      const torch::Tensor xt = torch::from_blob(const_cast<float*>(x.data()), {x.cols(), 3}, torch::kFloat32) + corr[b];
      const torch::Tensor surface = torch::mm(m.refine, xt);
      const Eigen::Matrix3Xf& c = batch[b]->cloud;
      const torch::Tensor cloud = torch::from_blob(const_cast<float*>(c.data()), {c.cols(), 3}, torch::kFloat32);
      loss = loss + chamferLoss(cloud, surface);
    }
    return loss / static_cast<double>(batch.size());
  };
  auto heldOut = [&](double& before, double& after) {
    torch::NoGradGuard noGrad;
    before = after = 0;
    for (const Frame& f : held) {
      const Eigen::Matrix3Xd x = f.state->x.cast<double>();
      before += cloudToPoints(f.cloud, model->refinedSurface(x)).mean;
      after += cloudToPoints(f.cloud, model->refinedSurface(model->correct(x, {f.state->tip, f.state->velocity}))).mean;
    }
    before /= held.size();
    after /= held.size();
  };

  std::vector<const Frame*> frames;
  for (const Frame& f : train) frames.push_back(&f);
  for (int epoch = startEpoch; epoch <= o.epochs; ++epoch) {
    const auto e0 = std::chrono::steady_clock::now();
    // Each epoch's order from the epoch's own seed: a resumed training draws the batches it would have.
    std::mt19937_64 rng(o.seed * 1000003ull + static_cast<std::uint64_t>(epoch));
    std::vector<const Frame*> order = frames;
    std::shuffle(order.begin(), order.end(), rng);
    double sum = 0;
    int batches = 0;
    m.net->train();
    for (size_t s0 = 0; s0 < order.size(); s0 += o.batch) {
      const std::vector<const Frame*> batch(order.begin() + s0, order.begin() + std::min(order.size(), s0 + o.batch));
      const torch::Tensor loss = batchLoss(batch);
      optimizer.zero_grad();
      loss.backward();
      optimizer.step();
      sum += loss.item<double>();
      ++batches;
    }
    m.net->eval();
    CorrectorEpochReport rep;
    rep.epoch = epoch;
    rep.epochs = o.epochs;
    rep.trainLoss = sum / std::max(1, batches);
    heldOut(rep.heldOutBefore, rep.heldOutAfter);
    rep.learningRate = static_cast<torch::optim::AdamOptions&>(optimizer.param_groups().front().options()).lr();
    rep.best = rep.heldOutAfter < bestError;
    nlohmann::ordered_json record;
    record["command"] = o.command;
    record["data"] = nlohmann::json::array();
    for (const std::string& d : o.data) record["data"].push_back(d);  // as given: a model folder names no machine's paths
    record["trainingFrames"] = train.size();
    record["heldOutFrames"] = held.size();
    record["heldOutShare"] = o.validation;
    record["pointsPerFrame"] = o.maxPoints;
    record["optimizer"] = "Adam";
    record["initialLearningRate"] = o.learningRate;
    record["batch"] = o.batch;
    record["seed"] = o.seed;
    record["epoch"] = epoch;
    record["heldOutBefore"] = rep.heldOutBefore;
    record["heldOutAfter"] = rep.heldOutAfter;
    if (rep.best) {
      bestError = rep.heldOutAfter;
      model->save(out.string(), record.dump());
      saveOptimizer(optimizer, (out / "optimizer.pt").string());
    }
    model->save(checkpointDir.string(), record.dump());
    saveOptimizer(optimizer, (checkpointDir / "optimizer.pt").string());
    nlohmann::ordered_json st = {{"epoch", epoch}, {"learningRate", rep.learningRate}};
    if (std::isfinite(bestError)) st["bestError"] = bestError;
    writeFileAtomic((checkpointDir / "state.json").string(), st.dump(2) + "\n");
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - e0).count();
    if (progress) progress(rep);
  }
}

}  // namespace viscera::learning
