// `viscera distance`: how far each point of a depth-camera cloud (one file or a sequence) lies from
// the simulated tissue surface, per frame, with obs::CloudDistance. The surface is one mesh, or the
// frames of a simulation's VTK series matched to the clouds by time.
#include "apps/viscera/DistanceCommand.h"
#include "core/Files.h"
#include "apps/viscera/CliText.h"

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/Error.h"
#include "observation/CloudDistance.h"
#include "io/mesh/Exodus.h"
#include "io/mesh/Mesh.h"
#include "io/pointcloud/CloudIo.h"
#include "io/scene/Transform.h"

namespace viscera {
namespace {

using cli::jsonString;

namespace fs = std::filesystem;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct DistanceCommandOptions {
  std::string cloud, mesh, series, transform, method = "vertices", out, residuals, summary;
  int factor = 3;
  std::optional<double> maxDistance, maxTimeGap, time;
  double cloudScale = 1.0, nameTimeScale = 1.0;
  int threads = 0;
  bool dropNan = false, quiet = false;
};

// ---------------------------------------------------------------------------------------------
// The simulated surface: one mesh, or a series of mesh frames

using io::readPvd;
using io::SeriesFrame;

// The triangle surface of a mesh file: the boundary of its tetrahedra (checked), or its triangles.
obs::TriangleList surfaceOf(const io::VolumeMesh& mesh, const std::string& path) {
  if (mesh.tets.cols() > 0) {
    io::checkTetMesh(mesh, path);
    return obs::boundaryTriangles(mesh.tets, mesh.points);
  }
  if (mesh.triangles.cols() > 0) return mesh.triangles;
  throw Error(SourceLoc{path}, "the mesh has neither tetrahedra nor triangles: no surface to measure against");
}

// The surface to measure against, for each cloud frame: the mesh, or the series frame nearest in time.
class SurfaceSource {
 public:
  // A single mesh.
  explicit SurfaceSource(const std::string& meshPath) {
    frames_.push_back({0.0, meshPath});
    io::VolumeMesh mesh = io::readVolumeMesh(meshPath);
    triangles_ = surfaceOf(mesh, meshPath);
    first_ = std::move(mesh);
    loaded_ = 0;
    current_ = first_.points;
  }
  // A series (.pvd of .vtu frames, or one Exodus .exo file); maxGap < 0 selects the default (half
  // the median frame interval).
  SurfaceSource(const std::string& seriesPath, double maxGap) : series_(true), pvd_(seriesPath) {
    if (std::filesystem::path(seriesPath).extension() == ".exo") {
      exodus_ = std::make_unique<io::ExodusReader>(seriesPath);
      if (exodus_->times().empty()) throw Error(SourceLoc{seriesPath}, "the Exodus series has no frames");
      for (size_t i = 0; i < exodus_->times().size(); ++i)
        frames_.push_back({exodus_->times()[i], seriesPath + " frame " + std::to_string(i)});
      first_ = exodus_->mesh();
      first_.points = exodus_->positions(0);
    } else {
      frames_ = readPvd(seriesPath);
      first_ = io::readVolumeMesh(frames_.front().path);
    }
    if (first_.tets.cols() == 0)
      throw Error(SourceLoc{frames_.front().path}, "the series frame has no tetrahedra (export the tissue's node with a force field)");
    triangles_ = surfaceOf(first_, frames_.front().path);
    loaded_ = 0;
    current_ = first_.points;
    if (maxGap >= 0) {
      maxGap_ = maxGap;
    } else if (frames_.size() > 1) {
      std::vector<double> steps;
      for (size_t i = 1; i < frames_.size(); ++i) steps.push_back(frames_[i].time - frames_[i - 1].time);
      std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
      maxGap_ = 0.5 * steps[steps.size() / 2];
    }
  }

  bool series() const { return series_; }
  double maxGap() const { return maxGap_; }
  const obs::TriangleList& triangles() const { return triangles_; }
  int numVertices() const { return static_cast<int>(first_.points.cols()); }

  // The frame for time t (nearest; the earlier one on a tie); throws naming `cloudPath` when it is
  // farther than the allowed gap.
  int frameFor(double t, const std::string& cloudPath) const {
    if (!series_) return 0;
    const auto after = std::lower_bound(frames_.begin(), frames_.end(), t, [](const SeriesFrame& f, double v) { return f.time < v; });
    size_t best = after == frames_.end() ? frames_.size() - 1 : static_cast<size_t>(after - frames_.begin());
    if (best > 0 && std::abs(frames_[best - 1].time - t) <= std::abs(frames_[best].time - t)) --best;
    const double gap = std::abs(frames_[best].time - t);
    if (gap > maxGap_) {
      std::ostringstream msg;
      msg << "cloud time " << t << " s: the nearest frame of " << pvd_ << " is at " << frames_[best].time << " s, " << gap
          << " s away, more than --max-time-gap " << maxGap_ << " s";
      throw Error(SourceLoc{cloudPath}, msg.str());
    }
    return static_cast<int>(best);
  }
  const SeriesFrame& frame(int i) const { return frames_[static_cast<size_t>(i)]; }

  // The vertex positions of frame i (3 x numVertices), read when it is not the last one read.
  const Eigen::Matrix3Xd& positions(int i) {
    if (i == loaded_) return current_;
    if (exodus_) {  // one mesh for every frame
      current_ = exodus_->positions(i);
      loaded_ = i;
      return current_;
    }
    const std::string& path = frames_[static_cast<size_t>(i)].path;
    io::VolumeMesh mesh = io::readVolumeMesh(path);
    if (mesh.points.cols() != first_.points.cols() || mesh.tets.cols() != first_.tets.cols() || mesh.tets != first_.tets)
      throw Error(SourceLoc{path}, "the frame's mesh differs from the series' first frame (" + frames_.front().path +
                                       "): same points and tetrahedra expected");
    current_ = std::move(mesh.points);
    loaded_ = i;
    return current_;
  }

 private:
  bool series_ = false;
  std::string pvd_;
  std::vector<SeriesFrame> frames_;
  std::unique_ptr<io::ExodusReader> exodus_;  // an Exodus series
  io::VolumeMesh first_;
  obs::TriangleList triangles_;
  double maxGap_ = kInf;
  int loaded_ = -1;
  Eigen::Matrix3Xd current_;
};

// ---------------------------------------------------------------------------------------------
// Output

struct FrameRow {
  double time = 0;
  std::string cloud;
  int points = 0;
  obs::DistanceStats stats;
  double meshTime = 0, gap = 0;
};

// A number for CSV and messages: 10 significant digits, "nan" for NaN.
std::string num(double v) {
  if (std::isnan(v)) return "nan";
  std::ostringstream o;
  o << std::setprecision(10) << v;
  return o.str();
}

// A number for JSON: null for NaN or infinity.
std::string jsonNum(double v) { return std::isfinite(v) ? num(v) : "null"; }

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string o = "\"";
  for (char c : s) o += c == '"' ? std::string("\"\"") : std::string(1, c);
  return o + "\"";
}

std::string tableCsv(const std::vector<FrameRow>& rows, bool triangles, bool series) {
  std::ostringstream c;
  c << "frame,time,count,beyond,mean,rms,mean_squared,median,p95,max" << (triangles ? ",signed_mean" : "")
    << (series ? ",mesh_time,time_gap" : "") << ",cloud\n";
  for (size_t i = 0; i < rows.size(); ++i) {
    const FrameRow& r = rows[i];
    const obs::DistanceStats& s = r.stats;
    c << i << "," << num(r.time) << "," << s.count << "," << s.beyond << "," << num(s.mean) << "," << num(s.rms) << ","
      << num(s.meanSquared) << "," << num(s.median) << "," << num(s.p95) << "," << num(s.max);
    if (triangles) c << "," << num(s.signedMean);
    if (series) c << "," << num(r.meshTime) << "," << num(r.gap);
    c << "," << csvField(r.cloud) << "\n";
  }
  return c.str();
}

// Statistics over all frames: pooled over the counted points (each point weighs the same), and
// per frame.
std::string summaryJson(const DistanceCommandOptions& o, const SurfaceSource& surface, const std::vector<FrameRow>& rows) {
  long count = 0, beyond = 0, points = 0;
  double sum = 0, sum2 = 0, signedSum = 0, max = kNaN, maxGap = 0, frameMeanSum = 0;
  int framesWithPoints = 0, worst = -1;
  for (size_t i = 0; i < rows.size(); ++i) {
    const obs::DistanceStats& s = rows[i].stats;
    points += rows[i].points;
    beyond += s.beyond;
    maxGap = std::max(maxGap, rows[i].gap);
    if (s.count == 0) continue;
    count += s.count;
    sum += s.mean * s.count;
    sum2 += s.meanSquared * s.count;
    signedSum += s.signedMean * s.count;
    max = std::isnan(max) ? s.max : std::max(max, s.max);
    frameMeanSum += s.mean;
    ++framesWithPoints;
    if (worst < 0 || s.mean > rows[static_cast<size_t>(worst)].stats.mean) worst = static_cast<int>(i);
  }
  const bool triangles = o.method == "triangles";
  const double n = static_cast<double>(count);
  std::ostringstream j;
  j << "{\n  \"cloud\": " << jsonString(o.cloud) << ",\n";
  j << "  \"surface\": " << jsonString(surface.series() ? o.series : o.mesh) << ",\n";
  j << "  \"transform\": " << (o.transform.empty() ? "null" : jsonString(o.transform)) << ",\n";
  j << "  \"method\": \"" << o.method << "\",\n";
  if (!triangles) j << "  \"factor\": " << o.factor << ",\n";
  j << "  \"max_distance\": " << (o.maxDistance ? jsonNum(*o.maxDistance) : "null") << ",\n";
  j << "  \"frames\": " << rows.size() << ",\n";
  j << "  \"points\": " << points << ",\n";
  j << "  \"counted\": " << count << ",\n";
  j << "  \"beyond\": " << beyond << ",\n";
  j << "  \"mean\": " << jsonNum(count ? sum / n : kNaN) << ",\n";
  j << "  \"rms\": " << jsonNum(count ? std::sqrt(sum2 / n) : kNaN) << ",\n";
  j << "  \"mean_squared\": " << jsonNum(count ? sum2 / n : kNaN) << ",\n";
  j << "  \"max\": " << jsonNum(max) << ",\n";
  if (triangles) j << "  \"signed_mean\": " << jsonNum(count ? signedSum / n : kNaN) << ",\n";
  j << "  \"mean_of_frame_means\": " << jsonNum(framesWithPoints ? frameMeanSum / framesWithPoints : kNaN) << ",\n";
  if (surface.series()) j << "  \"max_time_gap\": " << jsonNum(maxGap) << ",\n";
  j << "  \"worst_frame\": ";
  if (worst < 0) {
    j << "null\n";
  } else {
    const FrameRow& w = rows[static_cast<size_t>(worst)];
    j << "{\"frame\": " << worst << ", \"time\": " << jsonNum(w.time) << ", \"mean\": " << jsonNum(w.stats.mean)
      << ", \"cloud\": " << jsonString(w.cloud) << "}\n";
  }
  j << "}\n";
  return j.str();
}

// The residual files of one run, removed again when the run fails part way.
class ResidualWriter {
 public:
  explicit ResidualWriter(std::string folder) : folder_(std::move(folder)) {
    createdFolder_ = !fs::exists(folder_);
    std::error_code ec;
    fs::create_directories(folder_, ec);
    if (ec) throw Error(SourceLoc{folder_}, "--residuals: cannot create the folder: " + ec.message());
  }
  void add(int frame, double time, const Eigen::Matrix3Xd& cloud, const Eigen::Matrix3Xd& surface,
           const obs::TriangleList& triangles, const obs::DistanceResult& result) {
    char name[32];
    std::snprintf(name, sizeof name, "_%06d.vtp", frame);
    const std::string cloudFile = std::string("cloud") + name, surfaceFile = std::string("surface") + name;
    track(cloudFile);
    obs::writeCloudResiduals((fs::path(folder_) / cloudFile).string(), cloud, result);
    track(surfaceFile);
    obs::writeSurfaceResiduals((fs::path(folder_) / surfaceFile).string(), surface, triangles, result);
    cloudEntries_.push_back({time, cloudFile});
    surfaceEntries_.push_back({time, surfaceFile});
    // Rewritten after every frame, so an interrupted run still opens in ParaView.
    track("cloud.pvd");
    io::writePvd((fs::path(folder_) / "cloud.pvd").string(), cloudEntries_);
    track("surface.pvd");
    io::writePvd((fs::path(folder_) / "surface.pvd").string(), surfaceEntries_);
  }
  // Removes what this run wrote (and the folder, if it made it and nothing else is in it).
  void discard() {
    std::error_code ec;
    for (const auto& f : written_) fs::remove(fs::path(folder_) / f, ec);
    if (createdFolder_ && fs::is_empty(folder_, ec)) fs::remove(folder_, ec);
  }

 private:
  void track(const std::string& file) {
    if (std::find(written_.begin(), written_.end(), file) == written_.end()) written_.push_back(file);
  }
  std::string folder_;
  bool createdFolder_ = false;
  std::vector<std::string> written_;
  std::vector<std::pair<double, std::string>> cloudEntries_, surfaceEntries_;
};

// ---------------------------------------------------------------------------------------------

int runDistance(const DistanceCommandOptions& o) {
  // Every check that needs no cloud file comes first, so bad options or inputs write nothing.
  if (o.mesh.empty() == o.series.empty()) throw Error("distance: give the surface as either --mesh or --series");
  if (o.maxDistance && !(*o.maxDistance > 0)) throw Error("--max-distance: must be a positive distance");
  if (o.maxTimeGap && !(*o.maxTimeGap >= 0)) throw Error("--max-time-gap: must be a time >= 0");
  if (o.maxTimeGap && o.series.empty()) throw Error("--max-time-gap: applies to a --series only");
  if (!(o.cloudScale > 0) || !std::isfinite(o.cloudScale)) throw Error("--cloud-scale: must be a positive number");
  if (o.time && !std::isfinite(*o.time)) throw Error("--time: must be a finite number");
  if (!(o.nameTimeScale > 0) || !std::isfinite(o.nameTimeScale)) throw Error("--name-time-scale: must be a positive number");
  if (!o.out.empty()) cli::requireParentFolder(o.out, "--out");
  if (!o.summary.empty()) cli::requireParentFolder(o.summary, "--summary");
  if (!o.residuals.empty() && fs::exists(o.residuals) && !fs::is_directory(o.residuals))
    throw Error(SourceLoc{o.residuals}, "--residuals: must be a folder, and this is a file");

  std::unique_ptr<tbb::global_control> threads;
  if (o.threads > 0) threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, o.threads);

  Eigen::Isometry3d cameraToScene = Eigen::Isometry3d::Identity();
  if (!o.transform.empty()) cameraToScene = readTransform(o.transform);

  cloud::ReadOptions read;
  read.dropNonFinite = o.dropNan;
  read.allowEmpty = true;  // a frame with no points is a row of NaN statistics, not an error

  // The frames: one cloud file (at --time, else 0) or a sequence.
  std::vector<cloud::CloudFrame> frames;
  std::optional<cloud::PointCloud> single;
  if (!fs::is_directory(o.cloud) && cloud::isCloudFileName(o.cloud)) {
    single = cloud::readCloud(o.cloud, read);
    frames.push_back({o.time.value_or(0.0), o.cloud});
  } else {
    if (o.time) throw Error("--time: applies to a single cloud file only (a sequence has its own times)");
    frames = cloud::listCloudSequence(o.cloud, o.nameTimeScale);
  }

  SurfaceSource surface = o.series.empty() ? SurfaceSource(o.mesh) : SurfaceSource(o.series, o.maxTimeGap.value_or(-1));
  std::vector<int> meshFrame;
  for (const auto& f : frames) meshFrame.push_back(surface.frameFor(f.time, f.path));

  obs::DistanceOptions options;
  options.method = o.method == "triangles" ? obs::DistanceMethod::Triangles : obs::DistanceMethod::Vertices;
  options.factor = o.factor;
  if (o.maxDistance) options.maxDistance = *o.maxDistance;
  obs::CloudDistance distance(surface.triangles(), surface.numVertices(), options);

  std::optional<ResidualWriter> residuals;
  std::vector<FrameRow> rows;
  obs::DistanceResult result;
  int placed = -1;
  try {
    for (size_t i = 0; i < frames.size(); ++i) {
      cloud::PointCloud c = single ? std::move(*single) : cloud::readCloud(frames[i].path, read);
      single.reset();
      // Camera frame -> scene: scale (units), then the rigid transform.
      const Eigen::Matrix3Xd points = cameraToScene * (o.cloudScale * c.points);
      const int m = meshFrame[i];
      if (m != placed) {
        distance.setSurface(surface.positions(m));
        placed = m;
      }
      distance.measure(points, result);
      FrameRow row;
      row.time = frames[i].time;
      row.cloud = frames[i].path;
      row.points = static_cast<int>(points.cols());
      row.stats = result.stats;
      if (surface.series()) {
        row.meshTime = surface.frame(m).time;
        row.gap = std::abs(row.meshTime - row.time);
      }
      if (!o.residuals.empty()) {
        if (!residuals) residuals.emplace(o.residuals);
        residuals->add(static_cast<int>(i), row.time, points, surface.positions(m), surface.triangles(), result);
      }
      if (!o.quiet) {
        const obs::DistanceStats& s = row.stats;
        std::ostringstream line;
        line << std::setprecision(4) << "[" << i + 1 << "/" << frames.size() << "] t = " << row.time << " s  " << s.count
             << " points  mean " << s.mean << "  rms " << s.rms << "  p95 " << s.p95 << "  max " << s.max;
        if (s.beyond > 0) line << "  (" << s.beyond << " beyond --max-distance)";
        if (surface.series()) line << "  mesh t = " << row.meshTime << " s";
        std::cerr << line.str() << "\n";
      }
      rows.push_back(row);
    }
  } catch (const Error&) {
    if (residuals) {
      residuals->discard();
      std::cerr << "distance: stopped at frame " << rows.size() + 1 << " of " << frames.size()
                << "; the residual files written so far were removed\n";
    }
    throw;
  }

  const bool triangles = options.method == obs::DistanceMethod::Triangles;
  if (!o.out.empty()) writeFileAtomic(o.out, tableCsv(rows, triangles, surface.series()));
  if (!o.summary.empty()) writeFileAtomic(o.summary, summaryJson(o, surface, rows));
  if (!o.quiet) {
    long count = 0;
    double sum = 0;
    for (const auto& r : rows)
      if (r.stats.count > 0) count += r.stats.count, sum += r.stats.mean * r.stats.count;
    std::cerr << "measured " << rows.size() << " frame" << (rows.size() == 1 ? "" : "s") << " (" << count
              << " points, method " << o.method << "): mean distance " << num(count ? sum / count : kNaN) << "\n";
  }
  return kExitOk;
}

}  // namespace

void addDistanceCommand(CLI::App& app, std::function<int()>& action) {
  auto o = std::make_shared<DistanceCommandOptions>();
  auto* cmd = app.add_subcommand("distance", "distance from measured point clouds to the simulated surface, per frame");
  cmd->footer(
      "Only the cloud -> surface direction is measured (parts of the surface the camera does not see have no points).\n"
      "Distances are in the mesh's length unit; times in seconds. The table has one row per cloud frame.");
  cmd->add_option("--cloud", o->cloud, "cloud file (.pcd, .ply), sequence folder or index CSV")->required();
  auto* mesh = cmd->add_option("--mesh", o->mesh, "the surface: a mesh file (.vtu, .vtk, .msh, or an .exo series' first frame; tetrahedra or triangles)");
  cmd->add_option("--series", o->series, "the surface per frame: a simulation's .pvd series or Exodus .exo file (the frame nearest each cloud's time)")
      ->excludes(mesh);
  cmd->add_option("--transform", o->transform, "camera -> scene transform file applied to the clouds");
  cmd->add_option("--cloud-scale", o->cloudScale, "multiplies cloud coordinates before the transform (1000: metres to mm)")
      ->capture_default_str();
  cmd->add_option("--method", o->method, "vertices: nearest super-sampled point; triangles: exact point-to-triangle")
      ->check(CLI::IsMember({"vertices", "triangles"}))
      ->capture_default_str();
  cmd->add_option("--factor", o->factor, "super-sampling: subdivisions per triangle edge (vertices method), 1 to 100")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_option("--max-distance", o->maxDistance, "points farther from the surface are counted as beyond and left out of the statistics");
  cmd->add_option("--time", o->time, "time of a single cloud file, s, to pick its --series frame (default 0)");
  cmd->add_option("--max-time-gap", o->maxTimeGap,
                  "largest allowed time between a cloud and its series frame, s (default half the series' frame interval)");
  cmd->add_option("--name-time-scale", o->nameTimeScale,
                  "for a folder without index.csv: seconds per unit of the number in the file names (1e-9 for ns)")
      ->capture_default_str();
  cmd->add_flag("--drop-nan", o->dropNan, "drop non-finite points (missing pixels) instead of rejecting the file");
  cmd->add_option("--out", o->out, "write a CSV table, one row per frame (time, count, mean, rms, median, p95, max, ...)");
  cmd->add_option("--residuals", o->residuals, "write per-frame VTK files (cloud and surface residuals) and .pvd series into this folder");
  cmd->add_option("--summary", o->summary, "write a JSON summary over all frames");
  cmd->add_option("--threads", o->threads, "worker threads (default: all cores; the result does not depend on it)")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--quiet", o->quiet, "no progress lines");
  cmd->callback([o, &action] { action = [o] { return runDistance(*o); }; });
}

}  // namespace viscera
