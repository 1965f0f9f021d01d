#include "study/Replay.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <memory>

#include "builtin/Builtins.h"
#include "core/Attributes.h"
#include "core/Error.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "core/Units.h"
#include "engine/Run.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/mesh/Mesh.h"
#include "observation/CloudDistance.h"
#include "observation/Tissue.h"

namespace viscera::study {

namespace fs = std::filesystem;

TopResidualMap TopResidualMap::over(double xmin, double xmax, double ymin, double ymax, int cells) {
  TopResidualMap m;
  m.x0 = xmin;
  m.y0 = ymin;
  const double extent = std::max(xmax - xmin, ymax - ymin);
  m.cell = extent > 0 ? extent / cells : 1.0;
  m.nx = std::max(1, static_cast<int>(std::ceil((xmax - xmin) / m.cell)));
  m.ny = std::max(1, static_cast<int>(std::ceil((ymax - ymin) / m.cell)));
  return m.emptyLike();
}

TopResidualMap TopResidualMap::emptyLike() const {
  TopResidualMap m = *this;
  m.sum.assign(static_cast<size_t>(nx) * ny, 0.0);
  m.count.assign(static_cast<size_t>(nx) * ny, 0);
  return m;
}

void TopResidualMap::add(double x, double y, double signedDistance) {
  const int i = static_cast<int>(std::floor((x - x0) / cell)), j = static_cast<int>(std::floor((y - y0) / cell));
  if (i < 0 || j < 0 || i >= nx || j >= ny) return;
  sum[static_cast<size_t>(j) * nx + i] += signedDistance;
  count[static_cast<size_t>(j) * nx + i] += 1;
}

double TopResidualMap::mean(int i, int j) const {
  const size_t k = static_cast<size_t>(j) * nx + i;
  return count[k] > 0 ? sum[k] / count[k] : std::numeric_limits<double>::quiet_NaN();
}

namespace {

const char* const kDriverTag = "TrajectoryDriver";

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

void collectDrivers(ElementDesc& el, std::vector<ElementDesc*>& out) {
  const ComponentSpec* s = builtinRegistry().find(el.tag);
  if (s && s->name == kDriverTag) out.push_back(&el);
  for (auto& c : el.children) collectDrivers(c, out);
}

// Exporters and cameras write files; a candidate only scores.
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

// Measures frames against a simulated surface: the cloud (corrected when asked) to the surface's
// triangles, and the residuals per region. Shared by a replay and by rescore().
class FrameMeasure {
 public:
  FrameMeasure(const obs::TriangleList& triangles, int nodes, const PreparedDataset& data, const ReplayOptions& o)
      : data_(data), options_(o) {
    obs::DistanceOptions d;
    d.method = obs::DistanceMethod::Triangles;
    d.maxDistance = o.score.maxDistance;
    distance_ = std::make_unique<obs::CloudDistance>(triangles, nodes, d);
  }
  // Fills fs.points, fs.value and (with options.regions) fs.regions for dataset frame k against
  // surface vertices x; `tip` is the instrument sphere's centre then (tipRadius 0: none).
  // Returns the cloud measured (nullptr when empty).
  const Eigen::Matrix3Xd* measure(FrameScore& fs, size_t k, const Eigen::Matrix3Xd& x, const Eigen::Vector3d& tip,
                                  double tipRadius) {
    const Eigen::Matrix3Xd* cloud = &data_.clouds[k];
    if (options_.cloudCorrection) {
      corrected_ = *options_.cloudCorrection * cloud->colwise().homogeneous();
      cloud = &corrected_;
    }
    if (cloud->cols() == 0) return nullptr;
    distance_->setSurface(x);
    distance_->measure(*cloud, result_);
    fs.points = result_.stats.count;
    if (fs.points > 0) fs.value = result_.stats.rms;
    if (options_.regions) {
      if (options_.topMap && !map_) {
        if (options_.topMapGrid) {
          map_ = options_.topMapGrid->emptyLike();
        } else {
          const Eigen::Vector3d lo = x.rowwise().minCoeff(), hi = x.rowwise().maxCoeff();
          map_ = TopResidualMap::over(lo.x(), hi.x(), lo.y(), hi.y());
        }
      }
      fs.regions = regions(x, *cloud, tip, tipRadius);
    }
    if (!options_.residualFolder.empty() && measured_++ % std::max(1, options_.residualStride) == 0)
      writeResiduals(k, fs.time, x, *cloud);
    return cloud;
  }
  const std::optional<TopResidualMap>& topMap() const { return map_; }

 private:
  void writeResiduals(size_t k, double t, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& cloud) {
    char name[32];
    std::snprintf(name, sizeof name, "_%06zu.vtp", k);
    const fs::path dir = options_.residualFolder;
    obs::writeCloudResiduals((dir / ("cloud" + std::string(name))).string(), cloud, result_);
    obs::writeSurfaceResiduals((dir / ("surface" + std::string(name))).string(), x, distance_->triangles(), result_);
    cloudFiles_.push_back({t, "cloud" + std::string(name)});
    surfaceFiles_.push_back({t, "surface" + std::string(name)});
    io::writePvd((dir / "cloud.pvd").string(), cloudFiles_);
    io::writePvd((dir / "surface.pvd").string(), surfaceFiles_);
  }

  // The frame's residuals per region (result_ holds its distances).
  std::vector<RegionResiduals> regions(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& cloud, const Eigen::Vector3d& tip,
                                       double tipRadius) {
    std::vector<RegionResiduals> out(kRegionCount);
    const auto& tris = distance_->triangles();
    for (Eigen::Index i = 0; i < cloud.cols(); ++i) {
      if (!result_.within[static_cast<size_t>(i)]) continue;
      const int t = result_.nearest[static_cast<size_t>(i)];
      const Eigen::Vector3d n =
          (x.col(tris(1, t)) - x.col(tris(0, t))).cross(x.col(tris(2, t)) - x.col(tris(0, t)));
      int axis = 0;
      n.cwiseAbs().maxCoeff(&axis);
      const int face = axis == 2 ? (n.z() > 0 ? kTop : kBottom) : axis == 0 ? (n.x() > 0 ? kXMax : kXMin) : (n.y() > 0 ? kYMax : kYMin);
      const Eigen::Vector3d closest = cloud.col(i) + result_.residual.col(i);
      const bool near = tipRadius > 0 && (closest - tip).norm() < 3 * tipRadius;
      const double d = result_.distance[static_cast<size_t>(i)], sd = result_.signedDistance[static_cast<size_t>(i)];
      if (face == kTop && map_) map_->add(closest.x(), closest.y(), sd);
      for (int r : {face, static_cast<int>(near ? kNearInstrument : kAwayFromInstrument)}) {
        out[r].count += 1;
        out[r].sumSquared += d * d;
        out[r].sumSigned += sd;
      }
    }
    return out;
  }

  const PreparedDataset& data_;
  const ReplayOptions& options_;
  std::unique_ptr<obs::CloudDistance> distance_;
  obs::DistanceResult result_;
  Eigen::Matrix3Xd corrected_;
  size_t measured_ = 0;  // frames measured (for residualStride)
  std::optional<TopResidualMap> map_;
  std::vector<std::pair<double, std::string>> cloudFiles_, surfaceFiles_;
};

// Scores a run as it steps: frames and wrench samples whose time falls in a step are measured
// against the state interpolated between the step's start and end.
class Scorer : public RunObserver {
 public:
  Scorer(Scene& scene, const PreparedDataset& data, const ReplayOptions& o, RigidObject* tool, double offset)
      : data_(data), options_(o), tool_(tool), surfaces_(obs::tissueSurfaces(scene)) {
    offset_ = offset;
    if (surfaces_.empty())
      throw Error(SourceLoc{scene.file()}, "the scene has no deformable body with tetrahedra to compare the clouds with");
    int nodes = 0, tris = 0;
    for (const auto& s : surfaces_) {
      nodes += s.state->size();
      tris += static_cast<int>(s.triangles.cols());
    }
    obs::TriangleList all(3, tris);
    int tOff = 0, nOff = 0;
    for (const auto& s : surfaces_) {
      all.middleCols(tOff, s.triangles.cols()) = s.triangles.array() + nOff;
      tOff += static_cast<int>(s.triangles.cols());
      nOff += s.state->size();
    }
    measure_ = std::make_unique<FrameMeasure>(all, nodes, data, o);
    if (o.keepSurfaces) {
      recorded_ = std::make_shared<RecordedSurfaces>();
      recorded_->triangles = all;
      recorded_->nodes = nodes;
      recorded_->lengthScale = o.score.lengthScale;
    }
    prev_.resize(3, nodes);
    cur_.resize(3, nodes);
    deadline_ = o.timeBudget > 0 ? now() + o.timeBudget : 0;
    const auto spheres = scene.all<SphereCollisionModel>();
    if (!spheres.empty()) sphere_ = spheres.front();
  }

  void begin(const Simulation& sim, int) override {
    state_ = &sim.state();
    gather(prev_);
    tPrev_ = sim.time();
    fPrev_ = tool_ ? tool_->live(sim.state()).force : Eigen::Vector3d::Zero();
    // Measurements at or before the start see the initial state.
    while (nextFrame_ < data_.data.frames.size() && frameTime(nextFrame_) <= tPrev_) scoreFrame(prev_, false);
    if (data_.scoresWrench())
      while (nextSample_ < static_cast<size_t>(data_.data.wrench->size()) && sampleTime(nextSample_) <= tPrev_)
        scoreSample(fPrev_, false);
  }

  void step(const Simulation& sim) override {
    const double t = sim.time();
    state_ = &sim.state();
    gather(cur_);
    const bool contact = tool_ && tool_->live(sim.state()).contacts > 0;
    const Eigen::Vector3d f = tool_ ? tool_->live(sim.state()).force : Eigen::Vector3d::Zero();
    force_ = f.norm();
    const double h = t - tPrev_;
    while (nextFrame_ < data_.data.frames.size() && frameTime(nextFrame_) <= t) {
      const double a = h > 0 ? (frameTime(nextFrame_) - tPrev_) / h : 1.0;
      mix_ = (1 - a) * prev_ + a * cur_;
      scoreFrame(mix_, contact);
    }
    if (data_.scoresWrench())
      while (nextSample_ < static_cast<size_t>(data_.data.wrench->size()) && sampleTime(nextSample_) <= t) {
        const double a = h > 0 ? (sampleTime(nextSample_) - tPrev_) / h : 1.0;
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
  std::shared_ptr<RecordedSurfaces> recorded_;
  const std::optional<TopResidualMap>& topMap() const { return measure_->topMap(); }

 private:
  // Measurement times on the scene's clock.
  double frameTime(size_t k) const { return data_.data.frames[k].time - offset_; }
  double sampleTime(size_t j) const { return data_.data.wrench->t[j] - offset_; }

  void gather(Eigen::Matrix3Xd& x) const {
    int off = 0;
    for (const auto& s : surfaces_) {
      x.middleCols(off, s.state->size()) = s.state->x(*state_);
      off += s.state->size();
    }
  }
  void scoreFrame(const Eigen::Matrix3Xd& x, bool contact) {
    const size_t k = nextFrame_++;
    FrameScore fs;
    fs.time = data_.data.frames[k].time;
    if (fs.time < options_.from || fs.time > options_.to) return;
    fs.contact = contact;
    fs.force = force_;
    const Eigen::Vector3d tip = sphere_ ? sphere_->centre(*state_) : Eigen::Vector3d::Zero();
    const double radius = sphere_ ? sphere_->radius() : 0.0;
    measure_->measure(fs, k, x, tip, radius);
    if (recorded_) {
      recorded_->frame.push_back(k);
      recorded_->x.push_back(x);
      recorded_->tip.push_back(tip);
      recorded_->tipRadius = radius;
    }
    frames.push_back(std::move(fs));
  }
  void scoreSample(const Eigen::Vector3d& simulated, bool contact) {
    const size_t j = nextSample_++;
    FrameScore s;
    s.time = data_.data.wrench->t[j];
    if (s.time < options_.from || s.time > options_.to) return;
    s.contact = contact;
    s.force = simulated.norm();
    s.value = (simulated - data_.data.wrench->force[j]).norm();
    samples.push_back(s);
  }
  const PreparedDataset& data_;
  const ReplayOptions& options_;
  RigidObject* tool_;
  std::vector<obs::TissueSurface> surfaces_;
  const State* state_ = nullptr;  // the state of the simulation being scored
  std::unique_ptr<FrameMeasure> measure_;
  Eigen::Matrix3Xd prev_, cur_, mix_;
  const SphereCollisionModel* sphere_ = nullptr;
  double force_ = 0;
  Eigen::Vector3d fPrev_ = Eigen::Vector3d::Zero();
  double tPrev_ = 0, deadline_ = 0;
  size_t nextFrame_ = 0, nextSample_ = 0;
  double offset_ = 0;
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

// The scene's start time (the root's `time`, in its units; 0 when not given).
double sceneStartTime(const SceneDesc& scene) {
  const AttrDesc* t = scene.root.find("time");
  if (!t) return 0;
  const AttrDesc* u = scene.root.find("units");
  AttrValue v;
  try {
    parseAttrText(*Registry::nodeSpec().find("time"), t->value, u ? UnitSystem::parse(u->value) : UnitSystem(), v);
  } catch (const std::invalid_argument& e) {
    throw Error(t->loc, std::string("Node.time: ") + e.what());
  }
  return v.nums.at(0);
}

// Dataset time minus scene time: the dataset's clock starts with its trajectory, which starts
// with the scene, so that a capture stamped with absolute times replays from the scene's start.
double clockOffset(const SceneDesc& scene, const Dataset& data) { return data.trajectory.start() - sceneStartTime(scene); }

// The score's totals from its frames and samples (status Diverged when no frame scored).
void summarise(ReplayScore& s, const PreparedDataset& data, double lengthScale) {
  std::vector<double> c, cAll, cIn, cOut, g;
  for (const auto& f : s.frames) {
    if (!std::isfinite(f.value)) continue;
    c.push_back(f.value / lengthScale);
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
    return;
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
}

}  // namespace

const char* regionName(int region) {
  static const char* const names[] = {"top", "bottom", "x-", "x+", "y-", "y+", "near instrument", "away"};
  return region >= 0 && region < kRegionCount ? names[region] : "?";
}

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

void removeOutputs(ElementDesc& el, bool sensors) {
  auto& c = el.children;
  c.erase(std::remove_if(c.begin(), c.end(),
                         [sensors](const ElementDesc& e) {
                           const ComponentSpec* s = builtinRegistry().find(e.tag);
                           return s && (s->category == "output" || (sensors && s->category == "sensor"));
                         }),
          c.end());
  for (auto& ch : c) removeOutputs(ch, sensors);
}

SceneDesc withTrajectory(SceneDesc scene, const std::string& trajectory, double offset, const std::string& why) {
  std::vector<ElementDesc*> drivers;
  collectDrivers(scene.root, drivers);
  if (drivers.empty())
    throw Error(SourceLoc{scene.file}, std::string("the scene has no ") + kDriverTag + " to follow " + trajectory + " (" + why + ")");
  if (drivers.size() > 1) {
    std::string where;
    for (const ElementDesc* d : drivers) where += (where.empty() ? "" : ", ") + d->loc.str();
    throw Error(SourceLoc{scene.file}, std::string("the scene has ") + std::to_string(drivers.size()) + " " + kDriverTag +
                                           "s (" + where + "); " + why + ", so it needs one");
  }
  ElementDesc& d = *drivers.front();
  auto& a = d.attrs;
  a.erase(std::remove_if(a.begin(), a.end(),
                         [](const AttrDesc& x) {
                           return x.name == "transform" || x.name == "rotation" || x.name == "translation";
                         }),
          a.end());
  d.set("filename", fs::absolute(trajectory).string(), SourceLoc{trajectory});
  char text[40];
  std::snprintf(text, sizeof text, "%.17g", offset);
  d.set("timeOffset", text, SourceLoc{trajectory});
  removeOutputs(scene.root, true);
  return scene;
}

SceneDesc replayDescription(SceneDesc scene, const Dataset& data) {
  const double offset = clockOffset(scene, data);
  return withTrajectory(std::move(scene), data.trajectoryPath, offset, "the instrument must follow the dataset's trajectory");
}

ReplayScore replay(const SceneDesc& desc, const PreparedDataset& data, const ReplayOptions& options) {
  auto scene = buildScene(desc);
  Simulation sim(*scene);
  ReplayOptions o = options;
  if (!(o.score.lengthScale > 0)) o.score.lengthScale = 1e-3 / scene->units().siOf(Dimension::length());
  const double offset = clockOffset(desc, data.data);
  Scorer scorer(*scene, data, o, replayedInstrument(*scene), offset);

  RunOptions ro;
  const double span = std::min(data.data.end(), o.to) - offset - sim.time();
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

  s.surfaces = std::move(scorer.recorded_);
  s.topMap = scorer.topMap();
  summarise(s, data, o.score.lengthScale);
  return s;
}

ReplayScore rescore(const ReplayScore& recorded, const PreparedDataset& data, const ReplayOptions& options) {
  if (!recorded.surfaces) throw std::logic_error("rescore: the replay kept no surfaces (ReplayOptions::keepSurfaces)");
  const RecordedSurfaces& rec = *recorded.surfaces;
  ReplayScore s;
  s.steps = recorded.steps;
  s.surfaces = recorded.surfaces;
  for (const FrameScore& w : recorded.samples)
    if (w.time >= options.from && w.time <= options.to) s.samples.push_back(w);
  FrameMeasure measure(rec.triangles, rec.nodes, data, options);
  for (size_t i = 0; i < rec.frame.size() && i < recorded.frames.size(); ++i) {
    const FrameScore& old = recorded.frames[i];
    if (old.time < options.from || old.time > options.to) continue;
    FrameScore fs;
    fs.time = old.time;
    fs.contact = old.contact;
    fs.force = old.force;
    measure.measure(fs, rec.frame[i], rec.x[i], rec.tip[i], rec.tipRadius);
    s.frames.push_back(std::move(fs));
  }
  s.topMap = measure.topMap();
  summarise(s, data, rec.lengthScale);
  return s;
}

}  // namespace viscera::study
