// The PCL-backed functions of io/pointcloud for a build without PCL (VISCERA_WITH_PCL=OFF): each
// reports that it needs PCL. The rest of the module (sequences, index files, down-sampling) works
// without it.
#include <string>

#include "core/Error.h"
#include "io/pointcloud/CloudIo.h"
#include "io/pointcloud/CloudPrep.h"

namespace viscera::cloud {
namespace {

[[noreturn]] void needsPcl(const std::string& what, const std::string& file) {
  throw Error(SourceLoc{file}, what + " needs PCL: this build was configured with VISCERA_WITH_PCL=OFF");
}

}  // namespace

PointCloud readCloud(const std::string& path, const ReadOptions&, CloudFileInfo*) { needsPcl("reading a point-cloud file", path); }

void writeCloud(const std::string& path, const PointCloud&, CloudEncoding) { needsPcl("writing a point-cloud file", path); }

PointCloud prepareCloud(const PointCloud& cloud, const PrepOptions&, PrepReport*) {
  needsPcl("preparing a point cloud (plane, outlier and cluster filters)", cloud.source);
}

double planeFitNoise(const PointCloud& cloud, int, int, NoiseNeighbours) { needsPcl("estimating the noise of a cloud", cloud.source); }

}  // namespace viscera::cloud
