// Rolling a learned stepper out over recorded rollouts (no LibTorch here: it only calls the model).
#include <chrono>
#include <cmath>

#include "core/Error.h"
#include "learning/nn/Stepper.h"

namespace viscera::learning {

namespace {

double meanDistance(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xf& b) {
  return (a - b.cast<double>()).colwise().norm().mean();
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
  // Segments [k segment, (k+1) segment); the first frame (the shared start) is left out.
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

}  // namespace viscera::learning
