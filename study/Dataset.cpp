#include "core/Files.h"
#include "study/Dataset.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/Error.h"
#include "core/Text.h"
#include "io/scene/CsvTable.h"

namespace viscera::study {

namespace fs = std::filesystem;

namespace {

std::string readText(const std::string& path) { return plainText(readInputFile(path)); }

// The number of comma-separated fields on the first line that holds data or a header.
int firstLineFields(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto b = line.find_first_not_of(" \t");
    if (b == std::string::npos || line[b] == '#') continue;
    return static_cast<int>(std::count(line.begin(), line.end(), ',')) + 1;
  }
  return 0;
}

std::string seconds(double t) { return formatNumber(t) + " s"; }

}  // namespace

double Dataset::start() const {
  double s = frames.empty() ? trajectory.start() : frames.front().time;
  if (wrench && wrench->size() > 0) s = std::min(s, wrench->t.front());
  return s;
}

double Dataset::end() const {
  double e = frames.empty() ? trajectory.end() : frames.back().time;
  if (wrench && wrench->size() > 0) e = std::max(e, wrench->t.back());
  return e;
}

WrenchSeries readWrenchCsv(const std::string& path) {
  const std::string text = readText(path);
  const int fields = firstLineFields(text);
  if (fields != 4 && fields != 7)
    throw Error(SourceLoc{path, 1}, "a wrench table has 4 columns (t,fx,fy,fz) or 7 (t,fx,fy,fz,tx,ty,tz), not " +
                                        std::to_string(fields));
  std::vector<std::string> names = {"t", "fx", "fy", "fz"};
  if (fields == 7) names.insert(names.end(), {"tx", "ty", "tz"});
  const io::NumericCsv csv = io::parseNumericCsv(text, path, names);
  WrenchSeries w;
  w.source = path;
  w.hasTorque = fields == 7;
  for (int r = 0; r < csv.rows(); ++r) {
    const double* v = csv.row(r);
    if (!w.t.empty() && !(v[0] > w.t.back()))
      throw Error(SourceLoc{path, csv.lines[r]}, "time " + seconds(v[0]) + " does not increase (the row before is at " +
                                                     seconds(w.t.back()) + ")");
    w.t.push_back(v[0]);
    w.force.emplace_back(v[1], v[2], v[3]);
    w.torque.push_back(w.hasTorque ? Eigen::Vector3d(v[4], v[5], v[6]) : Eigen::Vector3d::Zero());
    w.lines.push_back(csv.lines[r]);
  }
  return w;
}

Dataset readDataset(const std::string& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec))
    throw Error(SourceLoc{folder}, fs::exists(folder, ec) ? "is not a folder (a dataset is a folder)" : "no such dataset folder");
  Dataset d;
  d.folder = folder;
  d.trajectoryPath = (fs::path(folder) / "trajectory.csv").string();
  if (!fs::exists(d.trajectoryPath, ec))
    throw Error(SourceLoc{d.trajectoryPath}, "missing: a dataset needs the instrument's trajectory (t,x,y,z,qx,qy,qz,qw)");
  d.trajectory = motion::readTrajectoryCsv(d.trajectoryPath);

  const fs::path camera = fs::path(folder) / "camera";
  if (!fs::is_directory(camera, ec))
    throw Error(SourceLoc{camera.string()}, "missing: a dataset needs a camera folder with the frames and their index.csv");
  d.frames = cloud::listCloudSequence(camera.string());
  for (size_t k = 0; k < d.frames.size(); ++k) {
    const auto& f = d.frames[k];
    if (!std::isfinite(f.time)) throw Error(SourceLoc{f.path}, "frame time is not finite");
    if (k > 0 && !(f.time > d.frames[k - 1].time))
      throw Error(SourceLoc{(camera / "index.csv").string()},
                  "frame times must increase: " + fs::path(f.path).filename().string() + " at " + seconds(f.time) +
                      " follows " + fs::path(d.frames[k - 1].path).filename().string() + " at " +
                      seconds(d.frames[k - 1].time));
    if (!fs::is_regular_file(f.path, ec)) throw Error(SourceLoc{f.path}, "frame file listed in the index is missing");
  }

  const fs::path transform = fs::path(folder) / "camera_to_scene.txt";
  if (fs::exists(transform, ec)) d.cameraToScene = readTransform(transform.string());
  const fs::path wrench = fs::path(folder) / "wrench.csv";
  if (fs::exists(wrench, ec)) d.wrench = readWrenchCsv(wrench.string());

  const double a = d.trajectory.start(), b = d.trajectory.end();
  int outside = 0;
  for (const auto& f : d.frames) outside += f.time < a || f.time > b;
  if (outside > 0)
    d.notes.push_back(d.trajectoryPath + ": note: " + std::to_string(outside) + " frame" + (outside == 1 ? "" : "s") +
                      " lie outside the trajectory's time span [" + seconds(a) + ", " + seconds(b) +
                      "]; the instrument is held at its first or last pose there");
  return d;
}

std::vector<Eigen::Matrix3Xd> readFrames(const Dataset& data, int maxPoints) {
  std::vector<Eigen::Matrix3Xd> out;
  out.reserve(data.frames.size());
  cloud::ReadOptions ro;
  ro.dropNonFinite = true;
  ro.allowEmpty = true;
  for (const auto& f : data.frames) {
    const cloud::PointCloud c = cloud::readCloud(f.path, ro);
    const long n = c.size();
    const long keep = maxPoints > 0 ? std::min<long>(n, maxPoints) : n;
    Eigen::Matrix3Xd p(3, keep);
    // Evenly through the file order: point floor(i n / keep).
    for (long i = 0; i < keep; ++i) p.col(i) = c.points.col(keep == n ? i : i * n / keep);
    if (data.cameraToScene) p = (*data.cameraToScene * p.colwise().homogeneous()).eval();
    out.push_back(std::move(p));
  }
  return out;
}

DatasetReport checkDataset(const std::string& folder, double maxGap) {
  DatasetReport r;
  Dataset d;
  try {
    d = readDataset(folder);
  } catch (const Error& e) {
    r.problems.push_back(e.what());
    return r;
  }
  for (const auto& n : d.notes) r.warnings.push_back(n);
  const auto& tr = d.trajectory;
  r.lines.push_back("trajectory: " + std::to_string(tr.size()) + " poses from " + seconds(tr.start()) + " to " +
                    seconds(tr.end()));
  double widest = 0, at = tr.start();
  for (int k = 1; k < tr.size(); ++k)
    if (tr.t[k] - tr.t[k - 1] > widest) {
      widest = tr.t[k] - tr.t[k - 1];
      at = tr.t[k - 1];
    }
  if (widest > maxGap)
    r.warnings.push_back(d.trajectoryPath + ": the trajectory has a gap of " + seconds(widest) + " after " + seconds(at) +
                         " (the pose is interpolated linearly across it)");

  // Every frame is read: unreadable, empty or non-finite frames are reported by file.
  long points = 0, minPoints = -1, maxPoints = 0;
  int empty = 0, nonFinite = 0;
  for (const auto& f : d.frames) {
    try {
      cloud::ReadOptions ro;
      ro.dropNonFinite = true;
      ro.allowEmpty = true;
      cloud::CloudFileInfo info;
      const cloud::PointCloud c = cloud::readCloud(f.path, ro, &info);
      if (info.nonFinite > 0) {
        ++nonFinite;
        r.warnings.push_back(f.path + ": " + std::to_string(info.nonFinite) + " non-finite points (left out)");
      }
      if (c.empty()) {
        ++empty;
        r.warnings.push_back(f.path + ": the frame has no points (it scores nothing)");
      }
      points += c.size();
      minPoints = minPoints < 0 ? c.size() : std::min<long>(minPoints, c.size());
      maxPoints = std::max<long>(maxPoints, c.size());
    } catch (const Error& e) {
      r.problems.push_back(e.what());
    }
  }
  const size_t n = d.frames.size();
  std::ostringstream fl;
  fl << "camera: " << n << " frame" << (n == 1 ? "" : "s") << " from " << seconds(d.frames.front().time) << " to "
     << seconds(d.frames.back().time);
  if (n > 1) fl << " (mean rate " << formatNumber((n - 1) / (d.frames.back().time - d.frames.front().time)) << " Hz)";
  if (n > 0 && minPoints >= 0)
    fl << "; points per frame: min " << minPoints << ", mean " << points / static_cast<long>(n) << ", max " << maxPoints;
  r.lines.push_back(fl.str());
  r.lines.push_back(d.cameraToScene ? "camera_to_scene.txt: clouds are in the camera frame and placed by it"
                                    : "no camera_to_scene.txt: clouds are in the scene frame");
  if (d.wrench) {
    const auto& w = *d.wrench;
    double peak = 0;
    for (const auto& f : w.force) peak = std::max(peak, f.norm());
    r.lines.push_back("wrench: " + std::to_string(w.size()) + " samples from " + seconds(w.t.front()) + " to " +
                      seconds(w.t.back()) + (w.hasTorque ? ", force and torque" : ", force only") +
                      "; peak |force| " + formatNumber(peak) + " (scene units)");
    if (w.t.front() < tr.start() || w.t.back() > tr.end())
      r.warnings.push_back(w.source + ": wrench samples lie outside the trajectory's time span");
  } else {
    r.lines.push_back("no wrench.csv: the search scores the clouds only");
  }
  return r;
}

}  // namespace viscera::study
