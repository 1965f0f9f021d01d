// Replaying a measured dataset through a scene and scoring how far the simulation is from it.
//
// The scene's instrument follows the dataset's trajectory; at each frame's time the tissue surface
// (interpolated linearly between the two steps around that time, so frames need not fall on step
// times) is compared with the frame's cloud, and at each wrench sample's time the instrument's
// simulated contact force with the measured one. The score (docs/user-guide.md, "How a candidate
// is scored"):
//   c_k = RMS cloud -> surface distance of frame k / L        (L: length scale, 1 mm by default)
//   g_j = |f_sim(t_j) - f_measured(t_j)| / F                  (F: RMS of the measured |f|)
//   metric = mean_k c_k + mean_j g_j                          (the force term only with a wrench)
// Both terms are dimensionless; metricSe, sqrt(var c / n_c + var g / n_g), is the standard error
// of the metric over frames and samples: its noise floor, what a difference between two candidates
// must exceed to mean something.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/SceneDesc.h"
#include "io/scene/Transform.h"
#include "study/Dataset.h"

namespace viscera::study {

struct ScoreOptions {
  int maxPoints = 2000;  // points scored per frame, chosen evenly through the file (0: all)
  double maxDistance = std::numeric_limits<double>::infinity();  // farther points are left out (scene units)
  double lengthScale = 0;  // L in scene units; 0: 1 mm in the scene's units
  double forceScale = 0;   // F in scene units; 0: the RMS of the measured force magnitude
  bool useWrench = true;   // score the force when the dataset has a wrench
};

// A dataset read once and shared, read-only, by every candidate that replays it.
struct PreparedDataset {
  Dataset data;
  std::vector<Eigen::Matrix3Xd> clouds;  // per frame, in the scene frame, at most maxPoints each
  ScoreOptions score;                    // forceScale filled in from the data when it was 0
  bool scoresWrench() const { return score.useWrench && data.wrench.has_value(); }
};
PreparedDataset prepareDataset(const std::string& folder, const ScoreOptions& options = {});

// The description a dataset is replayed through: the one TrajectoryDriver follows the dataset's
// trajectory (its placement attributes removed: the trajectory is in the scene frame), and the
// scene's outputs (exporters, cameras) are removed. The dataset's clock starts with its
// trajectory's first sample, at the scene's start time: a capture stamped with absolute times
// (1.7e9 s) replays from the start (the driver's timeOffset is set to the difference). Error when
// the scene has no TrajectoryDriver or several.
SceneDesc replayDescription(SceneDesc scene, const Dataset& data);
// Removes a description's outputs: exporters and, with `sensors`, cameras.
void removeOutputs(ElementDesc& root, bool sensors);
// `scene` with its one TrajectoryDriver following the trajectory file `trajectory`, in the scene's
// frame (the driver's transform, rotation and translation removed), at trajectory time = scene
// time + `offset`, and its outputs (exporters, cameras) removed. Error when the scene has no
// TrajectoryDriver or several; `why` says what the trajectory is for.
SceneDesc withTrajectory(SceneDesc scene, const std::string& trajectory, double offset, const std::string& why);

// The mean signed residual (along the outward normal, + outside the tissue) of the cloud points
// whose closest surface point lies on the tissue's top (+z facing), on an x-y grid: where on the
// top the model stands off the measurement, over all the frames scored.
struct TopResidualMap {
  double x0 = 0, y0 = 0, cell = 1;  // scene units: the grid's corner and cell size
  int nx = 0, ny = 0;
  std::vector<double> sum;          // of the signed distances, per cell (x fastest)
  std::vector<int> count;
  // A grid of about `cells` cells along the longer side over [xmin, xmax] x [ymin, ymax].
  static TopResidualMap over(double xmin, double xmax, double ymin, double ymax, int cells = 48);
  TopResidualMap emptyLike() const;  // the same grid, nothing added
  void add(double x, double y, double signedDistance);
  double mean(int i, int j) const;  // NaN where no point fell
};

struct ReplayOptions {
  ScoreOptions score;      // lengthScale 0 is resolved against the scene's units
  int threads = 1;         // worker threads of the run (0: all cores)
  double timeBudget = 0;   // wall-clock seconds before the replay is stopped as a timeout (0: none)
  // Only measurements at dataset times in [from, to] are scored, and the run stops at `to`.
  double from = -std::numeric_limits<double>::infinity(), to = std::numeric_limits<double>::infinity();
  // A rigid correction applied to every cloud (scene frame) before it is scored: the audit's
  // registration effect.
  std::optional<RigidTransform> cloudCorrection;
  // Keep per frame the residuals of each surface region (FrameScore::regions).
  bool regions = false;
  // When set, each scored frame's residuals go to this folder for ParaView: cloud_<k>.vtp (points
  // with distance, residual, signedDistance) and surface_<k>.vtp (the simulated surface with the
  // mean residual per vertex), indexed by cloud.pvd and surface.pvd. The folder must exist.
  std::string residualFolder;
  int residualStride = 1;  // residuals of every residualStride-th scored frame only
  // Keep the simulated surface at every scored frame (ReplayScore::surfaces), for rescore().
  bool keepSurfaces = false;
  // Accumulate ReplayScore::topMap (with `regions`): on this grid when given, else on one over the
  // surface's extent at the first frame scored.
  bool topMap = false;
  std::optional<TopResidualMap> topMapGrid;
};

// Where on the tissue a cloud point lies: by the outward normal of its closest triangle (the
// dominant axis), and whether that closest point is near the instrument (within three radii of
// the sphere's centre).
enum Region { kTop, kBottom, kXMin, kXMax, kYMin, kYMax, kNearInstrument, kAwayFromInstrument, kRegionCount };
const char* regionName(int region);  // "top", "bottom", "x-", "x+", "y-", "y+", "near instrument", "away"

struct RegionResiduals {
  int count = 0;
  double sumSquared = 0;  // of the distances
  double sumSigned = 0;   // of the signed distances along the outward normal (+ outside the tissue)
};

// One frame's or one wrench sample's part of the score.
struct FrameScore {
  double time = 0;
  double value = std::numeric_limits<double>::quiet_NaN();  // RMS distance (frame) or |force error| (sample), scene units
  int points = 0;                                           // points within maxDistance (frames)
  bool contact = false;                                     // the simulated instrument touched the tissue then
  double force = 0;                                         // |simulated contact force| then (scene units)
  std::vector<RegionResiduals> regions;                     // kRegionCount entries with ReplayOptions::regions
};

// The simulated surface at each scored frame of a replay: enough to score the frames again under
// another cloud correction without running the scene again.
struct RecordedSurfaces {
  Eigen::Matrix3Xi triangles;        // over the vertices of every tissue surface, concatenated
  int nodes = 0;
  double lengthScale = 1;            // L the replay resolved (scene units)
  std::vector<size_t> frame;         // dataset frame of each record
  std::vector<Eigen::Matrix3Xd> x;   // the surface's vertices then
  std::vector<Eigen::Vector3d> tip;  // the instrument sphere's centre then
  double tipRadius = 0;              // 0: no instrument sphere
};

struct ReplayScore {
  enum class Status { Ok, Diverged, Timeout };
  Status status = Status::Ok;
  std::string reason;  // why, when not Ok
  static constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  double metric = nan, metricSe = nan, cloudTerm = nan, forceTerm = nan;
  // Mean per-frame RMS distance (scene length units): all frames, frames in contact, frames without.
  double cloudRms = nan, cloudRmsContact = nan, cloudRmsFree = nan;
  // RMS of the force error (scene force units): all samples, in contact, without. NaN without a wrench.
  double forceRms = nan, forceRmsContact = nan, forceRmsFree = nan;
  std::vector<FrameScore> frames, samples;
  int steps = 0;
  double wallSeconds = 0;
  std::shared_ptr<const RecordedSurfaces> surfaces;  // with ReplayOptions::keepSurfaces
  std::optional<TopResidualMap> topMap;               // with ReplayOptions::topMap
  bool ok() const { return status == Status::Ok; }
};
const char* statusName(ReplayScore::Status s);  // "ok", "diverged", "timeout"

// Builds the scene from `desc` (a replay description), runs it over the dataset's time span and
// scores it. Input errors of the scene throw viscera::Error; divergence and timeouts are results.
ReplayScore replay(const SceneDesc& desc, const PreparedDataset& data, const ReplayOptions& options = {});

// Scores the frames of `recorded` (a replay with keepSurfaces) again with options' cloud
// correction, regions and [from, to] window, without running the scene: what a correction of the
// clouds alone (the audit's registration) costs. Wrench samples are kept as they were; residual
// files are written as replay() writes them.
ReplayScore rescore(const ReplayScore& recorded, const PreparedDataset& data, const ReplayOptions& options);

}  // namespace viscera::study
