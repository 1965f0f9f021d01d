// The graph U-Net's layers against finite differences, and the network's ability to fit: checks of
// the LibTorch internals of learning/nn (this file is built only with LibTorch).
#include <gtest/gtest.h>

#include <random>

#include "learning/nn/torch/MeshGraph.h"
#include "learning/nn/torch/GraphUNet.h"

using namespace viscera::learning;

namespace {

// A grid of nx x ny x nz nodes (unit spacing), each cube split into six tetrahedra.
RestMesh gridMesh(int nx, int ny, int nz) {
  RestMesh m;
  m.points.resize(3, nx * ny * nz);
  auto id = [&](int i, int j, int k) { return i + nx * (j + ny * k); };
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) m.points.col(id(i, j, k)) = Eigen::Vector3d(i, j, k);
  std::vector<std::array<int, 4>> tets;
  for (int k = 0; k + 1 < nz; ++k)
    for (int j = 0; j + 1 < ny; ++j)
      for (int i = 0; i + 1 < nx; ++i) {
        const int c[8] = {id(i, j, k),         id(i + 1, j, k),         id(i + 1, j + 1, k),     id(i, j + 1, k),
                          id(i, j, k + 1),     id(i + 1, j, k + 1),     id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
        // Kuhn's six tetrahedra around the diagonal 0-6.
        const int paths[6][2] = {{1, 2}, {1, 5}, {3, 2}, {3, 7}, {4, 5}, {4, 7}};
        for (const auto& p : paths) tets.push_back({c[0], c[p[0]], c[p[1]], c[6]});
      }
  m.tets.resize(4, static_cast<int>(tets.size()));
  for (size_t t = 0; t < tets.size(); ++t)
    for (int a = 0; a < 4; ++a) m.tets(a, static_cast<int>(t)) = tets[t][a];
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) m.fixed.push_back(id(i, j, 0));
  return m;
}

}  // namespace

TEST(MeshGraph, LevelsCoarsenAndEveryNodeHasACluster) {
  const RestMesh mesh = gridMesh(5, 4, 3);
  const MeshGraph g = buildMeshGraph(mesh, 2, 2);
  ASSERT_EQ(g.levels.size(), 3u);
  EXPECT_EQ(g.levels[0].nodes, 60);
  for (size_t l = 1; l < g.levels.size(); ++l) {
    const GraphLevel& fine = g.levels[l - 1];
    const GraphLevel& coarse = g.levels[l];
    // Two matchings: at most half and at least a quarter of the nodes (pairs of pairs).
    EXPECT_LE(coarse.nodes, (fine.nodes + 1) / 2);
    EXPECT_GE(coarse.nodes, fine.nodes / 4);
    ASSERT_EQ(static_cast<int>(coarse.cluster.size()), fine.nodes);
    std::vector<int> members(coarse.nodes, 0);
    for (int c : coarse.cluster) {
      ASSERT_GE(c, 0);
      ASSERT_LT(c, coarse.nodes);
      ++members[c];
    }
    for (int k = 0; k < coarse.nodes; ++k) EXPECT_GE(members[k], 1);
    // Cluster positions are their members' means.
    Eigen::Matrix3Xd sum = Eigen::Matrix3Xd::Zero(3, coarse.nodes);
    for (int i = 0; i < fine.nodes; ++i) sum.col(coarse.cluster[i]) += fine.positions.col(i);
    for (int k = 0; k < coarse.nodes; ++k) EXPECT_LT((sum.col(k) / members[k] - coarse.positions.col(k)).norm(), 1e-12);
    for (auto [a, b] : coarse.edges) EXPECT_LT(a, b);
  }
  // The grid's edges: 6 tetrahedra per cube share the cube's 12 edges, 6 face diagonals and 1 body diagonal.
  EXPECT_GT(g.levels[0].edges.size(), 0u);
  // Deterministic.
  const MeshGraph h = buildMeshGraph(mesh, 2, 2);
  EXPECT_EQ(h.levels[2].cluster, g.levels[2].cluster);
  EXPECT_EQ(h.levels[1].edges, g.levels[1].edges);
}

// Autograd's gradient of the U-Net (graph convolutions, pooling, unpooling) against central
// differences in double precision: relative agreement to 1e-6 (the differences' truncation error is
// O(h^2) = 1e-12 and round-off about 1e-16 / h = 1e-10; ReLU kinks are not met by random inputs).
TEST(GraphUNet, GradientsMatchFiniteDifferences) {
  const RestMesh mesh = gridMesh(4, 3, 3);
  const MeshGraph g = buildMeshGraph(mesh, 2, 1);
  const GraphOps ops = GraphOps::build(g, torch::kFloat64);
  torch::manual_seed(3);
  GraphUNet net(5, 6, 2, 3);
  net->to(torch::kFloat64);
  const long n = g.levels[0].nodes;
  torch::Tensor X = torch::randn({n, 2, 5}, torch::kFloat64).requires_grad_(true);
  const torch::Tensor W = torch::randn({n, 2, 3}, torch::kFloat64);
  auto loss = [&] { return (net->forward(X, ops) * W).sum(); };
  loss().backward();
  const torch::Tensor gradX = X.grad().clone();

  const double h = 1e-6;
  auto central = [&](torch::Tensor t, long k) {
    torch::NoGradGuard noGrad;
    double* p = t.data_ptr<double>() + k;
    const double keep = *p;
    *p = keep + h;
    const double up = loss().item<double>();
    *p = keep - h;
    const double down = loss().item<double>();
    *p = keep;
    return (up - down) / (2 * h);
  };
  double scale = gradX.abs().max().item<double>();
  for (long k = 0; k < X.numel(); ++k)
    EXPECT_NEAR(central(X, k), gradX.data_ptr<double>()[k], 1e-6 * scale) << "input " << k;
  int checked = 0;
  for (auto& p : net->named_parameters()) {
    const torch::Tensor grad = p.value().grad().clone();
    const double s = std::max(1e-12, grad.abs().max().item<double>());
    for (long k = 0; k < p.value().numel(); k += std::max<long>(1, p.value().numel() / 7), ++checked)
      EXPECT_NEAR(central(p.value(), k), grad.data_ptr<double>()[k], 1e-6 * s) << p.key() << " " << k;
  }
  EXPECT_GT(checked, 50);
}

// The whole stepper (features, U-Net, scaled sigmoid, fixed nodes) fits one batch: the targets are a
// second network's updates on four samples (so that an exact fit exists), and Adam drives the loss
// to under 1 % of where it starts.
TEST(GraphUNet, OverfitsOneBatch) {
  const RestMesh mesh = gridMesh(5, 4, 4);
  StepperNormalisers norm;
  norm.boxMin = Eigen::Vector3d::Zero();
  norm.boxMax = Eigen::Vector3d(4, 3, 3);
  norm.reach = 2;
  Stepper model(mesh, StepperArchitecture{32, 2, 1, 1.0}, norm, 1.0 / 30, "mm g s", 5);
  const Stepper teacher(mesh, StepperArchitecture{32, 2, 1, 1.0}, norm, 1.0 / 30, "mm g s", 6);
  TorchStepper& m = static_cast<TorchStepper&>(model.impl());
  const int n = static_cast<int>(mesh.points.cols()), B = 4;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  torch::Tensor feats = torch::empty({n, B, kStepperInputs});
  for (int b = 0; b < B; ++b) {
    Eigen::Matrix3Xd x = mesh.points;
    for (int i = 0; i < n; ++i)
      for (int a = 0; a < 3; ++a) x(a, i) += u(rng);
    m.features(x, InstrumentInput{Eigen::Vector3d(1 + b, 1, 3.5), Eigen::Vector3d(0, 0, -1)}, feats, b);
  }
  torch::Tensor target;
  {
    torch::NoGradGuard noGrad;
    target = static_cast<TorchStepper&>(teacher.impl()).update(feats);
  }
  torch::optim::Adam opt(m.net->parameters(), torch::optim::AdamOptions(3e-3));
  double first = 0, last = 0;
  for (int it = 0; it < 800; ++it) {
    const torch::Tensor loss = (m.update(feats) - target).pow(2).mean();
    if (it == 0) first = loss.item<double>();
    last = loss.item<double>();
    opt.zero_grad();
    loss.backward();
    opt.step();
  }
  EXPECT_LT(last, 0.01 * first) << "first " << first << ", last " << last;
  // Fixed nodes never move; updates stay within maxStep cells.
  const torch::Tensor out = m.update(feats);
  for (int f : mesh.fixed) EXPECT_EQ(out[f].abs().max().item<float>(), 0.0f);
  EXPECT_LE(out.abs().max().item<float>(), 1.0f);
}

// What the output means: with a network that outputs zero, NextOffset takes every free node back
// towards rest by maxStep cell tanh(offset / (maxStep cell)) (the clamp), which for a small offset
// is the whole way; Update leaves it where it is. Fixed nodes stay where they are.
TEST(GraphUNet, AZeroOutputHoldsOrReturnsToRestAsTheOutputSays) {
  const RestMesh mesh = gridMesh(5, 4, 4);
  StepperNormalisers norm;
  norm.cell = Eigen::Vector3d(1, 1, 1);
  norm.boxMax = Eigen::Vector3d(4, 3, 3);
  norm.reach = 2;
  const int n = static_cast<int>(mesh.points.cols());
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-0.4, 0.4);
  Eigen::Matrix3Xd x = mesh.points;
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) x(a, i) += u(rng);
  const InstrumentInput tool{Eigen::Vector3d(2, 1.5, 3.5), Eigen::Vector3d(0, 0, -1)};
  std::vector<char> fixed(n, 0);
  for (int f : mesh.fixed) fixed[f] = 1;
  using Output = StepperArchitecture::Output;
  for (auto [output, share] : {std::pair{Output::Update, 0.0}, std::pair{Output::NextOffset, 1.0}}) {
    StepperArchitecture arch{16, 2, 1, 0.5};
    arch.output = output;
    Stepper model(mesh, arch, norm, 1.0 / 30, "mm g s", 7);
    {
      torch::NoGradGuard noGrad;
      for (auto& p : static_cast<TorchStepper&>(model.impl()).net->parameters()) p.zero_();
    }
    const Eigen::Matrix3Xd next = model.step(x, tool);
    for (int i = 0; i < n; ++i)
      for (int a = 0; a < 3; ++a) {
        const double offset = x(a, i) - mesh.points(a, i);
        const double expected = fixed[i] ? x(a, i) : x(a, i) - 0.5 * std::tanh(share * offset / 0.5);
        EXPECT_NEAR(next(a, i), expected, 1e-6) << outputName(output) << ", node " << i << " axis " << a;
      }
  }
}

// The corrector's Chamfer loss against a brute-force double loop, and its gradient with respect to
// the surface against central differences (double precision; the closest pairs do not change
// within the step h = 1e-6 for random points, so the loss is smooth there).
TEST(ChamferLoss, MatchesBruteForceAndItsGradient) {
  torch::manual_seed(7);
  const torch::Tensor cloud = torch::rand({40, 3}, torch::kFloat64) * 10;
  torch::Tensor surface = (torch::rand({25, 3}, torch::kFloat64) * 10).requires_grad_(true);
  const torch::Tensor loss = chamferLoss(cloud, surface);
  double reference = 0;
  auto c = cloud.accessor<double, 2>();
  auto brute = [&](const torch::Tensor& s) {
    auto a = s.accessor<double, 2>();
    double sum = 0;
    for (int i = 0; i < 40; ++i) {
      double best = 1e300;
      for (int j = 0; j < 25; ++j) {
        double d = 0;
        for (int k = 0; k < 3; ++k) d += (c[i][k] - a[j][k]) * (c[i][k] - a[j][k]);
        best = std::min(best, d);
      }
      sum += best;
    }
    return sum / 40;
  };
  reference = brute(surface.detach());
  EXPECT_NEAR(loss.item<double>(), reference, 1e-12 * reference);
  loss.backward();
  const torch::Tensor grad = surface.grad();
  torch::Tensor probe = surface.detach().clone();
  double* p = probe.data_ptr<double>();
  for (int k = 0; k < 75; ++k) {
    const double keep = p[k], h = 1e-6;
    p[k] = keep + h;
    const double up = brute(probe);
    p[k] = keep - h;
    const double down = brute(probe);
    p[k] = keep;
    EXPECT_NEAR((up - down) / (2 * h), grad.data_ptr<double>()[k], 1e-6) << k;
  }
}
