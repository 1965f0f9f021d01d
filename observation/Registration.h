// Rigid registration of measured data to the simulated scene:
//  - ICP of a rest-state point cloud (camera frame) to the tissue's surface (scene frame), and
//  - point-based registration from corresponding points (robot frame -> scene frame), e.g. the
//    phantom's corners touched with the end-effector.
// Both return the rigid map source -> target, x_target = R x_source + t, as writeTransform stores it.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "observation/SurfaceIndex.h"
#include "io/scene/Transform.h"

namespace viscera::obs {

// ---------------------------------------------------------------------------------------------
// ICP: cloud -> surface

struct IcpOptions {
  // Correspondences farther than this from the surface are ignored (length; +inf: no limit).
  double maxDistance = std::numeric_limits<double>::infinity();
  // After each iteration the limit becomes min(limit, shrinkFactor x RMS distance of the pairs
  // within it, before trimming), so that it tightens around the inliers as the alignment improves
  // (with Gaussian noise it settles near shrinkFactor sigma); 0 keeps it fixed.
  double shrinkFactor = 3.0;
  // Fraction of the pairs within the limit that are kept: the closest ones (trimmed ICP). Points
  // of the cloud that are not on the surface (outliers, other objects) fall in the rest.
  double trim = 0.9;
  int maxIterations = 100;
  // Converged when an iteration rotates by at most `tolerance` radians and moves the kept points'
  // centroid by at most `tolerance` x the cloud's RMS radius (unit-free, so mm and m scenes agree).
  double tolerance = 1e-6;
  // The point-to-plane system is ill-conditioned when the smallest eigenvalue of its scaled 6 x 6
  // matrix is below this fraction of the largest: that iteration falls back to point-to-point
  // (Kabsch), and directions below it are reported as weakly constrained.
  double degeneracyRatio = 1e-3;
};

// A weakly constrained direction of the final point-to-plane system: a small rigid motion
// (rotation about the kept points' centroid, translation) that changes the residuals little.
struct WeakDirection {
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();     // rotation axis part (unit-free, scaled by the cloud radius)
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // translation part; |rotation|^2 + |translation|^2 = 1
  double ratio = 0;                                       // its eigenvalue / the largest eigenvalue
  // "translation along (1, 0, 0)", "rotation about (0, 0, 1)" or "mixed ..." for messages.
  std::string describe() const;
};

struct IcpResult {
  RigidTransform transform = RigidTransform::Identity();  // cloud frame -> surface frame
  int iterations = 0;
  bool converged = false;
  int pointToPointIterations = 0;  // iterations that fell back to point-to-point
  // Over the kept pairs of the final transform (distance from each point to its closest surface point).
  double rms = 0, mean = 0, max = 0;
  int pairs = 0;                 // pairs kept at the end
  double keptFraction = 0;       // pairs / cloud points
  double finalMaxDistance = 0;   // the correspondence limit at the end (+inf when none)
  // Conditioning of the final point-to-plane system: smallest / largest eigenvalue of its 6 x 6
  // matrix with rotations scaled by the cloud's RMS radius (both parts then move points by a length).
  double conditionRatio = 0;
  Eigen::Matrix<double, 6, 1> eigenvalues = Eigen::Matrix<double, 6, 1>::Zero();  // ascending, / #pairs
  bool degenerate = false;  // conditionRatio < degeneracyRatio: along weakDirections the result
                            // comes mostly from the initial guess
  std::vector<WeakDirection> weakDirections;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // of the kept points (surface frame): the
                                                       // centre of the weak directions' rotations
  // Per cloud point (n = cloud size), at the final transform: the distance to the surface (no
  // limit) and whether the pair was kept.
  Eigen::VectorXd distances;
  std::vector<bool> kept;
};

// Registers `cloud` (3 x n, camera frame) to `surface` (scene frame) starting from `initial`
// (camera -> scene). Point-to-plane ICP on exact closest points: each iteration linearises the
// rotation (R ~ I + [w]x about the kept points' centroid) and solves the 6 x 6 normal equations of
// sum (n_i . (R y_i + t - q_i))^2. `source` names the cloud in messages. Throws viscera::Error for
// an empty or non-finite cloud, an empty surface, invalid options, or fewer than 6 pairs within
// the distance limit.
IcpResult registerIcp(const Eigen::Matrix3Xd& cloud, const SurfaceIndex& surface, const RigidTransform& initial,
                      const IcpOptions& options = {}, const std::string& source = "cloud");

// ---------------------------------------------------------------------------------------------
// Corresponding points: robot -> scene

struct PointRegistration {
  RigidTransform transform = RigidTransform::Identity();  // source -> target
  Eigen::Matrix3Xd residuals;                             // 3 x n: T source_i - target_i
  Eigen::VectorXd norms;                                  // n: |residual_i|
  double rms = 0, max = 0;
};

// The rigid transform (rotation and translation, no scale) minimising sum |R s_i + t - d_i|^2
// (Kabsch / Umeyama). `source` and `target` are 3 x n with n >= 3 and the same n. Throws
// viscera::Error (naming the set by `sourceName` / `targetName`, e.g. its file) for fewer than 3
// points, different counts, non-finite values, or a (nearly) collinear or coincident set, for which
// the rotation about the line is undetermined.
PointRegistration registerPoints(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                                 const std::string& sourceName = "source points", const std::string& targetName = "target points");

// Points read from a CSV file: `x,y,z` or `name,x,y,z` per line.
struct PointList {
  std::string source;                 // the file
  Eigen::Matrix3Xd points;            // 3 x n
  std::vector<std::string> names;     // n names, or empty when the file has none
  std::vector<int> lines;             // n 1-based line numbers, for messages
};

// Reads a point CSV: an optional header line, '#' comment lines and blank lines; then 3 columns
// (x,y,z) or 4 (name,x,y,z) on every line. Throws viscera::Error "file:line: what" for a missing or
// empty file, a wrong column count, a non-number or non-finite value, or a repeated name.
PointList readPointList(const std::string& path);
// Parses the text of a point CSV; `source` names it in messages.
PointList parsePointList(const std::string& text, const std::string& source);

// Pairs two lists: by name when both have names (every name must be in both; the order is the
// source's), by order when neither has. Fills 3 x n matrices and n labels (the names, or "1".."n").
// Throws viscera::Error naming the files for mismatched counts or names, or names in one file only.
void pairPoints(const PointList& source, const PointList& target, Eigen::Matrix3Xd& sourceOut, Eigen::Matrix3Xd& targetOut,
                std::vector<std::string>& labels);

}  // namespace viscera::obs
