// Evaluating learned components: a stepper rolled out over recorded rollouts against the FEM, a
// corrector on measured clouds (no LibTorch here: this only calls the models).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "core/Error.h"
#include "observation/SurfaceIndex.h"
#include "learning/nn/Corrector.h"
#include "learning/nn/Stepper.h"

namespace viscera::learning {

namespace {

double meanDistance(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xf& b) {
  return (a - b.cast<double>()).colwise().norm().mean();
}

// Mean distance from the cloud's points to the closest points of the triangles over nodes x.
double meanSurfaceDistance(const Eigen::Matrix3Xf& cloud, const Eigen::Matrix3Xd& x, const obs::TriangleList& triangles) {
  const obs::SurfaceIndex index(x, triangles);
  double sum = 0;
  int hint = -1;
  for (Eigen::Index i = 0; i < cloud.cols(); ++i) {
    const auto hit = index.closest(cloud.col(i).cast<double>(), std::numeric_limits<double>::infinity(), hint);
    hint = hit.triangle;
    sum += std::sqrt(hit.distance2);
  }
  return cloud.cols() ? sum / cloud.cols() : 0.0;
}

}  // namespace

RolloutEvaluation evaluateRollout(const Stepper& model, const std::vector<RolloutFrame>& frames, double segment,
                                  double maxTime) {
  if (!(segment > 0)) throw Error("the evaluation segment must be a positive time");
  RolloutEvaluation ev;
  if (frames.empty()) return ev;
  const Eigen::Matrix3Xd& rest = model.mesh().points;
  Eigen::Matrix3Xd x = frames.front().x.cast<double>();
  const double t0 = frames.front().t;
  double seconds = 0;
  for (size_t f = 0; f < frames.size(); ++f) {
    const RolloutFrame& fr = frames[f];
    if (maxTime > 0 && fr.t - t0 > maxTime + 1e-9) break;
    if (f > 0) {
      const auto w0 = std::chrono::steady_clock::now();
      x = model.step(x, {fr.tip, fr.velocity});
      seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
    }
    ev.time.push_back(fr.t - t0);
    ev.error.push_back(meanDistance(x, fr.x));
    ev.baseline.push_back(meanDistance(rest, fr.x));
  }
  // Segments (k segment, (k+1) segment]; the first frame (the shared start) is left out.
  const size_t n = ev.time.size();
  for (size_t f = 1; f < n;) {
    const int k = static_cast<int>(std::floor((ev.time[f] - 1e-9) / segment));
    SegmentError s;
    s.t0 = k * segment;
    s.t1 = (k + 1) * segment;
    double sum = 0, sum2 = 0, base = 0;
    for (; f < n && ev.time[f] - 1e-9 < s.t1; ++f) {
      sum += ev.error[f];
      sum2 += ev.error[f] * ev.error[f];
      base += ev.baseline[f];
      ++s.frames;
    }
    s.mean = sum / s.frames;
    s.stddev = std::sqrt(std::max(0.0, sum2 / s.frames - s.mean * s.mean));
    s.baselineMean = base / s.frames;
    ev.segments.push_back(s);
  }
  double sum = 0, base = 0;
  for (size_t f = 1; f < n; ++f) sum += ev.error[f], base += ev.baseline[f];
  if (n > 1) ev.mean = sum / (n - 1), ev.baselineMean = base / (n - 1);
  ev.seconds = seconds;
  return ev;
}

std::vector<RolloutEvaluation> evaluateStepper(const Stepper& model, const RolloutSet& data, double segment, double maxTime) {
  model.checkMesh(data.mesh, "the recording " + data.folder);
  if (std::abs(data.frameRate * model.framePeriod() - 1) > 1e-6)
    throw Error(SourceLoc{data.folder}, "the recording has " + std::to_string(data.frameRate) +
                                            " frames per unit time; the model steps " + std::to_string(1 / model.framePeriod()));
  if (data.units != model.units())
    throw Error(SourceLoc{data.folder}, "the recording is in " + data.units + ", the model in " + model.units());
  std::vector<RolloutEvaluation> out;
  for (const std::string& file : data.files) {
    out.push_back(evaluateRollout(model, readRollout(file, static_cast<int>(data.mesh.points.cols())), segment, maxTime));
    out.back().file = file;
  }
  return out;
}

CloudDistance cloudToPoints(const Eigen::Matrix3Xf& cloud, const Eigen::Matrix3Xd& points) {
  CloudDistance d;
  if (cloud.cols() == 0 || points.cols() == 0) return d;
  const Eigen::Matrix3Xf p = points.cast<float>();
  for (Eigen::Index i = 0; i < cloud.cols(); ++i) {
    const float best = (p.colwise() - cloud.col(i)).colwise().squaredNorm().minCoeff();
    d.mean += std::sqrt(best);
    d.meanSquared += best;
  }
  d.mean /= cloud.cols();
  d.meanSquared /= cloud.cols();
  return d;
}

CorrectionEvaluation evaluateCorrector(const Corrector& model, const PairSet& pairs, int maxPoints) {
  model.checkMesh(pairs.mesh, "the pairs " + pairs.folder);
  if (pairs.units != model.units()) throw Error(SourceLoc{pairs.folder}, "the pairs are in " + pairs.units + ", the model in " + model.units());
  CorrectionEvaluation ev;
  const obs::TriangleList triangles = obs::boundaryTriangles(pairs.mesh.tets, pairs.mesh.points);
  double seconds = 0, sumD = 0, sumD2 = 0;
  int counted = 0;
  for (size_t k = 0; k < pairs.states.size(); ++k) {
    const RolloutFrame& f = pairs.states[k];
    Eigen::Matrix3Xf cloud = pairs.clouds[k];
    if (cloud.cols() == 0) continue;
    if (maxPoints > 0 && cloud.cols() > maxPoints) {
      Eigen::Matrix3Xf pick(3, maxPoints);
      for (int i = 0; i < maxPoints; ++i) pick.col(i) = cloud.col(static_cast<Eigen::Index>(i) * cloud.cols() / maxPoints);
      cloud = pick;
    }
    const Eigen::Matrix3Xd x = f.x.cast<double>();
    const auto t0 = std::chrono::steady_clock::now();
    const Eigen::Matrix3Xd corrected = model.correct(x, {f.tip, f.velocity});
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const CloudDistance before = cloudToPoints(cloud, model.refinedSurface(x)), after = cloudToPoints(cloud, model.refinedSurface(corrected));
    ev.surfaceBefore.push_back(meanSurfaceDistance(cloud, x, triangles));
    ev.surfaceAfter.push_back(meanSurfaceDistance(cloud, corrected, triangles));
    ev.time.push_back(f.t);
    ev.before.push_back(before.mean);
    ev.after.push_back(after.mean);
    ev.beforeSquared.push_back(before.meanSquared);
    ev.afterSquared.push_back(after.meanSquared);
    const double d = before.mean - after.mean;
    sumD += d;
    sumD2 += d * d;
    ++counted;
  }
  if (counted == 0) throw Error(SourceLoc{pairs.folder}, "no frame with cloud points to evaluate");
  auto mean = [](const std::vector<double>& v) { double s = 0; for (double x : v) s += x; return s / v.size(); };
  ev.meanBefore = mean(ev.before);
  ev.meanAfter = mean(ev.after);
  ev.meanSquaredBefore = mean(ev.beforeSquared);
  ev.meanSquaredAfter = mean(ev.afterSquared);
  ev.meanSurfaceBefore = mean(ev.surfaceBefore);
  ev.meanSurfaceAfter = mean(ev.surfaceAfter);
  ev.msPerFrame = 1e3 * seconds / counted;
  const double md = sumD / counted;
  ev.improvementSe = counted > 1 ? std::sqrt(std::max(0.0, (sumD2 / counted - md * md) / (counted - 1))) : 0.0;
  return ev;
}

}  // namespace viscera::learning
