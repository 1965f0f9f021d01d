#include "study/Replay.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "engine/Run.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "observation/CloudDistance.h"
#include "observation/Tissue.h"

namespace viscera::study {

namespace fs = std::filesystem;

namespace {

const char* const kDriverTag = "TrajectoryDriver";

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

void collectDrivers(ElementDesc& el, std::vector<ElementDesc*>& out) {
  const ComponentSpec* s = builtinRegistry().find(el.tag);
  if (s && s->name == kDriverTag) out.push_back(&el);
  for (auto& c : el.children) collectDrivers(c, out);
}

// Exporters and cameras write files; a candidate only scores.
void dropOutputs(ElementDesc& el) {
  auto& c = el.children;
  c.erase(std::remove_if(c.begin(), c.end(),
                         [](const ElementDesc& e) {
                           const ComponentSpec* s = builtinRegistry().find(e.tag);
                           return s && (s->category == "output" || s->category == "sensor");
                         }),
          c.end());
  for (auto& ch : c) dropOutputs(ch);
}

double mean(const std::vector<double>& v) {
  if (v.empty()) return ReplayScore::nan;
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

// Sample variance / n: the squared standard error of the mean (0 for fewer than two values).
double varianceOfMean(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  const double m = mean(v);
  double s = 0;
  for (double x : v) s += (x - m) * (x - m);
  return s / static_cast<double>(v.size() - 1) / static_cast<double>(v.size());
}

// Scores a run as it steps: frames and wrench samples whose time falls in a step are measured
// against the state interpolated between the step's start and end.
class Scorer : public RunObserver {
 public:
  Scorer(Scene& scene, const PreparedDataset& data, const ReplayOptions& o, RigidObject* tool)
      : data_(data), options_(o), tool_(tool), surfaces_(obs::tissueSurfaces(scene)) {
    if (surfaces_.empty())
      throw Error(SourceLoc{scene.file()}, "the scene has no deformable body with tetrahedra to compare the clouds with");
    int nodes = 0, tris = 0;
    for (const auto& s : surfaces_) {
      nodes += static_cast<int>(s.state->x.cols());
      tris += static_cast<int>(s.triangles.cols());
    }
    obs::TriangleList all(3, tris);
    int tOff = 0, nOff = 0;
    for (const auto& s : surfaces_) {
      all.middleCols(tOff, s.triangles.cols()) = s.triangles.array() + nOff;
      tOff += static_cast<int>(s.triangles.cols());
      nOff += static_cast<int>(s.state->x.cols());
    }
    obs::DistanceOptions d;
    d.method = obs::DistanceMethod::Triangles;
    d.maxDistance = o.score.maxDistance;
    distance_ = std::make_unique<obs::CloudDistance>(all, nodes, d);
    prev_.resize(3, nodes);
    cur_.resize(3, nodes);
    deadline_ = o.timeBudget > 0 ? now() + o.timeBudget : 0;
  }

  void begin(const Simulation& sim, int) override {
    gather(prev_);
    tPrev_ = sim.time();
    fPrev_ = tool_ ? tool_->force : Eigen::Vector3d::Zero();
    // Measurements at or before the start see the initial state.
    while (nextFrame_ < data_.data.frames.size() && data_.data.frames[nextFrame_].time <= tPrev_) scoreFrame(prev_, false);
    if (data_.scoresWrench())
      while (nextSample_ < static_cast<size_t>(data_.data.wrench->size()) && data_.data.wrench->t[nextSample_] <= tPrev_)
        scoreSample(fPrev_, false);
  }

  void step(const Simulation& sim) override {
    const double t = sim.time();
    gather(cur_);
    const bool contact = tool_ && tool_->contacts > 0;
    const Eigen::Vector3d f = tool_ ? tool_->force : Eigen::Vector3d::Zero();
    const double h = t - tPrev_;
    while (nextFrame_ < data_.data.frames.size() && data_.data.frames[nextFrame_].time <= t) {
      const double a = h > 0 ? (data_.data.frames[nextFrame_].time - tPrev_) / h : 1.0;
      mix_ = (1 - a) * prev_ + a * cur_;
      scoreFrame(mix_, contact);
    }
    if (data_.scoresWrench())
      while (nextSample_ < static_cast<size_t>(data_.data.wrench->size()) && data_.data.wrench->t[nextSample_] <= t) {
        const double a = h > 0 ? (data_.data.wrench->t[nextSample_] - tPrev_) / h : 1.0;
        scoreSample((1 - a) * fPrev_ + a * f, contact);
      }
    std::swap(prev_, cur_);
    tPrev_ = t;
    fPrev_ = f;
  }

  std::optional<std::string> stopReason() const override {
    if (deadline_ > 0 && now() > deadline_)
      return "ran past its time budget of " + formatNumber(options_.timeBudget) + " s at t = " + formatNumber(tPrev_) + " s";
    return std::nullopt;
  }

  std::vector<FrameScore> frames, samples;

 private:
  void gather(Eigen::Matrix3Xd& x) const {
    int off = 0;
    for (const auto& s : surfaces_) {
      x.middleCols(off, s.state->x.cols()) = s.state->x;
      off += static_cast<int>(s.state->x.cols());
    }
  }
  void scoreFrame(const Eigen::Matrix3Xd& x, bool contact) {
    const size_t k = nextFrame_++;
    FrameScore fs;
    fs.time = data_.data.frames[k].time;
    fs.contact = contact;
    const Eigen::Matrix3Xd& cloud = data_.clouds[k];
    if (cloud.cols() > 0) {
      distance_->setSurface(x);
      distance_->measure(cloud, result_);
      fs.points = result_.stats.count;
      if (fs.points > 0) fs.value = result_.stats.rms;
    }
    frames.push_back(fs);
  }
  void scoreSample(const Eigen::Vector3d& simulated, bool contact) {
    const size_t j = nextSample_++;
    FrameScore s;
    s.time = data_.data.wrench->t[j];
    s.contact = contact;
    s.value = (simulated - data_.data.wrench->force[j]).norm();
    samples.push_back(s);
  }

  const PreparedDataset& data_;
  const ReplayOptions& options_;
  RigidObject* tool_;
  std::vector<obs::TissueSurface> surfaces_;
  std::unique_ptr<obs::CloudDistance> distance_;
  obs::DistanceResult result_;
  Eigen::Matrix3Xd prev_, cur_, mix_;
  Eigen::Vector3d fPrev_ = Eigen::Vector3d::Zero();
  double tPrev_ = 0, deadline_ = 0;
  size_t nextFrame_ = 0, nextSample_ = 0;
};

// The rigid body the scene's TrajectoryDriver moves.
RigidObject* replayedInstrument(Scene& scene) {
  for (Component* c : scene.all<Component>()) {
    if (c->typeName() != kDriverTag) continue;
    for (RigidObject* r : scene.all<RigidObject>())
      if (&r->node() == &c->node()) return r;
  }
  return nullptr;
}

}  // namespace

const char* statusName(ReplayScore::Status s) {
  switch (s) {
    case ReplayScore::Status::Ok: return "ok";
    case ReplayScore::Status::Diverged: return "diverged";
    case ReplayScore::Status::Timeout: return "timeout";
  }
  return "?";
}

PreparedDataset prepareDataset(const std::string& folder, const ScoreOptions& options) {
  PreparedDataset p;
  p.data = readDataset(folder);
  p.score = options;
  if (options.maxPoints < 0) throw Error("the points scored per frame must be >= 0 (0: all), got " + std::to_string(options.maxPoints));
  p.clouds = readFrames(p.data, options.maxPoints);
  if (p.scoresWrench() && !(p.score.forceScale > 0)) {
    double s = 0;
    for (const auto& f : p.data.wrench->force) s += f.squaredNorm();
    p.score.forceScale = std::sqrt(s / p.data.wrench->size());
    if (!(p.score.forceScale > 0))
      throw Error(SourceLoc{p.data.wrench->source},
                  "the measured force is zero throughout, so it gives no force scale; set one (--force-scale)");
  }
  return p;
}

SceneDesc replayDescription(SceneDesc scene, const Dataset& data) {
  std::vector<ElementDesc*> drivers;
  collectDrivers(scene.root, drivers);
  if (drivers.empty())
    throw Error(SourceLoc{scene.file}, std::string("the scene has no ") + kDriverTag + " to replay " + data.trajectoryPath +
                                           " (the instrument must follow the dataset's trajectory)");
  if (drivers.size() > 1) {
    std::string where;
    for (const ElementDesc* d : drivers) where += (where.empty() ? "" : ", ") + d->loc.str();
    throw Error(SourceLoc{scene.file}, std::string("the scene has ") + std::to_string(drivers.size()) + " " + kDriverTag +
                                           "s (" + where + "); a dataset has one instrument trajectory");
  }
  ElementDesc& d = *drivers.front();
  auto& a = d.attrs;
  a.erase(std::remove_if(a.begin(), a.end(),
                         [](const AttrDesc& x) {
                           return x.name == "transform" || x.name == "rotation" || x.name == "translation" ||
                                  x.name == "timeOffset";
                         }),
          a.end());
  d.set("filename", fs::absolute(data.trajectoryPath).string(), SourceLoc{data.trajectoryPath});
  dropOutputs(scene.root);
  return scene;
}

ReplayScore replay(const SceneDesc& desc, const PreparedDataset& data, const ReplayOptions& options) {
  auto scene = buildScene(desc);
  Simulation sim(*scene);
  ReplayOptions o = options;
  if (!(o.score.lengthScale > 0)) o.score.lengthScale = 1e-3 / scene->units().siOf(Dimension::length());
  Scorer scorer(*scene, data, o, replayedInstrument(*scene));

  RunOptions ro;
  const double span = data.data.end() - sim.time();
  ro.steps = span > 0 ? static_cast<int>(std::ceil(span / scene->dt() - 1e-9)) : 0;
  ro.threads = o.threads;
  ro.recordWrench = false;
  ro.observers.push_back(&scorer);
  const RunResult r = run(sim, ro);

  ReplayScore s;
  s.steps = r.steps;
  s.wallSeconds = r.wallSeconds;
  s.frames = std::move(scorer.frames);
  s.samples = std::move(scorer.samples);
  if (r.failure) {
    s.status = ReplayScore::Status::Diverged;
    s.reason = r.failure->str();
    return s;
  }
  if (r.status == RunResult::Status::Stopped) {
    s.status = ReplayScore::Status::Timeout;
    s.reason = r.stopReason;
    return s;
  }

  std::vector<double> c, cAll, cIn, cOut, g;
  for (const auto& f : s.frames) {
    if (!std::isfinite(f.value)) continue;
    c.push_back(f.value / o.score.lengthScale);
    cAll.push_back(f.value);
    (f.contact ? cIn : cOut).push_back(f.value);
  }
  s.cloudRms = mean(cAll);
  s.cloudRmsContact = mean(cIn);
  s.cloudRmsFree = mean(cOut);
  s.cloudTerm = mean(c);
  if (c.empty()) {
    s.status = ReplayScore::Status::Diverged;
    s.reason = "no frame had a point within the distance cut-off of the simulated surface";
    return s;
  }
  double var = varianceOfMean(c);
  s.metric = s.cloudTerm;
  if (data.scoresWrench() && !s.samples.empty()) {
    double all = 0, in = 0, out = 0;
    int nIn = 0, nOut = 0;
    for (const auto& w : s.samples) {
      g.push_back(w.value / data.score.forceScale);
      all += w.value * w.value;
      (w.contact ? in : out) += w.value * w.value;
      (w.contact ? nIn : nOut) += 1;
    }
    s.forceRms = std::sqrt(all / static_cast<double>(s.samples.size()));
    s.forceRmsContact = nIn ? std::sqrt(in / nIn) : ReplayScore::nan;
    s.forceRmsFree = nOut ? std::sqrt(out / nOut) : ReplayScore::nan;
    s.forceTerm = mean(g);
    s.metric += s.forceTerm;
    var += varianceOfMean(g);
  }
  s.metricSe = std::sqrt(var);
  return s;
}

}  // namespace viscera::study
