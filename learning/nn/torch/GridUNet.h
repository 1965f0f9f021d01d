// The learned correction's network and model state, on LibTorch. Internal to learning/nn: only this
// module's .cpp files (and its tests) include it.
#pragma once

#include <torch/torch.h>

#include <tuple>
#include <utility>

#include "core/Error.h"
#include "learning/nn/Corrector.h"
#include "learning/nn/torch/MeshGraph.h"
#include "learning/nn/torch/GraphUNet.h"

namespace viscera::learning {

constexpr int kCorrectorInputs = 6;  // offset from rest (cells), rest position in the box
constexpr int kPoseInputs = 6;       // instrument position in the box, velocity

// Two 3x3(x3) convolutions with ReLU, in 2 or 3 dimensions.
struct ConvBlockImpl : torch::nn::Module {
  ConvBlockImpl(int dims, int in, int out, int convs = 2) {
    for (int c = 0; c < convs; ++c) {
      const int i = c == 0 ? in : out;
      if (dims == 2)
        layers.emplace_back(register_module("conv" + std::to_string(c), torch::nn::Conv2d(torch::nn::Conv2dOptions(i, out, 3).padding(1))));
      else
        layers.emplace_back(register_module("conv" + std::to_string(c), torch::nn::Conv3d(torch::nn::Conv3dOptions(i, out, 3).padding(1))));
    }
  }
  torch::Tensor forward(torch::Tensor x) {
    for (auto& l : layers) x = torch::relu(l.forward(x));
    return x;
  }
  std::vector<torch::nn::AnyModule> layers;
};
TORCH_MODULE(ConvBlock);

// Three blocks down (w, 2w, 4w), each followed by a 2x max-pooling; the pose joins at the bottom
// (four convolutions back to 4w); three blocks up with skip connections; a 1x1 convolution to 3
// outputs.
struct GridUNetImpl : torch::nn::Module {
  GridUNetImpl(int dims, int inputs, int width) : dims(dims) {
    e1 = register_module("e1", ConvBlock(dims, inputs, width));
    e2 = register_module("e2", ConvBlock(dims, width, 2 * width));
    e3 = register_module("e3", ConvBlock(dims, 2 * width, 4 * width));
    bottom = register_module("bottom", ConvBlock(dims, 4 * width + kPoseInputs, 4 * width, 4));
    d3 = register_module("d3", ConvBlock(dims, 8 * width, 4 * width));
    d2 = register_module("d2", ConvBlock(dims, 6 * width, 2 * width));
    d1 = register_module("d1", ConvBlock(dims, 3 * width, width));
    if (dims == 2)
      out = torch::nn::AnyModule(register_module("out", torch::nn::Conv2d(torch::nn::Conv2dOptions(width, 3, 1))));
    else
      out = torch::nn::AnyModule(register_module("out", torch::nn::Conv3d(torch::nn::Conv3dOptions(width, 3, 1))));
    // A new corrector changes nothing: its output layer starts at zero.
    torch::NoGradGuard noGrad;
    for (auto& p : out.ptr()->parameters()) p.zero_();
  }
  torch::Tensor pool(const torch::Tensor& x) {
    return dims == 2 ? torch::max_pool2d(x, 2, 2, 0, 1, true) : torch::max_pool3d(x, 2, 2, 0, 1, true);
  }
  torch::Tensor upTo(const torch::Tensor& x, const torch::Tensor& like) {
    std::vector<int64_t> size(like.sizes().begin() + 2, like.sizes().end());
    return torch::nn::functional::interpolate(x, torch::nn::functional::InterpolateFuncOptions().size(size).mode(torch::kNearest));
  }
  torch::Tensor forward(const torch::Tensor& x, const torch::Tensor& pose) {
    const torch::Tensor a = e1(x), b = e2(pool(a)), c = e3(pool(b));
    torch::Tensor m = pool(c);
    std::vector<int64_t> shape = {pose.size(0), pose.size(1)};
    for (int d = 0; d < dims; ++d) shape.push_back(1);
    std::vector<int64_t> full(m.sizes().begin(), m.sizes().end());
    full[1] = pose.size(1);
    const torch::Tensor p = pose.view(shape).expand(full);
    m = bottom(torch::cat({m, p}, 1));
    torch::Tensor h = d3(torch::cat({upTo(m, c), c}, 1));
    h = d2(torch::cat({upTo(h, b), b}, 1));
    h = d1(torch::cat({upTo(h, a), a}, 1));
    return out.forward(h);
  }
  int dims;
  ConvBlock e1{nullptr}, e2{nullptr}, e3{nullptr}, bottom{nullptr}, d3{nullptr}, d2{nullptr}, d1{nullptr};
  torch::nn::AnyModule out;
};
TORCH_MODULE(GridUNet);

// The face of the grid box that faces the camera: (axis, side 0 = min, 1 = max).
inline std::pair<int, int> observedFace(const Eigen::Vector3d& view) {
  int axis = 0, side = 0;
  double best = 1e300;
  for (int a = 0; a < 3; ++a)
    for (int s = 0; s < 2; ++s) {
      const double facing = (s == 1 ? 1.0 : -1.0) * view[a];  // outward normal . view: most negative faces the camera
      if (facing < best) best = facing, axis = a, side = s;
    }
  return {axis, side};
}

// The corrector on LibTorch.
struct TorchCorrector : Corrector::Impl {
  RestMesh rest;
  GridShape shape;
  Eigen::Vector3d view;
  CorrectorArchitecture arch;
  std::string unitSystem, trainingRecord;
  std::uint64_t hash = 0;
  Eigen::Vector3d cell, boxMin, boxMax;
  double velocityScale = 10;
  int faceAxis = 2, faceSide = 1, faceU = 0, faceV = 1, nu = 0, nv = 0;
  std::vector<int> faceNodes;  // 2D: the observed face's nodes, u-major
  std::vector<int> movable;
  mutable GridUNet net{nullptr};
  torch::Tensor restFeatures;  // (n, inputs) at rest: the rest-position part, offsets added per frame
  torch::Tensor movableMask;   // (n, 1)
  torch::Tensor limit;         // (1, 3): maxCorrection * cell
  torch::Tensor faceIndex;     // long (faceNodes)
  torch::Tensor refine;        // sparse (refined points, n)

  TorchCorrector(RestMesh m, const GridShape& g, const Eigen::Vector3d& v, const CorrectorArchitecture& a, std::string u)
      : rest(std::move(m)), shape(checkGrid(rest, g, "corrector")), view(v.normalized()), arch(a), unitSystem(std::move(u)) {
    if (a.width < 1 || a.width > 1024) throw Error("corrector width must be 1 to 1024, got " + std::to_string(a.width));
    if (!(a.maxCorrection > 0) || a.maxCorrection > 5) throw Error("corrector maxCorrection must be in (0, 5] cells");
    hash = meshHash(rest);
    boxMin = rest.points.rowwise().minCoeff();
    boxMax = rest.points.rowwise().maxCoeff();
    cell = Eigen::Vector3d((boxMax.x() - boxMin.x()) / (shape.nx - 1), (boxMax.y() - boxMin.y()) / (shape.ny - 1),
                           (boxMax.z() - boxMin.z()) / (shape.nz - 1));
    std::tie(faceAxis, faceSide) = observedFace(view);
    faceU = faceAxis == 0 ? 1 : 0;
    faceV = faceAxis == 2 ? 1 : 2;
    const int dims[3] = {shape.nx, shape.ny, shape.nz};
    nu = dims[faceU];
    nv = dims[faceV];
    for (int iu = 0; iu < nu; ++iu)
      for (int iv = 0; iv < nv; ++iv) {
        int ijk[3];
        ijk[faceAxis] = faceSide ? dims[faceAxis] - 1 : 0;
        ijk[faceU] = iu;
        ijk[faceV] = iv;
        faceNodes.push_back(shape.index(ijk[0], ijk[1], ijk[2]));
      }
    const int n = shape.nodes();
    std::vector<char> fixed(n, 0), seen(n, arch.threeD ? 1 : 0);
    for (int f : rest.fixed) fixed[f] = 1;
    if (!arch.threeD)
      for (int i : faceNodes) seen[i] = 1;
    movableMask = torch::zeros({n, 1});
    for (int i = 0; i < n; ++i)
      if (seen[i] && !fixed[i]) movable.push_back(i), movableMask[i][0] = 1.0f;
    limit = torch::tensor({float(arch.maxCorrection * cell[0]), float(arch.maxCorrection * cell[1]), float(arch.maxCorrection * cell[2])}).view({1, 3});
    faceIndex = torch::tensor(std::vector<int64_t>(faceNodes.begin(), faceNodes.end()), torch::kLong);
    restFeatures = torch::zeros({n, kCorrectorInputs});
    const Eigen::Vector3d mid = 0.5 * (boxMin + boxMax), half = (0.5 * (boxMax - boxMin)).cwiseMax(1e-12);
    for (int i = 0; i < n; ++i)
      for (int a2 = 0; a2 < 3; ++a2) restFeatures[i][3 + a2] = float((rest.points(a2, i) - mid[a2]) / half[a2]);
    net = GridUNet(arch.threeD ? 3 : 2, kCorrectorInputs, arch.width);
    buildRefinement();
  }

  void checkMesh(const RestMesh& mesh, const std::string& what) const override;
  void save(const std::string& folder, const std::string& training) const override;
  Eigen::Matrix3Xd correct(const Eigen::Matrix3Xd& x, const InstrumentInput& instrument) const override;
  const std::vector<int>& movableNodes() const override { return movable; }
  const RestMesh& mesh() const override { return rest; }
  const GridShape& grid() const override { return shape; }
  const CorrectorArchitecture& architecture() const override { return arch; }
  const std::string& units() const override { return unitSystem; }
  const std::string& training() const override { return trainingRecord; }
  std::int64_t parameters() const override;
  Eigen::Matrix3Xd refinedSurface(const Eigen::Matrix3Xd& x) const override;

  // Bilinear points of each boundary face refined three times, as a sparse (points, n) matrix.
  void buildRefinement() {
    std::vector<int64_t> rows, cols;
    std::vector<float> vals;
    int64_t point = 0;
    const int dims[3] = {shape.nx, shape.ny, shape.nz};
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side) {
        const int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;
        const int ru = 3 * (dims[u] - 1) + 1, rv = 3 * (dims[v] - 1) + 1;
        for (int a = 0; a < ru; ++a)
          for (int b = 0; b < rv; ++b) {
            // Each refined point once: shared edges of two faces are kept on the first face only.
            const int cu = std::min(a / 3, dims[u] - 2), cv = std::min(b / 3, dims[v] - 2);
            const double fu = a / 3.0 - cu, fv = b / 3.0 - cv;
            const bool edgeU = a == 0 || a == ru - 1, edgeV = b == 0 || b == rv - 1;
            if ((edgeU && u < axis) || (edgeV && v < axis)) continue;
            for (int du = 0; du < 2; ++du)
              for (int dv = 0; dv < 2; ++dv) {
                const double w = (du ? fu : 1 - fu) * (dv ? fv : 1 - fv);
                if (w == 0) continue;
                int ijk[3];
                ijk[axis] = side ? dims[axis] - 1 : 0;
                ijk[u] = cu + du;
                ijk[v] = cv + dv;
                rows.push_back(point), cols.push_back(shape.index(ijk[0], ijk[1], ijk[2])), vals.push_back(static_cast<float>(w));
              }
            ++point;
          }
      }
    torch::Tensor idx = torch::empty({2, static_cast<int64_t>(rows.size())}, torch::kLong);
    for (size_t k = 0; k < rows.size(); ++k) idx[0][k] = rows[k], idx[1][k] = cols[k];
    refine = torch::sparse_coo_tensor(idx, torch::tensor(vals), {point, static_cast<int64_t>(shape.nodes())}).coalesce();
  }

  // Node features of B frames (nodes x(b), float) and their pose, as the network's tensors.
  torch::Tensor nodeFeatures(const std::vector<const Eigen::Matrix3Xf*>& xs) const {
    const int n = shape.nodes(), B = static_cast<int>(xs.size());
    torch::Tensor f = restFeatures.unsqueeze(0).repeat({B, 1, 1});  // (B, n, C)
    auto fa = f.accessor<float, 3>();
    for (int b = 0; b < B; ++b)
      for (int i = 0; i < n; ++i)
        for (int a = 0; a < 3; ++a) fa[b][i][a] = static_cast<float>(((*xs[b])(a, i) - rest.points(a, i)) / cell[a]);
    return f;
  }
  torch::Tensor poseFeatures(const std::vector<InstrumentInput>& tools) const {
    const int B = static_cast<int>(tools.size());
    torch::Tensor p = torch::empty({B, kPoseInputs});
    const Eigen::Vector3d mid = 0.5 * (boxMin + boxMax), half = (0.5 * (boxMax - boxMin)).cwiseMax(1e-12);
    for (int b = 0; b < B; ++b)
      for (int a = 0; a < 3; ++a) {
        p[b][a] = float((tools[b].position[a] - mid[a]) / half[a]);
        p[b][3 + a] = float(tools[b].velocity[a] / velocityScale);
      }
    return p;
  }
  // Corrections (B, n, 3) from node features (B, n, C) and poses (B, P).
  torch::Tensor corrections(const torch::Tensor& feats, const torch::Tensor& pose) const {
    const int64_t B = feats.size(0), n = shape.nodes();
    torch::Tensor raw;
    if (arch.threeD) {
      const torch::Tensor g = feats.view({B, shape.nz, shape.ny, shape.nx, kCorrectorInputs}).permute({0, 4, 1, 2, 3});
      raw = net->forward(g, pose).permute({0, 2, 3, 4, 1}).reshape({B, n, 3});
    } else {
      const torch::Tensor face = feats.index_select(1, faceIndex).view({B, nu, nv, kCorrectorInputs}).permute({0, 3, 1, 2});
      const torch::Tensor out = net->forward(face, pose).permute({0, 2, 3, 1}).reshape({B, nu * nv, 3});
      raw = torch::zeros({B, n, 3}).index_add(1, faceIndex, out);
    }
    return limit * torch::tanh(raw) * movableMask;
  }
};

// The backend's entry points for the corrector (learning/nn/Backend.h).
std::unique_ptr<Corrector::Impl> newTorchCorrector(const RestMesh& mesh, const GridShape& grid, const Eigen::Vector3d& view,
                                                   const CorrectorArchitecture& arch, const std::string& units, std::uint64_t seed);
std::unique_ptr<Corrector::Impl> loadTorchCorrector(const std::string& folder);
void torchTrainCorrector(const CorrectorTrainOptions& options, const std::function<void(const CorrectorEpochReport&)>& progress);

}  // namespace viscera::learning
