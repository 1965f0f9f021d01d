// Rollouts: what a learned stepper is trained on. A recording is a folder holding the rest mesh of
// one deformable body (mesh.bin), one file per rollout (rollout_0000.bin, ...) with the body's node
// positions at a fixed frame rate and the instrument's pose, velocity and contact wrench, and an
// index (rollouts.json) saying how each was made. The binary files are little-endian, start with
// an 8-byte magic and a version, and are described in docs/user-guide.md ("Rollouts").
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace viscera::learning {

// The body at rest: positions (3 x #nodes), tetrahedra (4 x #tets, node indices) and the nodes its
// projective constraints hold fixed.
struct RestMesh {
  Eigen::Matrix3Xd points;
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets;
  std::vector<int> fixed;
};

// One frame: the time, every node's position (single precision: the network's) and the instrument.
struct RolloutFrame {
  double t = 0;
  Eigen::Matrix3Xf x;                                    // 3 x #nodes
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();         // instrument position
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();    // mean over the step ending at t
  Eigen::Vector3d angularVelocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d force = Eigen::Vector3d::Zero();       // contact force on the instrument
  std::int32_t contacts = 0;                             // contacts carrying force
};

void writeRestMesh(const std::string& path, const RestMesh& mesh);
// Throws Error naming the file (and the byte offset) for anything that is not a rest mesh.
RestMesh readRestMesh(const std::string& path);

// Writes a rollout frame by frame (a long rollout is never held in memory); the file exists under
// its name only once close() has written its frame count.
class RolloutWriter {
 public:
  RolloutWriter(const std::string& path, int nodes);
  ~RolloutWriter();
  RolloutWriter(const RolloutWriter&) = delete;
  RolloutWriter& operator=(const RolloutWriter&) = delete;
  void add(const RolloutFrame& f);
  void close();
  int frames() const { return frames_; }

 private:
  std::string path_, partial_;
  std::FILE* file_ = nullptr;
  int nodes_ = 0, frames_ = 0;
};

// Reads a whole rollout; `nodes` (when >= 0) is the mesh's node count, which it must match.
// Throws Error naming the file for anything else.
std::vector<RolloutFrame> readRollout(const std::string& path, int nodes = -1);

}  // namespace viscera::learning

namespace viscera::learning {

// Point clouds, one per frame (single precision, 3 x #points each): the measured side of the pairs
// a learned correction trains on. Little-endian: the 8 bytes VSCCLOU1, uint32 version (1), uint32
// frames, then per frame uint32 points P and P x (x, y, z) float32.
void writeCloudFrames(const std::string& path, const std::vector<Eigen::Matrix3Xf>& clouds);
std::vector<Eigen::Matrix3Xf> readCloudFrames(const std::string& path);

// A recording folder as its index (rollouts.json) describes it: the rest mesh, how the frames were
// made, and the rollouts that completed (those that diverged are listed in `skipped`).
struct RolloutSet {
  std::string folder;
  RestMesh mesh;
  std::string units;
  double frameRate = 0;          // frames per unit time
  double instrumentRadius = 0;
  std::vector<std::string> files;    // full paths of the usable rollouts
  std::vector<std::string> skipped;  // rollouts marked as diverged
};

// Reads `folder`/rollouts.json and mesh.bin. Throws Error naming the file for a missing or
// malformed index, or a rollout file that is missing.
RolloutSet readRolloutSet(const std::string& folder);

}  // namespace viscera::learning
