// The graph U-Net of the learned stepper, on LibTorch: part of the LibTorch plugin
// (learning/nn/torch/, libviscera_torch.so); only its .cpp files and its tests include it.
//
// Tensors are node-major, (nodes, batch, features), so that a graph operator (a sparse nodes x nodes
// matrix) applies to all samples and features at once as one sparse-dense product.
#pragma once

#include <torch/torch.h>

#include <mutex>

#include "learning/nn/torch/MeshGraph.h"
#include "learning/nn/Stepper.h"

namespace viscera::learning {

// The fixed operators of a hierarchy: per level the neighbour mean, and between levels the pooling
// (cluster mean) and unpooling (copy to the members).
struct GraphOps {
  std::vector<torch::Tensor> neighbourMean;  // per level, sparse (n_l, n_l)
  std::vector<torch::Tensor> pool;           // pool[l]: sparse (n_{l+1}, n_l)
  std::vector<torch::Tensor> unpool;         // unpool[l]: sparse (n_l, n_{l+1})
  static GraphOps build(const MeshGraph& graph, torch::Dtype dtype = torch::kFloat32);
};

// S (m, n) sparse times H (n, batch, features) -> (m, batch, features).
torch::Tensor applyGraph(const torch::Tensor& S, const torch::Tensor& H);

// A graph convolution: each node's features mapped with one weight and the mean of its
// neighbours' with another (GraphSAGE's mean aggregator), plus a bias.
struct GraphConvImpl : torch::nn::Module {
  GraphConvImpl(int in, int out);
  torch::Tensor forward(const torch::Tensor& H, const torch::Tensor& neighbourMean);
  torch::nn::Linear self{nullptr}, neighbours{nullptr};
  int in = 0, out = 0;
};
TORCH_MODULE(GraphConv);

// Encoder: a convolution at each level (pooled from the level below); decoder: unpooled, added to
// the encoder's features of that level (skip connection), convolved; the last convolution also sees
// the inputs. ReLU inside; raw output.
struct GraphUNetImpl : torch::nn::Module {
  GraphUNetImpl(int inputs, int width, int levels, int outputs);
  torch::Tensor forward(const torch::Tensor& X, const GraphOps& ops);
  std::vector<GraphConv> down, up;
  int levels = 0;
};
TORCH_MODULE(GraphUNet);

constexpr int kStepperInputs = 14;  // offset 3, rest position 3, fixed 1, instrument seen 1, relative position 3, velocity 3

// The stepper on LibTorch.
struct TorchStepper : Stepper::Impl {
  RestMesh rest;
  StepperArchitecture arch;
  StepperNormalisers norm;
  double period = 0;
  std::string unitSystem, trainingRecord;
  std::uint64_t hash = 0;
  MeshGraph graph;
  GraphOps ops;
  mutable GraphUNet net{nullptr};  // forward() is not const in LibTorch; inference changes nothing
  torch::Tensor movable;    // (n, 1, 1): 0 at fixed nodes
  torch::Tensor stepScale;  // (1, 1, 3): maxStep * cell
  std::vector<char> fixed;  // per node
  torch::Tensor restFeatures;  // (n, 1, inputs): the rest shape, no instrument in reach

  TorchStepper(RestMesh m, const StepperArchitecture& a, const StepperNormalisers& n, double framePeriod, std::string u);

  void checkMesh(const RestMesh& mesh, const std::string& what) const override;
  void save(const std::string& folder, const std::string& training) const override;
  Eigen::Matrix3Xd step(const Eigen::Matrix3Xd& x, const InstrumentInput& instrument) const override;
  const RestMesh& mesh() const override { return rest; }
  const StepperArchitecture& architecture() const override { return arch; }
  const StepperNormalisers& normalisers() const override { return norm; }
  double framePeriod() const override { return period; }
  const std::string& units() const override { return unitSystem; }
  std::int64_t parameters() const override;
  const std::string& training() const override { return trainingRecord; }
  // Writes sample b's features (nodes at `x`, the instrument) into `out`, a (n, batch, inputs) tensor.
  template <class Positions>
  void features(const Positions& x, const InstrumentInput& instrument, torch::Tensor& out, int b) const;
  // The update of every node, (n, batch, 3), from features (n, batch, inputs).
  torch::Tensor update(const torch::Tensor& features) const;

 private:
  // The network at the rest shape with no instrument (restAnchored). Without gradients it is
  // computed once per set of weights (parameters' version counters tell when they changed).
  torch::Tensor anchor() const;
  mutable std::mutex anchorMutex_;
  mutable torch::Tensor anchor_;
  mutable std::int64_t anchorVersion_ = -1;
};

// The corrector's loss on one frame: the mean over the cloud's points (M, 3) of the squared distance
// to the closest of the surface points (S, 3) (the one-sided Chamfer distance).
torch::Tensor chamferLoss(const torch::Tensor& cloud, const torch::Tensor& surface);

// A network's parameters by name (weights.pt); loading refuses a missing parameter or one of
// another shape, naming both (`configPath` is the architecture's source).
void saveParameters(const torch::nn::Module& net, const std::string& path);
void loadParameters(torch::nn::Module& net, const std::string& path, const std::string& configPath);
// The optimiser's state (optimizer.pt), written through a temporary file and a rename.
void saveOptimizer(torch::optim::Optimizer& optimizer, const std::string& path);

// The backend's entry points for the stepper (learning/nn/Backend.h).
std::unique_ptr<Stepper::Impl> newTorchStepper(const RestMesh& mesh, const StepperArchitecture& arch, const StepperNormalisers& norm,
                                               double framePeriod, const std::string& units, std::uint64_t seed);
std::unique_ptr<Stepper::Impl> loadTorchStepper(const std::string& folder);
void torchTrainStepper(const StepperTrainOptions& options, const std::function<void(const EpochReport&)>& progress);
GemmSpeed torchMeasureGemm(int m, int k, int n, int repeats);

template <class Positions>
void TorchStepper::features(const Positions& x, const InstrumentInput& instrument, torch::Tensor& out, int b) const {
  const int n = static_cast<int>(rest.points.cols());
  const long B = out.size(1), F = out.size(2);
  float* base = out.data_ptr<float>() + b * F;
  const long stride = B * F;
  int nearest = -1;
  double best = norm.reach * norm.reach;
  for (int i = 0; i < n; ++i) {
    const double d = (x.col(i).template cast<double>() - instrument.position).squaredNorm();
    if (d <= best) best = d, nearest = i;
  }
  const Eigen::Vector3d mid = 0.5 * (norm.boxMin + norm.boxMax);
  const Eigen::Vector3d half = (0.5 * (norm.boxMax - norm.boxMin)).cwiseMax(1e-12);
  for (int i = 0; i < n; ++i) {
    float* f = base + i * stride;
    const Eigen::Vector3d p = rest.points.col(i);
    const Eigen::Vector3d offset = (x.col(i).template cast<double>() - p).cwiseQuotient(norm.cell);
    const Eigen::Vector3d rest = (p - mid).cwiseQuotient(half);
    for (int a = 0; a < 3; ++a) f[a] = static_cast<float>(offset[a]), f[3 + a] = static_cast<float>(rest[a]);
    f[6] = fixed[i] ? 1.0f : 0.0f;
    for (int k = 7; k < kStepperInputs; ++k) f[k] = 0;
  }
  auto see = [&](int i) {
    float* f = base + i * stride;
    const Eigen::Vector3d rel = (instrument.position - x.col(i).template cast<double>()) / norm.reach;
    const Eigen::Vector3d vel = instrument.velocity / norm.velocityScale;
    f[7] = 1;
    for (int a = 0; a < 3; ++a) f[8 + a] = static_cast<float>(rel[a]), f[11 + a] = static_cast<float>(vel[a]);
  };
  if (arch.instrumentAtAllInReach) {
    const double reach2 = norm.reach * norm.reach;
    for (int i = 0; i < n; ++i)
      if ((x.col(i).template cast<double>() - instrument.position).squaredNorm() <= reach2) see(i);
  } else if (nearest >= 0) {
    see(nearest);
  }
}

}  // namespace viscera::learning
