// `viscera cloud prep`: preprocess a capture (one cloud file, or a sequence folder / index CSV)
// with prepareCloud and write the result; `viscera cloud info`: describe a cloud file or sequence.
#include "apps/viscera/CloudCommand.h"
#include "core/Files.h"
#include "apps/viscera/CliText.h"

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/pointcloud/CloudIo.h"
#include "io/pointcloud/CloudPrep.h"

namespace viscera {
namespace {

using cli::jsonString;

namespace fs = std::filesystem;
using namespace viscera::cloud;

struct PrepCommandOptions {
  std::string in, out, crop, report, format = "pcd";
  bool noPlane = false, noOutliers = false, dropNan = false, ascii = false, quiet = false;
  double nameTimeScale = 1.0;
  PrepOptions prep;
};

struct InfoCommandOptions {
  std::string in;
  double nameTimeScale = 1.0;
};

// "xmin ymin zmin xmax ymax zmax" (blanks or commas between).
CropBox parseCrop(const std::string& text) {
  const auto v = cli::finiteNumbers(text, "--crop", 6, "xmin ymin zmin xmax ymax zmax");
  return {Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5])};
}

std::string vec3(const Eigen::Vector3d& v) {
  std::ostringstream o;
  o << "(" << v.x() << " " << v.y() << " " << v.z() << ")";
  return o.str();
}

struct FrameResult {
  double time = 0;
  std::string input, output;
  int nonFinite = 0;
  PrepReport report;
};

std::string reportJson(const PrepCommandOptions& o, const std::vector<FrameResult>& frames) {
  const PrepOptions& p = o.prep;
  std::ostringstream j;
  j << std::setprecision(10);
  j << "{\n  \"input\": " << jsonString(o.in) << ",\n  \"output\": " << jsonString(o.out) << ",\n";
  j << "  \"options\": {";
  if (p.crop)
    j << "\"crop\": [" << p.crop->min.x() << ", " << p.crop->min.y() << ", " << p.crop->min.z() << ", " << p.crop->max.x()
      << ", " << p.crop->max.y() << ", " << p.crop->max.z() << "], ";
  j << "\"remove_plane\": " << (p.removePlane ? "true" : "false") << ", \"plane_threshold\": " << p.planeThreshold
    << ", \"plane_iterations\": " << p.planeMaxIterations << ", \"seed\": " << p.seed
    << ", \"remove_outliers\": " << (p.removeOutliers ? "true" : "false") << ", \"outlier_k\": " << p.outlierNeighbours
    << ", \"outlier_std\": " << p.outlierStddev << ", \"cluster_tolerance\": " << p.clusterTolerance
    << ", \"min_cluster\": " << p.minClusterSize << ", \"max_cluster\": " << p.maxClusterSize << ", \"keep_rank\": " << p.keepRank
    << ", \"target\": " << p.targetCount << "},\n";
  j << "  \"frames\": [";
  for (size_t i = 0; i < frames.size(); ++i) {
    const FrameResult& f = frames[i];
    const PrepReport& r = f.report;
    j << (i ? "," : "") << "\n    {\"time\": " << f.time << ", \"input\": " << jsonString(f.input)
      << ", \"output\": " << jsonString(f.output) << ", \"non_finite_dropped\": " << f.nonFinite << ",\n";
    j << "     \"counts\": {\"input\": " << r.input << ", \"crop\": " << r.afterCrop << ", \"plane\": " << r.afterPlane
      << ", \"outliers\": " << r.afterOutliers << ", \"cluster\": " << r.afterCluster << ", \"output\": " << r.output << "},\n";
    j << "     \"plane\": ";
    if (p.removePlane)
      j << "{\"coefficients\": [" << r.plane[0] << ", " << r.plane[1] << ", " << r.plane[2] << ", " << r.plane[3]
        << "], \"inliers\": " << r.planeInliers << "}";
    else
      j << "null";
    j << ",\n     \"clusters\": [";
    for (size_t k = 0; k < r.clusterSizes.size(); ++k) j << (k ? ", " : "") << r.clusterSizes[k];
    j << "], \"kept_rank\": " << r.keptRank << ", \"voxel_leaf\": " << r.voxelLeaf << "}";
  }
  j << "\n  ]\n}\n";
  return j.str();
}

// "scan.pcd: 307200 -> 45000 points (crop 250000, plane 80000, outliers 79000, cluster 2 of 3: 60000)"
std::string summaryLine(const std::string& name, const PrepReport& r) {
  std::ostringstream s;
  s << name << ": " << r.input << " -> " << r.output << " points (crop " << r.afterCrop << ", plane " << r.afterPlane
    << ", outliers " << r.afterOutliers << ", cluster " << r.keptRank << " of " << r.clusterSizes.size() << ": "
    << r.afterCluster << ")";
  return s.str();
}

// Reads and prepares one cloud; the result's output path is left for the caller to fill in.
FrameResult prepareFrame(const PrepCommandOptions& o, const std::string& input, double time, PointCloud& prepared) {
  ReadOptions read;
  read.dropNonFinite = o.dropNan;
  CloudFileInfo info;
  PointCloud cloud = readCloud(input, read, &info);
  cloud.time = time;
  FrameResult f;
  f.time = time;
  f.input = input;
  f.nonFinite = info.nonFinite;
  prepared = prepareCloud(cloud, o.prep, &f.report);
  return f;
}

// Removes the frames a failed sequence run wrote, its index, and the folder when the run made it.
void removeSequenceOutput(const std::string& folder, const std::vector<CloudFrame>& written, bool createdFolder) {
  std::error_code ec;
  for (const auto& f : written) fs::remove(f.path, ec);
  fs::remove(fs::path(folder) / "index.csv", ec);
  if (createdFolder) fs::remove(folder, ec);  // only removes an empty folder
}

int runPrep(PrepCommandOptions o) {
  // Every option is checked before any input is read or output written.
  if (!o.crop.empty()) o.prep.crop = parseCrop(o.crop);
  o.prep.removePlane = !o.noPlane;
  o.prep.removeOutliers = !o.noOutliers;
  validatePrepOptions(o.prep);
  if (o.format != "pcd" && o.format != "ply") throw Error("--format: must be pcd or ply, got '" + o.format + "'");
  if (!(o.nameTimeScale > 0) || !std::isfinite(o.nameTimeScale))
    throw Error("--name-time-scale: must be a positive number");
  if (!o.report.empty()) cli::requireParentFolder(o.report, "--report");
  const CloudEncoding encoding = o.ascii ? CloudEncoding::Ascii : CloudEncoding::Binary;

  std::vector<FrameResult> results;
  const bool single = !fs::is_directory(o.in) && isCloudFileName(o.in);
  if (single) {
    if (!isCloudFileName(o.out))
      throw Error(SourceLoc{o.out}, "the output of a single cloud must be a .pcd or .ply file name");
    cli::requireParentFolder(o.out, "OUT");
    PointCloud prepared;
    FrameResult f = prepareFrame(o, o.in, 0.0, prepared);
    writeCloud(o.out, prepared, encoding);
    f.output = o.out;
    if (!o.quiet) std::cerr << summaryLine(o.in, f.report) << " -> " << o.out << "\n";
    results.push_back(f);
  } else {
    const std::vector<CloudFrame> frames = listCloudSequence(o.in, o.nameTimeScale);
    if (fs::exists(o.out) && !fs::is_directory(o.out))
      throw Error(SourceLoc{o.out}, "the output of a sequence must be a folder, and this is a file");
    // Writing frame_NNNNNN files and index.csv into the input's folder would overwrite the input.
    const bool createdFolder = !fs::exists(o.out);
    for (const auto& f : frames) {
      const fs::path folder = fs::path(f.path).has_parent_path() ? fs::path(f.path).parent_path() : fs::path(".");
      std::error_code ec;
      if (!createdFolder && fs::equivalent(folder, o.out, ec))
        throw Error(SourceLoc{o.out}, "the output folder holds input frames (" + f.path + "); write to another folder");
    }
    CloudSequenceWriter writer(o.out, "frame", o.format, encoding);
    try {
      for (size_t i = 0; i < frames.size(); ++i) {
        PointCloud prepared;
        FrameResult f = prepareFrame(o, frames[i].path, frames[i].time, prepared);
        f.output = writer.add(prepared, frames[i].time);
        if (!o.quiet)
          std::cerr << "[" << i + 1 << "/" << frames.size() << "] t = " << frames[i].time << " s  "
                    << summaryLine(fs::path(f.input).filename().string(), f.report) << "\n";
        results.push_back(f);
      }
    } catch (const Error&) {
      // The sequence is all or nothing: an input error leaves no partial output behind.
      removeSequenceOutput(o.out, writer.frames(), createdFolder);
      std::cerr << "cloud prep: stopped at frame " << results.size() + 1 << " of " << frames.size()
                << "; the frames written so far were removed\n";
      throw;
    }
    if (!o.quiet) std::cerr << "wrote " << frames.size() << " frames and index.csv to " << o.out << "\n";
  }
  if (!o.report.empty()) writeFileAtomic(o.report, reportJson(o, results));
  return kExitOk;
}

// Count, bounds, centroid of a cloud's points, for `info`.
void printGeometry(std::ostream& out, const PointCloud& c) {
  if (c.empty()) {
    out << "bounds    none (no points)\n";
    return;
  }
  const Eigen::Vector3d lo = c.points.rowwise().minCoeff(), hi = c.points.rowwise().maxCoeff();
  out << "bounds    min " << vec3(lo) << "  max " << vec3(hi) << "\n";
  out << "size      " << vec3(hi - lo) << "\n";
  out << "centroid  " << vec3(c.points.rowwise().mean()) << "\n";
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : " ") + x;
  return s;
}

int runInfo(const InfoCommandOptions& o) {
  if (!(o.nameTimeScale > 0) || !std::isfinite(o.nameTimeScale))
    throw Error("--name-time-scale: must be a positive number");
  // Missing pixels and empty frames are described, not rejected.
  ReadOptions read;
  read.dropNonFinite = true;
  read.allowEmpty = true;
  std::ostringstream out;
  out << std::setprecision(6);
  if (!fs::is_directory(o.in) && isCloudFileName(o.in)) {
    CloudFileInfo info;
    const PointCloud c = readCloud(o.in, read, &info);
    out << "file      " << o.in << "\n";
    out << "format    " << info.format;
    if (info.height > 1) out << ", organized " << info.width << " x " << info.height;
    out << "\nfields    " << joined(info.fields) << "\n";
    out << "points    " << c.size();
    if (info.nonFinite) out << " (" << info.nonFinite << " non-finite not counted)";
    out << "\nnormals   " << (c.normals.cols() ? "yes" : "no") << "\n";
    printGeometry(out, c);
    out << "time      none (a single file carries no time stamp; sequences take it from index.csv or the file names)\n";
    std::cout << out.str();
    return kExitOk;
  }
  const std::vector<CloudFrame> frames = listCloudSequence(o.in, o.nameTimeScale);
  const bool indexed = !fs::is_directory(o.in) || fs::exists(fs::path(o.in) / "index.csv");
  out << "sequence  " << o.in << " (" << (indexed ? "times from the index" : "times from the file names") << ")\n";
  out << "frames    " << frames.size() << ", t = " << frames.front().time << " .. " << frames.back().time << " s\n";
  out << std::left << std::setw(7) << "frame" << std::setw(12) << "time" << std::setw(10) << "points" << std::setw(30) << "min"
      << std::setw(30) << "max" << std::setw(30) << "centroid"
      << "file (fields)\n";
  for (size_t i = 0; i < frames.size(); ++i) {
    CloudFileInfo info;
    const PointCloud c = readCloud(frames[i].path, read, &info);
    out << std::setw(7) << i << std::setw(12) << frames[i].time << std::setw(10) << c.size();
    if (c.empty()) {
      out << std::setw(90) << "-";
    } else {
      out << std::setw(30) << vec3(c.points.rowwise().minCoeff()) << std::setw(30) << vec3(c.points.rowwise().maxCoeff())
          << std::setw(30) << vec3(c.points.rowwise().mean());
    }
    out << frames[i].path << " (" << joined(info.fields) << (info.nonFinite ? "; " + std::to_string(info.nonFinite) + " non-finite" : "")
        << ")\n";
  }
  std::cout << out.str();
  return kExitOk;
}

}  // namespace

void addCloudCommand(CLI::App& app, std::function<int()>& action) {
  auto* cloud = app.add_subcommand("cloud", "point-cloud files: preprocess captures, describe files and sequences");
  cloud->require_subcommand(1);

  auto o = std::make_shared<PrepCommandOptions>();
  PrepOptions& p = o->prep;
  auto* prep = cloud->add_subcommand("prep", "crop, remove the table and outliers, keep the specimen's cluster, down-sample");
  prep->footer(
      "IN is a .pcd/.ply file (OUT a file) or a sequence: a folder or its index.csv (OUT a folder of frame_NNNNNN files\n"
      "and an index.csv, with the input times). Distances are in the cloud's units; the defaults assume millimetres.\n"
      "Stages in order: crop, plane (RANSAC), statistical outliers, Euclidean clusters (keep one by size rank), voxel\n"
      "down-sampling to the target count.");
  prep->add_option("IN", o->in, "cloud file, sequence folder or index CSV")->required();
  prep->add_option("OUT", o->out, "output cloud file (for a file) or folder (for a sequence)")->required();
  prep->add_option("--crop", o->crop, "keep only points in the box \"xmin ymin zmin xmax ymax zmax\" (first stage)");
  prep->add_option("--plane-threshold", p.planeThreshold, "distance from the table plane within which points are removed")
      ->capture_default_str();
  prep->add_option("--plane-iterations", p.planeMaxIterations, "RANSAC iterations at most")->capture_default_str();
  prep->add_flag("--no-plane", o->noPlane, "keep the table plane (no RANSAC plane removal)");
  prep->add_option("--seed", p.seed, "RANSAC random seed; the same seed gives the same result")->capture_default_str();
  prep->add_option("--outlier-k", p.outlierNeighbours, "neighbours for the statistical outlier removal")->capture_default_str();
  prep->add_option("--outlier-std", p.outlierStddev, "remove points whose mean neighbour distance exceeds the mean by this many standard deviations")
      ->capture_default_str();
  prep->add_flag("--no-outliers", o->noOutliers, "no statistical outlier removal");
  prep->add_option("--cluster-tolerance", p.clusterTolerance, "points closer than this are in the same cluster")
      ->capture_default_str();
  prep->add_option("--min-cluster", p.minClusterSize, "clusters with fewer points are dropped")->capture_default_str();
  prep->add_option("--max-cluster", p.maxClusterSize, "clusters with more points are dropped (default: no limit)");
  prep->add_option("--keep-rank", p.keepRank,
                   "keep the cluster of this size rank (1 = largest; the table-included pipeline of the dissertation is "
                   "--no-plane --keep-rank 2)")
      ->capture_default_str();
  prep->add_option("--target", p.targetCount, "down-sample to at most this many points by a voxel grid (0: keep all)")
      ->capture_default_str();
  prep->add_flag("--drop-nan", o->dropNan, "drop non-finite points (missing pixels) instead of rejecting the file");
  prep->add_option("--report", o->report, "write a JSON report: counts after each stage, plane, clusters, per frame");
  prep->add_flag("--ascii", o->ascii, "write ASCII files (default binary)");
  prep->add_option("--format", o->format, "frame file format of an output sequence: pcd or ply")->capture_default_str();
  prep->add_option("--name-time-scale", o->nameTimeScale,
                   "for a folder without index.csv: seconds per unit of the number in the file names (1e-9 for ns)")
      ->capture_default_str();
  prep->add_flag("--quiet", o->quiet, "no progress lines");
  prep->callback([o, &action] { action = [o] { return runPrep(*o); }; });

  auto io = std::make_shared<InfoCommandOptions>();
  auto* info = cloud->add_subcommand("info", "describe a cloud file (format, fields, count, bounds, centroid) or each frame of a sequence");
  info->add_option("IN", io->in, "cloud file, sequence folder or index CSV")->required();
  info->add_option("--name-time-scale", io->nameTimeScale,
                   "for a folder without index.csv: seconds per unit of the number in the file names (1e-9 for ns)")
      ->capture_default_str();
  info->callback([io, &action] { action = [io] { return runInfo(*io); }; });
}

}  // namespace viscera
