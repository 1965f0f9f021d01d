#include "learning/nn/torch/MeshGraph.h"

#include <algorithm>
#include <cstring>
#include <limits>

#include "core/Error.h"

namespace viscera::learning {

namespace {

std::vector<std::vector<int>> adjacency(int n, const std::vector<std::pair<int, int>>& edges) {
  std::vector<std::vector<int>> adj(n);
  for (auto [a, b] : edges) {
    adj[a].push_back(b);
    adj[b].push_back(a);
  }
  return adj;
}

// One greedy matching: each node still free takes its nearest free neighbour (lowest index on a
// tie); a node with none stays alone. Returns the cluster of each node and the cluster count.
int matchOnce(const GraphLevel& g, std::vector<int>& cluster) {
  const auto adj = adjacency(g.nodes, g.edges);
  cluster.assign(g.nodes, -1);
  int clusters = 0;
  for (int i = 0; i < g.nodes; ++i) {
    if (cluster[i] >= 0) continue;
    int best = -1;
    double bestDist = std::numeric_limits<double>::infinity();
    for (int j : adj[i]) {
      if (cluster[j] >= 0) continue;
      const double d = (g.positions.col(i) - g.positions.col(j)).squaredNorm();
      if (d < bestDist || (d == bestDist && j < best)) best = j, bestDist = d;
    }
    cluster[i] = clusters;
    if (best >= 0) cluster[best] = clusters;
    ++clusters;
  }
  return clusters;
}

// The graph of the clusters: their mean positions, joined where any members are.
GraphLevel coarsen(const GraphLevel& g, const std::vector<int>& cluster, int clusters) {
  GraphLevel c;
  c.nodes = clusters;
  c.positions = Eigen::Matrix3Xd::Zero(3, clusters);
  Eigen::VectorXd count = Eigen::VectorXd::Zero(clusters);
  for (int i = 0; i < g.nodes; ++i) {
    c.positions.col(cluster[i]) += g.positions.col(i);
    count[cluster[i]] += 1;
  }
  for (int k = 0; k < clusters; ++k) c.positions.col(k) /= count[k];
  for (auto [a, b] : g.edges) {
    int ca = cluster[a], cb = cluster[b];
    if (ca == cb) continue;
    if (ca > cb) std::swap(ca, cb);
    c.edges.emplace_back(ca, cb);
  }
  std::sort(c.edges.begin(), c.edges.end());
  c.edges.erase(std::unique(c.edges.begin(), c.edges.end()), c.edges.end());
  c.cluster = cluster;
  return c;
}

}  // namespace

MeshGraph buildMeshGraph(const RestMesh& mesh, int levels, int matchings) {
  if (levels < 0 || levels > 8) throw Error("graph levels must be 0 to 8, got " + std::to_string(levels));
  if (matchings < 1 || matchings > 4) throw Error("matchings per level must be 1 to 4, got " + std::to_string(matchings));
  MeshGraph graph;
  GraphLevel base;
  base.nodes = static_cast<int>(mesh.points.cols());
  base.positions = mesh.points;
  for (int t = 0; t < mesh.tets.cols(); ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        int i = mesh.tets(a, t), j = mesh.tets(b, t);
        if (i > j) std::swap(i, j);
        base.edges.emplace_back(i, j);
      }
  std::sort(base.edges.begin(), base.edges.end());
  base.edges.erase(std::unique(base.edges.begin(), base.edges.end()), base.edges.end());
  graph.levels.push_back(std::move(base));
  for (int l = 0; l < levels; ++l) {
    // Several matchings make one level; the clusters compose.
    GraphLevel level = graph.levels.back();
    std::vector<int> total(level.nodes);
    for (int i = 0; i < level.nodes; ++i) total[i] = i;
    for (int m = 0; m < matchings; ++m) {
      std::vector<int> cluster;
      const int clusters = matchOnce(level, cluster);
      level = coarsen(level, cluster, clusters);
      for (int& c : total) c = cluster[c];
    }
    // Positions: the means of the members (not of the intermediate matchings' means).
    const GraphLevel& fine = graph.levels.back();
    Eigen::VectorXd count = Eigen::VectorXd::Zero(level.nodes);
    level.positions.setZero();
    for (int i = 0; i < fine.nodes; ++i) level.positions.col(total[i]) += fine.positions.col(i), count[total[i]] += 1;
    for (int k = 0; k < level.nodes; ++k) level.positions.col(k) /= count[k];
    level.cluster = total;
    graph.levels.push_back(std::move(level));
  }
  return graph;
}

Eigen::Vector3d meshCellSize(const RestMesh& mesh) {
  if (mesh.tets.cols() == 0) throw Error("the mesh has no tetrahedra");
  Eigen::Vector3d cell;
  std::vector<double> extent(mesh.tets.cols());
  for (int a = 0; a < 3; ++a) {
    for (int t = 0; t < mesh.tets.cols(); ++t) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (int k = 0; k < 4; ++k) {
        const double v = mesh.points(a, mesh.tets(k, t));
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
      extent[t] = hi - lo;
    }
    std::nth_element(extent.begin(), extent.begin() + extent.size() / 2, extent.end());
    cell[a] = extent[extent.size() / 2];
  }
  if (!(cell.minCoeff() > 0)) throw Error("the mesh's tetrahedra are flat along an axis (cell size 0)");
  return cell;
}

std::uint64_t meshHash(const RestMesh& mesh) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a
  auto mix = [&h](const void* data, size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  };
  const std::int64_t n = mesh.points.cols(), t = mesh.tets.cols();
  mix(&n, sizeof n);
  mix(&t, sizeof t);
  for (Eigen::Index i = 0; i < mesh.points.size(); ++i) {
    const float v = static_cast<float>(mesh.points.data()[i]);
    mix(&v, sizeof v);
  }
  mix(mesh.tets.data(), sizeof(int) * mesh.tets.size());
  for (int f : mesh.fixed) mix(&f, sizeof f);
  return h;
}

}  // namespace viscera::learning
