// Measured datasets: what a search, an audit or a learned component compares a simulation with.
// A dataset is a folder (docs/user-guide.md, "Datasets"):
//   trajectory.csv          instrument pose, t,x,y,z,qx,qy,qz,qw (s; scene frame and units)
//   camera/index.csv        time,file: one row per frame (s), frames .pcd or .ply, camera frame
//   camera_to_scene.txt     4x4 camera -> scene transform (absent: clouds in the scene frame)
//   wrench.csv              optional: t,fx,fy,fz[,tx,ty,tz], force of the tissue on the instrument
//   README.txt/dataset.json optional notes
// Datasets come from other tools too, so everything is read as outside data: frame times need not
// fall on step times, the trajectory may be sampled at any rate, clouds may be PCD (ASCII, binary,
// binary_compressed) or PLY.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "io/pointcloud/CloudIo.h"
#include "io/scene/Transform.h"
#include "motion/Trajectory.h"

namespace viscera::study {

// The measured wrench on the instrument, one sample per row.
struct WrenchSeries {
  std::string source;
  std::vector<double> t;
  std::vector<Eigen::Vector3d> force, torque;  // torque is zero when the file has no torque columns
  bool hasTorque = false;
  std::vector<int> lines;  // line of each sample in the file

  int size() const { return static_cast<int>(t.size()); }
};

struct Dataset {
  std::string folder;
  std::string trajectoryPath;                 // folder/trajectory.csv
  motion::Trajectory trajectory;
  std::vector<cloud::CloudFrame> frames;      // camera/index.csv (or the frame file names), time order
  std::optional<RigidTransform> cameraToScene;
  std::optional<WrenchSeries> wrench;
  std::vector<std::string> notes;             // oddities that are not errors (e.g. a frame outside the trajectory)

  // The time span of the measurements: from the first to the last frame or wrench sample (the
  // instrument is held at its first or last pose outside the trajectory's span).
  double start() const;
  double end() const;
};

// Reads a dataset folder: the trajectory, the frame list and the transform; frames are listed,
// not read (readFrames reads them). Throws viscera::Error naming the file (and line) for a missing
// or malformed part: no trajectory, no frames, frame times not increasing or not finite, a wrench
// table with the wrong columns or times that do not increase.
Dataset readDataset(const std::string& folder);

// Reads the wrench table (t,fx,fy,fz or t,fx,fy,fz,tx,ty,tz; header optional).
WrenchSeries readWrenchCsv(const std::string& path);

// The frames' clouds in the scene frame (the transform applied), in frame order. Non-finite
// points are dropped; an empty frame is kept (it scores nothing). `maxPoints` > 0 keeps at most
// that many points of each frame, chosen evenly through the file order (deterministic: the same
// points for every candidate).
std::vector<Eigen::Matrix3Xd> readFrames(const Dataset& data, int maxPoints = 0);

// What `viscera dataset check` reports: the parts found and every problem, each naming its file.
struct DatasetReport {
  std::vector<std::string> lines;     // summary, one fact per line
  std::vector<std::string> problems;  // errors: the dataset cannot be used as it is
  std::vector<std::string> warnings;  // usable, but worth a look
  bool ok() const { return problems.empty(); }
};

// Validates a dataset completely: reads every frame (empty, NaN, unreadable), checks the times
// (frames out of order, outside the trajectory, gaps in the trajectory longer than `maxGap`
// seconds), the wrench table and the transform.
DatasetReport checkDataset(const std::string& folder, double maxGap = 0.5);

}  // namespace viscera::study
