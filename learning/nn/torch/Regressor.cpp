// LibTorch's side of learning/nn/Regressor.h: the force estimators' small networks, their
// training (Adam, best validation epoch kept) and their model folders.
#include "learning/nn/Regressor.h"

#include <torch/torch.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>

#include "core/Error.h"
#include "core/Files.h"
#include "learning/nn/torch/GraphUNet.h"
#include "learning/nn/torch/ModelFolder.h"

namespace viscera::learning {
namespace {

namespace fs = std::filesystem;

torch::Tensor activate(const std::string& kind, const torch::Tensor& x) {
  if (kind == "relu") return torch::relu(x);
  if (kind == "leakyrelu") return torch::leaky_relu(x, 0.01);
  return torch::tanh(x);
}

// window * features -> hidden (x layers) -> outputs.
struct MlpImpl : torch::nn::Module {
  MlpImpl(int in, int hidden, int layers, int outputs, std::string activation) : activation(std::move(activation)) {
    for (int l = 0; l < layers; ++l)
      hiddenLayers.push_back(register_module("hidden" + std::to_string(l), torch::nn::Linear(l == 0 ? in : hidden, hidden)));
    out = register_module("out", torch::nn::Linear(layers == 0 ? in : hidden, outputs));
  }
  torch::Tensor forward(torch::Tensor x) {
    for (auto& l : hiddenLayers) x = activate(activation, l->forward(x));
    return out->forward(x);
  }
  std::string activation;
  std::vector<torch::nn::Linear> hiddenLayers;
  torch::nn::Linear out{nullptr};
};
TORCH_MODULE(Mlp);

// LSTM over the window, its last output through two fully connected layers (dissertation Fig. 2-19).
struct LstmNetImpl : torch::nn::Module {
  LstmNetImpl(int features, int hidden, int outputs)
      : lstm(register_module("lstm", torch::nn::LSTM(torch::nn::LSTMOptions(features, hidden).batch_first(true)))),
        fc1(register_module("fc1", torch::nn::Linear(hidden, hidden))),
        fc2(register_module("fc2", torch::nn::Linear(hidden, outputs))) {}
  torch::Tensor forward(const torch::Tensor& x) {  // (batch, window, features)
    const torch::Tensor h = std::get<0>(lstm->forward(x)).select(1, x.size(1) - 1);
    return fc2->forward(torch::relu(fc1->forward(torch::relu(h))));
  }
  torch::nn::LSTM lstm;
  torch::nn::Linear fc1, fc2;
};
TORCH_MODULE(LstmNet);

// One network per output column, or one for all.
struct RegressorNetImpl : torch::nn::Module {
  explicit RegressorNetImpl(const RegressorArchitecture& a) : arch(a) {
    const int count = a.perOutput ? a.outputs : 1;
    const int each = a.perOutput ? 1 : a.outputs;
    for (int k = 0; k < count; ++k) {
      const std::string name = "net" + std::to_string(k);
      if (a.kind == "lstm")
        lstms.push_back(register_module(name, LstmNet(a.features, a.hidden, each)));
      else
        mlps.push_back(register_module(name, Mlp(a.window * a.features, a.hidden, a.layers, each, a.activation)));
    }
  }
  torch::Tensor forward(const torch::Tensor& x) {  // (batch, window * features), normalised
    std::vector<torch::Tensor> parts;
    if (arch.kind == "lstm") {
      const torch::Tensor seq = x.view({x.size(0), arch.window, arch.features});
      for (auto& n : lstms) parts.push_back(n->forward(seq));
    } else {
      for (auto& n : mlps) parts.push_back(n->forward(x));
    }
    return parts.size() == 1 ? parts[0] : torch::cat(parts, 1);
  }
  RegressorArchitecture arch;
  std::vector<Mlp> mlps;
  std::vector<LstmNet> lstms;
};
TORCH_MODULE(RegressorNet);

void checkArchitecture(const RegressorArchitecture& a) {
  if (a.kind != "mlp" && a.kind != "lstm") throw Error("regressor: kind " + viscera::quoted(a.kind) + " is neither mlp nor lstm");
  if (a.window < 1 || a.features < 1 || a.outputs < 1 || a.hidden < 1 || a.layers < 0)
    throw Error("regressor: window, features, outputs and hidden must be positive, layers >= 0");
  if (a.activation != "tanh" && a.activation != "relu" && a.activation != "leakyrelu")
    throw Error("regressor: activation " + viscera::quoted(a.activation) + " is not tanh, relu or leakyrelu");
  if (a.outputScaling != "standard" && a.outputScaling != "range" && a.outputScaling != "none")
    throw Error("regressor: output scaling " + viscera::quoted(a.outputScaling) + " is not standard, range or none");
}

torch::Tensor toTensor(const Eigen::MatrixXf& m) {
  // Eigen is column-major; a row-major copy gives (rows, cols).
  const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> r = m;
  return torch::from_blob(const_cast<float*>(r.data()), {r.rows(), r.cols()}, torch::kFloat32).clone();
}

Eigen::MatrixXf toMatrix(const torch::Tensor& t) {
  const torch::Tensor c = t.contiguous().to(torch::kFloat32);
  return Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(c.data_ptr<float>(), c.size(0), c.size(1));
}

class TorchRegressor final : public Regressor::Impl {
 public:
  TorchRegressor(const RegressorArchitecture& a, std::vector<float> inMean, std::vector<float> inScale,
                 std::vector<float> outCentre, std::vector<float> outScale, std::string notes)
      : arch_(a), net(a), inMean_(std::move(inMean)), inScale_(std::move(inScale)), outCentre_(std::move(outCentre)),
        outScale_(std::move(outScale)), notes_(std::move(notes)) {
    // Per-feature statistics repeated over the window's positions.
    std::vector<float> mean, scale;
    for (int w = 0; w < a.window; ++w) {
      mean.insert(mean.end(), inMean_.begin(), inMean_.end());
      scale.insert(scale.end(), inScale_.begin(), inScale_.end());
    }
    xMean = torch::tensor(mean).view({1, -1});
    xScale = torch::tensor(scale).view({1, -1});
    yCentre = torch::tensor(outCentre_).view({1, -1});
    yScale = torch::tensor(outScale_).view({1, -1});
  }

  torch::Tensor normaliseX(const torch::Tensor& x) const { return (x - xMean) / xScale; }
  torch::Tensor normaliseY(const torch::Tensor& y) const { return (y - yCentre) / yScale; }

  Eigen::MatrixXf predict(const Eigen::MatrixXf& x) const override {
    if (x.cols() != arch_.window * arch_.features)
      throw Error("regressor: inputs of " + std::to_string(arch_.window * arch_.features) + " columns expected, not " +
                  std::to_string(x.cols()));
    torch::NoGradGuard noGrad;
    auto& self = const_cast<TorchRegressor&>(*this);
    self.net->eval();
    Eigen::MatrixXf out(x.rows(), arch_.outputs);
    constexpr Eigen::Index chunk = 8192;
    for (Eigen::Index start = 0; start < x.rows(); start += chunk) {
      const Eigen::Index rows = std::min(chunk, x.rows() - start);
      const torch::Tensor y = self.net->forward(normaliseX(toTensor(x.middleRows(start, rows)))) * yScale + yCentre;
      out.middleRows(start, rows) = toMatrix(y);
    }
    return out;
  }

  void save(const std::string& folder, const std::string& notes) const override {
    fs::create_directories(folder);
    saveParameters(*net, (fs::path(folder) / "weights.pt").string());
    nlohmann::ordered_json c;
    c["format"] = "viscera model";
    c["version"] = 1;
    c["kind"] = "regressor";
    c["architecture"] = {{"network", arch_.kind},       {"window", arch_.window},         {"features", arch_.features},
                         {"outputs", arch_.outputs},    {"hidden", arch_.hidden},         {"layers", arch_.layers},
                         {"activation", arch_.activation}, {"perOutput", arch_.perOutput}, {"outputScaling", arch_.outputScaling},
                         {"parameters", parameters()}};
    c["normalisation"] = {{"inputMean", inMean_}, {"inputScale", inScale_}, {"outputCentre", outCentre_}, {"outputScale", outScale_}};
    const std::string& n = notes.empty() ? notes_ : notes;
    c["training"] = n.empty() ? nlohmann::ordered_json::object() : nlohmann::ordered_json::parse(n);
    writeFileAtomic((fs::path(folder) / "config.json").string(), c.dump(2) + "\n");
  }

  const RegressorArchitecture& architecture() const override { return arch_; }
  std::int64_t parameters() const override {
    std::int64_t n = 0;
    for (const auto& p : net->parameters()) n += p.numel();
    return n;
  }
  const std::string& notes() const override { return notes_; }

  RegressorArchitecture arch_;
  RegressorNet net;
  std::vector<float> inMean_, inScale_, outCentre_, outScale_;
  std::string notes_;
  torch::Tensor xMean, xScale, yCentre, yScale;
};

std::unique_ptr<Regressor::Impl> torchTrainRegressor(const RegressorArchitecture& a, const RegressorTrainOptions& o,
                                                      const RegressorData& train, const RegressorData& validation,
                                                      const std::function<void(const RegressorEpochReport&)>& progress) {
  checkArchitecture(a);
  if (train.samples() < 2 || train.x.cols() != a.window * a.features || train.y.cols() != a.outputs || train.y.rows() != train.x.rows())
    throw Error("regressor: training data of at least 2 samples with " + std::to_string(a.window * a.features) +
                " inputs and " + std::to_string(a.outputs) + " outputs expected");
  if (validation.samples() > 0 && (validation.x.cols() != train.x.cols() || validation.y.cols() != train.y.cols()))
    throw Error("regressor: validation data of another shape than the training data");
  if (o.epochs < 1 || o.batch < 1 || !(o.learningRate > 0) || (o.loss != "mse" && o.loss != "mae") || !(o.weightDecay >= 0))
    throw Error("regressor: epochs, batch and learning rate must be positive, weight decay >= 0 and the loss mse or mae");
  torch::manual_seed(o.seed);
  // Normalisation from the training data: per feature over all window positions.
  const Eigen::Index n = train.x.rows();
  std::vector<float> inMean(a.features), inScale(a.features), outCentre(a.outputs), outScale(a.outputs);
  for (int f = 0; f < a.features; ++f) {
    double s = 0, s2 = 0;
    for (int w = 0; w < a.window; ++w) {
      const auto col = train.x.col(w * a.features + f).cast<double>();
      s += col.sum();
      s2 += col.squaredNorm();
    }
    const double count = static_cast<double>(n) * a.window;
    const double mean = s / count, var = std::max(0.0, s2 / count - mean * mean);
    inMean[f] = static_cast<float>(mean);
    inScale[f] = static_cast<float>(var > 1e-20 ? std::sqrt(var) : 1.0);
  }
  for (int k = 0; k < a.outputs; ++k) {
    const auto col = train.y.col(k).cast<double>();
    if (a.outputScaling == "none") {
      outCentre[k] = 0;
      outScale[k] = 1;
    } else if (a.outputScaling == "range") {
      const double lo = col.minCoeff(), hi = col.maxCoeff();
      outCentre[k] = static_cast<float>((lo + hi) / 2);
      outScale[k] = static_cast<float>(hi > lo ? (hi - lo) / 2 : 1.0);
    } else {
      const double mean = col.mean(), var = (col.array() - mean).square().mean();
      outCentre[k] = static_cast<float>(mean);
      outScale[k] = static_cast<float>(var > 1e-20 ? std::sqrt(var) : 1.0);
    }
  }
  auto model = std::make_unique<TorchRegressor>(a, inMean, inScale, outCentre, outScale, "");
  const torch::Tensor X = model->normaliseX(toTensor(train.x)), Y = model->normaliseY(toTensor(train.y));
  torch::Tensor Xv, Yv;
  if (validation.samples() > 0) {
    Xv = model->normaliseX(toTensor(validation.x));
    Yv = model->normaliseY(toTensor(validation.y));
  }
  auto lossOf = [&](const torch::Tensor& p, const torch::Tensor& y) {
    return o.loss == "mae" ? torch::l1_loss(p, y) : torch::mse_loss(p, y);
  };
  torch::optim::Adam optimizer(model->net->parameters(), torch::optim::AdamOptions(o.learningRate).weight_decay(o.weightDecay));
  double best = std::numeric_limits<double>::infinity(), rate = o.learningRate;
  int sinceBest = 0;
  std::vector<torch::Tensor> bestWeights;
  for (int epoch = 1; epoch <= o.epochs; ++epoch) {
    const auto t0 = std::chrono::steady_clock::now();
    model->net->train();
    const torch::Tensor order = torch::randperm(n, torch::kLong);
    double sum = 0;
    for (std::int64_t start = 0; start < n; start += o.batch) {
      const torch::Tensor idx = order.slice(0, start, std::min<std::int64_t>(start + o.batch, n));
      optimizer.zero_grad();
      const torch::Tensor loss = lossOf(model->net->forward(X.index_select(0, idx)), Y.index_select(0, idx));
      loss.backward();
      optimizer.step();
      sum += loss.item<double>() * static_cast<double>(idx.size(0));
    }
    RegressorEpochReport r;
    r.epoch = epoch;
    r.trainLoss = sum / static_cast<double>(n);
    r.validationLoss = std::numeric_limits<double>::quiet_NaN();
    {
      torch::NoGradGuard noGrad;
      model->net->eval();
      const double v = validation.samples() > 0 ? lossOf(model->net->forward(Xv), Yv).item<double>() : r.trainLoss;
      if (validation.samples() > 0) r.validationLoss = v;
      r.best = v < best;
      if (r.best) {
        best = v;
        sinceBest = 0;
        bestWeights.clear();
        for (const auto& p : model->net->parameters()) bestWeights.push_back(p.detach().clone());
      } else if (++sinceBest % 5 == 0) {  // a plateau: halve the learning rate
        rate /= 2;
        for (auto& g : optimizer.param_groups()) static_cast<torch::optim::AdamOptions&>(g.options()).lr(rate);
      }
    }
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (progress) progress(r);
    if (o.patience > 0 && sinceBest >= o.patience) break;
  }
  {
    torch::NoGradGuard noGrad;
    auto params = model->net->parameters();
    for (size_t k = 0; k < params.size() && k < bestWeights.size(); ++k) params[k].copy_(bestWeights[k]);
  }
  return model;
}

std::vector<float> floats(const nlohmann::json& j, size_t size, const std::string& what, const std::string& configPath) {
  std::vector<float> v = j.get<std::vector<float>>();
  if (v.size() != size) throw Error(SourceLoc{configPath}, what + ": " + std::to_string(size) + " values expected");
  return v;
}

std::unique_ptr<Regressor::Impl> loadTorchRegressor(const std::string& folder) {
  std::string configPath;
  const nlohmann::json c = readModelConfig(folder, "regressor", configPath, 1);
  std::unique_ptr<TorchRegressor> impl;
  try {
    const auto& ar = c.at("architecture");
    RegressorArchitecture a;
    a.kind = ar.at("network").get<std::string>();
    a.window = ar.at("window").get<int>();
    a.features = ar.at("features").get<int>();
    a.outputs = ar.at("outputs").get<int>();
    a.hidden = ar.at("hidden").get<int>();
    a.layers = ar.at("layers").get<int>();
    a.activation = ar.at("activation").get<std::string>();
    a.perOutput = ar.at("perOutput").get<bool>();
    a.outputScaling = ar.at("outputScaling").get<std::string>();
    try {
      checkArchitecture(a);
    } catch (const Error& e) {
      throw Error(SourceLoc{configPath}, e.what());
    }
    const auto& nm = c.at("normalisation");
    impl = std::make_unique<TorchRegressor>(
        a, floats(nm.at("inputMean"), a.features, "inputMean", configPath),
        floats(nm.at("inputScale"), a.features, "inputScale", configPath),
        floats(nm.at("outputCentre"), a.outputs, "outputCentre", configPath),
        floats(nm.at("outputScale"), a.outputs, "outputScale", configPath), c.value("training", nlohmann::json::object()).dump());
  } catch (const nlohmann::json::exception& e) {
    throw Error(SourceLoc{configPath}, std::string("not a regressor's configuration: ") + e.what());
  }
  loadParameters(*impl->net, (fs::path(folder) / "weights.pt").string(), configPath);
  return impl;
}

}  // namespace

// Entry points for Backend.cpp.
std::unique_ptr<Regressor::Impl> newTrainedRegressor(const RegressorArchitecture& a, const RegressorTrainOptions& o,
                                                      const RegressorData& train, const RegressorData& validation,
                                                      const std::function<void(const RegressorEpochReport&)>& progress) {
  return torchTrainRegressor(a, o, train, validation, progress);
}
std::unique_ptr<Regressor::Impl> loadSavedRegressor(const std::string& folder) { return loadTorchRegressor(folder); }

}  // namespace viscera::learning
