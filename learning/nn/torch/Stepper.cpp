// The learned stepper's network, inference and model folders (LibTorch).
#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <limits>

#include <filesystem>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/Error.h"
#include "core/Files.h"
#include "learning/nn/torch/ModelFolder.h"
#include "learning/nn/torch/GraphUNet.h"

namespace viscera::learning {

namespace fs = std::filesystem;


// ---------------------------------------------------------------------------------------------
// Graph operators and layers

namespace {

torch::Tensor sparse(const std::vector<std::int64_t>& rows, const std::vector<std::int64_t>& cols,
                     const std::vector<double>& values, std::int64_t m, std::int64_t n, torch::Dtype dtype) {
  const auto nnz = static_cast<std::int64_t>(rows.size());
  torch::Tensor idx = torch::empty({2, nnz}, torch::kLong);
  auto a = idx.accessor<std::int64_t, 2>();
  for (std::int64_t k = 0; k < nnz; ++k) a[0][k] = rows[k], a[1][k] = cols[k];
  torch::Tensor v = torch::from_blob(const_cast<double*>(values.data()), {nnz}, torch::kFloat64).to(dtype);
  return torch::sparse_coo_tensor(idx, v, {m, n}, torch::TensorOptions().dtype(dtype)).coalesce();
}

}  // namespace

GraphOps GraphOps::build(const MeshGraph& graph, torch::Dtype dtype) {
  GraphOps ops;
  for (size_t l = 0; l < graph.levels.size(); ++l) {
    const GraphLevel& g = graph.levels[l];
    std::vector<int> degree(g.nodes, 0);
    for (auto [a, b] : g.edges) ++degree[a], ++degree[b];
    std::vector<std::int64_t> rows, cols;
    std::vector<double> vals;
    for (auto [a, b] : g.edges) {
      rows.push_back(a), cols.push_back(b), vals.push_back(1.0 / degree[a]);
      rows.push_back(b), cols.push_back(a), vals.push_back(1.0 / degree[b]);
    }
    ops.neighbourMean.push_back(sparse(rows, cols, vals, g.nodes, g.nodes, dtype));
    if (l == 0) continue;
    // Between level l-1 (fine) and l (coarse).
    const GraphLevel& fine = graph.levels[l - 1];
    std::vector<int> size(g.nodes, 0);
    for (int c : g.cluster) ++size[c];
    std::vector<std::int64_t> pr, pc, ur, uc;
    std::vector<double> pv, uv;
    for (int i = 0; i < fine.nodes; ++i) {
      const int c = g.cluster[i];
      pr.push_back(c), pc.push_back(i), pv.push_back(1.0 / size[c]);
      ur.push_back(i), uc.push_back(c), uv.push_back(1.0);
    }
    ops.pool.push_back(sparse(pr, pc, pv, g.nodes, fine.nodes, dtype));
    ops.unpool.push_back(sparse(ur, uc, uv, fine.nodes, g.nodes, dtype));
  }
  return ops;
}

torch::Tensor applyGraph(const torch::Tensor& S, const torch::Tensor& H) {
  const auto n = H.size(0), batch = H.size(1), features = H.size(2);
  return torch::mm(S, H.reshape({n, batch * features})).view({S.size(0), batch, features});
}

GraphConvImpl::GraphConvImpl(int in, int out) : in(in), out(out) {
  self = register_module("self", torch::nn::Linear(in, out));
  neighbours = register_module("neighbours", torch::nn::Linear(torch::nn::LinearOptions(in, out).bias(false)));
}

torch::Tensor GraphConvImpl::forward(const torch::Tensor& H, const torch::Tensor& neighbourMean) {
  // The mean and the weight commute: the sparse product runs on the narrower side.
  const torch::Tensor n = out < in ? applyGraph(neighbourMean, neighbours(H)) : neighbours(applyGraph(neighbourMean, H));
  return self(H) + n;
}

GraphUNetImpl::GraphUNetImpl(int inputs, int width, int levels, int outputs) : levels(levels) {
  for (int l = 0; l <= levels; ++l)
    down.push_back(register_module("down" + std::to_string(l), GraphConv(l == 0 ? inputs : width, width)));
  for (int l = levels - 1; l >= 0; --l)
    up.push_back(register_module("up" + std::to_string(l), GraphConv(l == 0 ? width + inputs : width, l == 0 ? outputs : width)));
}

torch::Tensor GraphUNetImpl::forward(const torch::Tensor& X, const GraphOps& ops) {
  std::vector<torch::Tensor> skip;
  torch::Tensor h = torch::relu(down[0]->forward(X, ops.neighbourMean[0]));
  for (int l = 1; l <= levels; ++l) {
    skip.push_back(h);
    h = torch::relu(down[l]->forward(applyGraph(ops.pool[l - 1], h), ops.neighbourMean[l]));
  }
  for (int l = levels - 1, k = 0; l >= 0; --l, ++k) {
    h = applyGraph(ops.unpool[l], h) + skip[l];
    if (l == 0) h = torch::cat({h, X}, 2);  // the inputs too: an update proportional to the offset is one layer away
    h = up[k]->forward(h, ops.neighbourMean[l]);
    if (l > 0) h = torch::relu(h);
  }
  return h;
}

// ---------------------------------------------------------------------------------------------
// The model

TorchStepper::TorchStepper(RestMesh m, const StepperArchitecture& a, const StepperNormalisers& n, double framePeriod, std::string u)
    : rest(std::move(m)), arch(a), norm(n), period(framePeriod), unitSystem(std::move(u)) {
  if (a.width < 1 || a.width > 4096) throw Error("stepper width must be 1 to 4096, got " + std::to_string(a.width));
  if (!(a.maxStep > 0) || a.maxStep > 10) throw Error("stepper maxStep must be in (0, 10] cells");
  if (a.levels < 1 || a.levels > 8) throw Error("stepper levels must be 1 to 8, got " + std::to_string(a.levels));
  hash = meshHash(rest);
  graph = buildMeshGraph(rest, a.levels, a.matchings);
  ops = GraphOps::build(graph);
  net = GraphUNet(kStepperInputs, a.width, a.levels, 3);
  const int nodes = static_cast<int>(rest.points.cols());
  fixed.assign(nodes, 0);
  for (int f : rest.fixed)
    if (f >= 0 && f < nodes) fixed[f] = 1;
  movable = torch::ones({nodes, 1, 1});
  for (int i = 0; i < nodes; ++i)
    if (fixed[i]) movable[i][0][0] = 0.0f;
  stepScale = torch::tensor({float(a.maxStep * n.cell[0]), float(a.maxStep * n.cell[1]), float(a.maxStep * n.cell[2])}).view({1, 1, 3});
  restFeatures = torch::empty({nodes, 1, kStepperInputs});
  const double far = std::numeric_limits<double>::infinity();
  features(rest.points, InstrumentInput{Eigen::Vector3d(far, far, far), Eigen::Vector3d::Zero()}, restFeatures, 0);
}

torch::Tensor TorchStepper::anchor() const {
  if (torch::GradMode::is_enabled()) return net->forward(restFeatures, ops);
  std::int64_t version = 0;
  for (const auto& p : net->parameters()) version += p._version();
  std::lock_guard<std::mutex> lock(anchorMutex_);
  if (!anchor_.defined() || version != anchorVersion_) {
    anchor_ = net->forward(restFeatures, ops);
    anchorVersion_ = version;
  }
  return anchor_;
}

torch::Tensor TorchStepper::update(const torch::Tensor& features) const {
  torch::Tensor raw = net->forward(features, ops);
  if (arch.restAnchored) raw = raw - anchor();
  // 2 sigmoid(r) - 1 is r / 2 near zero: subtracting 2 offset / maxStep (offsets in cells) makes the
  // update the network's output minus the current offset, and that output the next offset.
  if (arch.output == StepperArchitecture::Output::NextOffset) raw = raw - (2 / arch.maxStep) * features.narrow(2, 0, 3);
  return stepScale * (2 * torch::sigmoid(raw) - 1) * movable;
}

std::unique_ptr<Stepper::Impl> newTorchStepper(const RestMesh& mesh, const StepperArchitecture& arch, const StepperNormalisers& norm,
                                               double framePeriod, const std::string& units, std::uint64_t seed) {
  torch::manual_seed(seed);
  return std::make_unique<TorchStepper>(mesh, arch, norm, framePeriod, units);
}

std::int64_t TorchStepper::parameters() const {
  std::int64_t n = 0;
  for (const auto& p : net->parameters()) n += p.numel();
  return n;
}

Eigen::Matrix3Xd TorchStepper::step(const Eigen::Matrix3Xd& x, const InstrumentInput& instrument) const {
  const TorchStepper& m = *this;
  const auto n = m.rest.points.cols();
  if (x.cols() != n) throw Error("stepper: " + std::to_string(x.cols()) + " nodes given, the model has " + std::to_string(n));
  torch::NoGradGuard noGrad;
  torch::Tensor f = torch::empty({n, 1, kStepperInputs});
  m.features(x, instrument, f, 0);
  const torch::Tensor u = m.update(f).contiguous();
  const float* d = u.data_ptr<float>();
  Eigen::Matrix3Xd next = x;
  for (Eigen::Index i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) next(a, i) += d[3 * i + a];
  return next;
}

// ---------------------------------------------------------------------------------------------
// Model folders

namespace {

nlohmann::json vec(const Eigen::Vector3d& v) { return {v[0], v[1], v[2]}; }

Eigen::Vector3d vec(const nlohmann::json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

std::string paramKey(std::string name) {
  for (size_t p; (p = name.find('.')) != std::string::npos;) name.replace(p, 1, "__");
  return name;
}

std::string shapeText(const torch::Tensor& t) {
  std::string s;
  for (auto d : t.sizes()) s += (s.empty() ? "" : "x") + std::to_string(d);
  return s;
}

template <class Write>
void writeAtomically(const fs::path& path, Write write) {
  const fs::path temp = path.string() + ".tmp-" + std::to_string(::getpid());
  try {
    write(temp.string());
    fs::rename(temp, path);
  } catch (const c10::Error& e) {
    std::error_code ec;
    fs::remove(temp, ec);
    throw Error(SourceLoc{path.string()}, std::string("cannot write: ") + e.what_without_backtrace());
  } catch (...) {
    std::error_code ec;
    fs::remove(temp, ec);
    throw;
  }
}

}  // namespace

void saveParameters(const torch::nn::Module& net, const std::string& path) {
  writeAtomically(path, [&](const std::string& temp) {
    torch::serialize::OutputArchive archive;
    for (const auto& p : net.named_parameters()) archive.write(paramKey(p.key()), p.value());
    archive.save_to(temp);
  });
}

void saveOptimizer(torch::optim::Optimizer& optimizer, const std::string& path) {
  writeAtomically(path, [&](const std::string& temp) { torch::save(optimizer, temp); });
}

// Loads parameters by name, refusing a missing one or one of another shape.
void loadParameters(torch::nn::Module& net, const std::string& path, const std::string& configPath) {
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const c10::Error& e) {
    throw Error(SourceLoc{path}, std::string("cannot read the network's weights: ") + e.what_without_backtrace());
  }
  torch::NoGradGuard noGrad;
  for (auto& p : net.named_parameters()) {
    torch::Tensor t;
    if (!archive.try_read(paramKey(p.key()), t))
      throw Error(SourceLoc{path}, "has no " + p.key() + ", which the architecture in " + configPath +
                                       " needs: the weights are of another architecture");
    if (t.sizes() != p.value().sizes())
      throw Error(SourceLoc{path}, p.key() + " is " + shapeText(t) + " in the weights and " + shapeText(p.value()) +
                                       " in the architecture of " + configPath + ": the weights are of another architecture");
    p.value().copy_(t);
  }
}

void TorchStepper::save(const std::string& folder, const std::string& training) const {
  const TorchStepper& m = *this;
  fs::create_directories(folder);
  writeRestMesh((fs::path(folder) / "mesh.bin").string(), m.rest);
  saveParameters(*m.net, (fs::path(folder) / "weights.pt").string());
  nlohmann::ordered_json c;
  c["format"] = "viscera model";
  c["version"] = 2;  // 2: architecture.output
  c["kind"] = "stepper";
  c["architecture"] = {{"network", "graph U-Net"},
                       {"convolution", "self + neighbour mean (GraphSAGE mean)"},
                       {"inputs", kStepperInputs},
                       {"width", m.arch.width},
                       {"levels", m.arch.levels},
                       {"matchings", m.arch.matchings},
                       {"maxStep", m.arch.maxStep},
                       {"restAnchored", m.arch.restAnchored},
                       {"instrumentNodes", m.arch.instrumentAtAllInReach ? "all within reach" : "nearest within reach"},
                       {"output", outputName(m.arch.output)},
                       {"parameters", parameters()}};
  c["normalisers"] = {{"cell", vec(m.norm.cell)},
                      {"boxMin", vec(m.norm.boxMin)},
                      {"boxMax", vec(m.norm.boxMax)},
                      {"reach", m.norm.reach},
                      {"velocityScale", m.norm.velocityScale}};
  c["mesh"] = meshEntry(m.rest, m.hash);
  c["units"] = m.unitSystem;
  c["framePeriod"] = m.period;
  c["training"] = training.empty() ? nlohmann::ordered_json::object() : nlohmann::ordered_json::parse(training);
  writeFileAtomic((fs::path(folder) / "config.json").string(), c.dump(2) + "\n");
}

std::unique_ptr<Stepper::Impl> loadTorchStepper(const std::string& folder) {
  std::string configPath;
  const nlohmann::json c = readModelConfig(folder, "stepper", configPath, 2);
  std::unique_ptr<TorchStepper> impl;
  try {
    const auto& a = c.at("architecture");
    if (a.at("inputs").get<int>() != kStepperInputs)
      throw Error(SourceLoc{configPath}, "the network takes " + std::to_string(a.at("inputs").get<int>()) +
                                             " inputs per node; this version's stepper takes " + std::to_string(kStepperInputs));
    StepperArchitecture arch;
    arch.width = a.at("width").get<int>();
    arch.levels = a.at("levels").get<int>();
    arch.matchings = a.at("matchings").get<int>();
    arch.maxStep = a.at("maxStep").get<double>();
    arch.restAnchored = a.at("restAnchored").get<bool>();
    const std::string seen = a.at("instrumentNodes").get<std::string>();
    if (seen != "all within reach" && seen != "nearest within reach")
      throw Error(SourceLoc{configPath}, "architecture.instrumentNodes must be \"nearest within reach\" or \"all within reach\", got \"" + seen + "\"");
    arch.instrumentAtAllInReach = seen == "all within reach";
    const std::string output = a.value("output", std::string("update"));  // models before this key predicted updates
    if (output != "update" && output != "next offset")
      throw Error(SourceLoc{configPath}, "architecture.output must be \"update\" or \"next offset\", got \"" + output + "\"");
    arch.output = output == "next offset" ? StepperArchitecture::Output::NextOffset : StepperArchitecture::Output::Update;
    const auto& nj = c.at("normalisers");
    StepperNormalisers norm;
    norm.cell = vec(nj.at("cell"));
    norm.boxMin = vec(nj.at("boxMin"));
    norm.boxMax = vec(nj.at("boxMax"));
    norm.reach = nj.at("reach").get<double>();
    norm.velocityScale = nj.at("velocityScale").get<double>();
    if (!(norm.cell.minCoeff() > 0) || !(norm.reach > 0) || !(norm.velocityScale > 0))
      throw Error(SourceLoc{configPath}, "normalisers must be positive (cell, reach, velocityScale)");
    RestMesh mesh = readRestMesh((fs::path(folder) / c.at("mesh").at("file").get<std::string>()).string());
    try {
      impl = std::make_unique<TorchStepper>(std::move(mesh), arch, norm, c.at("framePeriod").get<double>(), c.at("units").get<std::string>());
    } catch (const Error& e) {
      throw Error(SourceLoc{configPath}, e.what());
    }
    checkMeshEntry(c, impl->hash, configPath);
    if (c.contains("training")) impl->trainingRecord = c.at("training").dump();
  } catch (const nlohmann::json::exception& e) {
    throw Error(SourceLoc{configPath}, std::string("malformed model configuration: ") + e.what());
  }
  loadParameters(*impl->net, (fs::path(folder) / "weights.pt").string(), configPath);
  return impl;
}

void TorchStepper::checkMesh(const RestMesh& mesh, const std::string& what) const {
  const TorchStepper& m = *this;
  const std::uint64_t h = meshHash(mesh);
  if (h == m.hash) return;
  std::ostringstream s;
  s << "the model was trained on a mesh of " << m.rest.points.cols() << " nodes, " << m.rest.tets.cols() << " tetrahedra and "
    << m.rest.fixed.size() << " fixed nodes (fingerprint " << hexFingerprint(m.hash) << "); " << what << " has " << mesh.points.cols()
    << " nodes, " << mesh.tets.cols() << " tetrahedra and " << mesh.fixed.size() << " fixed nodes (fingerprint " << hexFingerprint(h)
    << ")";
  if (mesh.points.cols() == m.rest.points.cols() && mesh.tets.cols() == m.rest.tets.cols())
    s << ": same sizes, other rest positions, elements or fixed nodes";
  throw Error(s.str());
}

}  // namespace viscera::learning

namespace viscera::learning {

GemmSpeed torchMeasureGemm(int m, int k, int n, int repeats) {
  torch::NoGradGuard noGrad;
  torch::manual_seed(1);
  const torch::Tensor a = torch::randn({m, k}), b = torch::randn({k, n});
  torch::Tensor c = torch::mm(a, b);  // warm-up
  std::vector<double> ms;
  for (int r = 0; r < std::max(1, repeats); ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    c = torch::mm(a, b);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
  GemmSpeed g;
  g.milliseconds = ms[ms.size() / 2];
  g.gflops = 2.0 * m * k * n / (g.milliseconds * 1e6);
  if (void* sym = ::dlsym(RTLD_DEFAULT, "sgemm_")) {
    Dl_info info;
    if (::dladdr(sym, &info) && info.dli_fname) {
      std::error_code ec;
      const fs::path real = fs::canonical(info.dli_fname, ec);
      g.blas = ec ? info.dli_fname : real.string();
    }
  }
  if (g.blas.empty()) g.blas = "(not found: LibTorch's own kernels)";
  return g;
}

}  // namespace viscera::learning
