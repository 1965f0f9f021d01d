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

// What a cloud file holds besides the points (for `viscera cloud info`).
struct CloudFileInfo {
  // "pcd ascii", "pcd binary", "pcd binary_compressed", "ply ascii", "ply binary_little_endian",
  // "ply binary_big_endian".
  std::string format;
  std::vector<std::string> fields;  // every field of the file in file order, e.g. x y z rgb
  int width = 0, height = 0;        // organized clouds: the image size; unorganized: n x 1
  int nonFinite = 0;                // points dropped because a coordinate or normal was not finite
};

// Reads a .pcd or .ply file (by extension, case-insensitive): x y z, and the normals when the file
// has normal_x normal_y normal_z (or nx ny nz). Any numeric field type is accepted; values are
// converted to double. A point is non-finite when a coordinate, or its normal, is NaN or infinite.
// Throws viscera::Error naming the file for unreadable or malformed files, missing x/y/z fields,
// NaN points (with the first bad point's index), empty clouds. `info`, when given, is filled in.
PointCloud readCloud(const std::string& path, const ReadOptions& options = {}, CloudFileInfo* info = nullptr);
// Writes atomically (.pcd or .ply by extension): points, and normals when present, as float32
// (the precision of both formats as PCL writes them; ASCII with 9 significant digits, so reading
// the file back gives the float-rounded values exactly). Throws viscera::Error for an empty
// cloud, non-finite values or values beyond the float range, or a folder that does not exist.
void writeCloud(const std::string& path, const PointCloud& cloud, CloudEncoding encoding = CloudEncoding::Binary);

// Whether `path` names a cloud file by its extension (.pcd or .ply, case-insensitive).
bool isCloudFileName(const std::string& path);

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
  // Writes one frame at time `time` (seconds); returns its path. Times must increase strictly.
  std::string add(const PointCloud& cloud, double time);
  const std::vector<CloudFrame>& frames() const { return frames_; }

 private:
  std::string folder_, prefix_, extension_;
  CloudEncoding encoding_;
  std::vector<CloudFrame> frames_;
};

}  // namespace viscera::cloud
