// Pairs for a learned correction: a body on a regular grid as a scene simulated it at each frame of
// a measured dataset, beside the cloud measured then (in the scene frame). A pair folder holds
// pairs.json (the index: scene, dataset, units, grid, camera direction), mesh.bin (the rest mesh,
// as for rollouts), states.bin (a rollout file: per frame the time, the simulated nodes and the
// instrument) and clouds.bin (writeCloudFrames).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "learning/data/Rollout.h"

namespace viscera::learning {

// Nodes per axis of a regular grid whose node i + nx (j + ny k) is at (i, j, k) (SOFA's order).
struct GridShape {
  int nx = 0, ny = 0, nz = 0;
  int nodes() const { return nx * ny * nz; }
  int index(int i, int j, int k) const { return i + nx * (j + ny * k); }
};

struct PairSet {
  std::string folder, scene, dataset, units;
  RestMesh mesh;
  GridShape grid;
  Eigen::Vector3d viewDirection{0, 0, -1};  // the camera's viewing direction, scene frame
  std::vector<RolloutFrame> states;          // per measured frame
  std::vector<Eigen::Matrix3Xf> clouds;      // per measured frame, scene frame
};

// The grid shape of a rest mesh's nodes, checked: node i + nx (j + ny k) must lie at the grid's
// corner plus i, j, k spacings. Throws Error (naming `what`) when the nodes are not such a grid.
GridShape checkGrid(const RestMesh& mesh, const GridShape& shape, const std::string& what);

// The grid shape of a rest mesh whose nodes are a regular grid in SOFA's order (found from the
// distinct coordinates along each axis), or nothing.
std::optional<GridShape> gridOf(const RestMesh& mesh);

// Writes the pair files into `folder` (which must exist); each file is written whole.
void writePairSet(const std::string& folder, const PairSet& pairs);
// Reads a pair folder; throws Error naming the file for anything missing or inconsistent.
PairSet readPairSet(const std::string& folder);
// True when `folder` holds pairs (pairs.json), not rollouts.
bool isPairFolder(const std::string& folder);

}  // namespace viscera::learning
