// The graph a learned stepper convolves over: the nodes of a tetrahedral mesh joined by the
// tetrahedra's edges, and a fixed hierarchy of coarser graphs for the U-Net's pooling. Each coarser
// level merges pairs of neighbouring nodes (a greedy matching, nearest neighbour first), `matchings`
// times per level, so a level has about 2^-matchings of the nodes of the one below.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <vector>

#include "learning/data/Rollout.h"

namespace viscera::learning {

struct GraphLevel {
  int nodes = 0;
  std::vector<std::pair<int, int>> edges;  // undirected, first < second, sorted
  Eigen::Matrix3Xd positions;              // rest positions (cluster means above level 0)
  std::vector<int> cluster;                // level > 0: the cluster of each node of the level below
};

struct MeshGraph {
  std::vector<GraphLevel> levels;  // levels[0] is the mesh itself
};

// The hierarchy of `levels` coarser graphs above the mesh graph. Deterministic: the same mesh gives
// the same hierarchy.
MeshGraph buildMeshGraph(const RestMesh& mesh, int levels, int matchings);

// The mesh's cell size along each axis: the median extent of the tetrahedra's bounding boxes
// (exactly the grid spacing for a grid split into tetrahedra).
Eigen::Vector3d meshCellSize(const RestMesh& mesh);

// A fingerprint of the rest mesh (node count, rest positions at single precision, tetrahedra and
// fixed nodes): a model trained on one mesh refuses another.
std::uint64_t meshHash(const RestMesh& mesh);

}  // namespace viscera::learning
