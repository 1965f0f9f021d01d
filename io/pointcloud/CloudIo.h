// Point-cloud files through PCL: .pcd (ASCII or binary) and .ply, one file per frame, and
// sequences of them with timestamps from an index CSV or from the file names.
#pragma once

#include <string>
#include <vector>

#include "io/pointcloud/PointCloud.h"

namespace viscera::cloud {

enum class CloudEncoding { Binary, Ascii };

struct ReadOptions {
  // Non-finite points (PCL marks missing pixels of organized clouds with NaN) are an error naming
  // the file and point index unless this is set, in which case they are dropped.
  bool dropNonFinite = false;
  // An empty cloud is an error unless this is set.
  bool allowEmpty = false;
};

// Reads a .pcd or .ply file (by extension, case-insensitive). Throws viscera::Error naming the
// file for unreadable or malformed files, missing x/y/z fields, NaN points, empty clouds.
PointCloud readCloud(const std::string& path, const ReadOptions& options = {});
// Writes atomically (.pcd or .ply by extension): points, and normals when present.
void writeCloud(const std::string& path, const PointCloud& cloud, CloudEncoding encoding = CloudEncoding::Binary);

// One frame of a sequence.
struct CloudFrame {
  double time = 0.0;
  std::string path;
};

// The frames of a sequence, in time order. `where` is either
//  - a folder: uses its `index.csv` (columns `time,file`, file relative to the folder) when present;
//    otherwise every .pcd/.ply in it, with the time read from the last number in the file name
//    (`frame_12.5.pcd` -> 12.5 s) multiplied by `nameTimeScale` (1e-9 for nanosecond stamps), or
//  - an index CSV file itself.
// Throws viscera::Error for a missing folder, a folder with no clouds, bad index lines
// (file:line), names without a number, or duplicate times.
std::vector<CloudFrame> listCloudSequence(const std::string& where, double nameTimeScale = 1.0);

// Writes a sequence into a folder: frame files `<prefix>_<index, 6 digits>.<ext>` and an
// `index.csv` (time,file) rewritten atomically after each frame, so an interrupted run leaves a
// consistent sequence.
class CloudSequenceWriter {
 public:
  CloudSequenceWriter(std::string folder, std::string prefix = "frame", std::string extension = "pcd",
                      CloudEncoding encoding = CloudEncoding::Binary);
  // Writes one frame at time `time` (seconds); returns its path.
  std::string add(const PointCloud& cloud, double time);
  const std::vector<CloudFrame>& frames() const { return frames_; }

 private:
  std::string folder_, prefix_, extension_;
  CloudEncoding encoding_;
  std::vector<CloudFrame> frames_;
};

}  // namespace viscera::cloud
