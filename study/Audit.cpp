#include "study/Audit.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <boost/math/distributions/normal.hpp>
#include <boost/math/distributions/students_t.hpp>
#include <boost/math/tools/minima.hpp>
#include <cmath>
#include <filesystem>
#include <future>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <nlopt.hpp>
#include <sstream>
#include <thread>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "engine/collision/Collision.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/pointcloud/CloudPrep.h"
#include "io/scene/SceneWriter.h"
#include "observation/CloudDistance.h"
#include "observation/Tissue.h"

namespace viscera::study {

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
enum Phase { kRest, kLoading, kHolding, kRelease };

double mean(const std::vector<double>& v) {
  if (v.empty()) return kNan;
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}
double variance(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  const double m = mean(v);
  double s = 0;
  for (double x : v) s += (x - m) * (x - m);
  return s / static_cast<double>(v.size() - 1);
}

// The scaled items of a replay's score in a time window: c_k = d_k / L per frame, g_j = e_j / F
// per wrench sample (Replay.h).
struct Items {
  std::vector<double> c, g, mm;  // mm: d_k in millimetres
  std::vector<double> times;     // of the frames in c
  double metric() const { return mean(c) + (g.empty() ? 0.0 : mean(g)); }
  double se() const {
    return std::sqrt((c.empty() ? 0 : variance(c) / c.size()) + (g.empty() ? 0 : variance(g) / g.size()));
  }
  double mmMean() const { return mean(mm); }
};

struct Scales {
  double L = 1, F = 1, mm = 1;  // length scale and force scale (scene units); scene length units per mm
};

Items itemsOf(const ReplayScore& s, double from, double to, const Scales& k, bool wrench) {
  Items it;
  for (const auto& f : s.frames) {
    if (!std::isfinite(f.value) || f.time < from || f.time > to) continue;
    it.c.push_back(f.value / k.L);
    it.mm.push_back(f.value / k.mm);
    it.times.push_back(f.time);
  }
  if (wrench)
    for (const auto& w : s.samples)
      if (w.time >= from && w.time <= to) it.g.push_back(w.value / k.F);
  return it;
}

// One-sided paired test that `after` lowers the metric of `before` (same frames and samples):
// z = mean difference / its standard error, p from Student's t with the frames' degrees of freedom.
double pairedP(const Items& before, const Items& after) {
  if (before.c.size() != after.c.size() || before.g.size() != after.g.size() || before.c.size() < 3) return 1;
  std::vector<double> dc(before.c.size()), dg(before.g.size());
  for (size_t i = 0; i < dc.size(); ++i) dc[i] = before.c[i] - after.c[i];
  for (size_t i = 0; i < dg.size(); ++i) dg[i] = before.g[i] - after.g[i];
  const double d = mean(dc) + (dg.empty() ? 0.0 : mean(dg));
  const double se = std::sqrt(variance(dc) / dc.size() + (dg.empty() ? 0.0 : variance(dg) / dg.size()));
  if (!(se > 0)) return d > 0 ? 0.0 : 1.0;
  boost::math::students_t t(static_cast<double>(dc.size() - 1));
  return boost::math::cdf(boost::math::complement(t, d / se));
}

// The standard error of the difference between two scorings of the same frames and samples.
double pairedSe(const Items& a, const Items& b) {
  if (a.c.size() != b.c.size() || a.g.size() != b.g.size() || a.c.size() < 2) return kNan;
  std::vector<double> dc(a.c.size()), dg(a.g.size());
  for (size_t i = 0; i < dc.size(); ++i) dc[i] = a.c[i] - b.c[i];
  for (size_t i = 0; i < dg.size(); ++i) dg[i] = a.g[i] - b.g[i];
  return std::sqrt(variance(dc) / dc.size() + (dg.size() > 1 ? variance(dg) / dg.size() : 0.0));
}

// The stream ("surface" or "force") that `after` makes materially worse than `before`, or "".
// A one-sided paired test per stream at level alpha, with no correction for the number of
// candidates: the check only ever withholds a confirmation, so erring toward it is the safe side.
// Material: more than 1 % of the stream's mean before, so that a change far below what the report
// shows cannot veto an effect that the other stream needs.
std::string worsenedStream(const Items& before, const Items& after, double alpha) {
  auto worse = [alpha](const std::vector<double>& b, const std::vector<double>& a) {
    if (a.size() != b.size() || a.size() < 3) return false;
    std::vector<double> d(a.size());
    for (size_t i = 0; i < d.size(); ++i) d[i] = a[i] - b[i];
    const double m = mean(d), se = std::sqrt(variance(d) / static_cast<double>(d.size()));
    if (!(m > 0.01 * mean(b))) return false;
    if (!(se > 0)) return true;
    boost::math::students_t t(static_cast<double>(d.size() - 1));
    return boost::math::cdf(boost::math::complement(t, m / se)) < alpha;
  };
  if (worse(before.c, after.c)) return "surface";
  if (worse(before.g, after.g)) return "force";
  return "";
}

// Candidates best first: fits that failed last, then those that make a stream worse, then by
// held-out BIC change.
bool rankedBefore(const EffectFit& a, const EffectFit& b) {
  if ((a.status == "ok") != (b.status == "ok")) return a.status == "ok";
  if (a.worsens.empty() != b.worsens.empty()) return a.worsens.empty();
  return a.deltaBic < b.deltaBic;
}

// BIC of the items as Gaussian residuals with k parameters: n ln(mean square) + k ln n.
double bic(const Items& it, int k) {
  double ss = 0;
  for (double x : it.c) ss += x * x;
  for (double x : it.g) ss += x * x;
  const double n = static_cast<double>(it.c.size() + it.g.size());
  return n > 0 ? n * std::log(ss / n) + k * std::log(n) : 0.0;
}

// A top-surface map in millimetres (`mm`: scene length units per mm).
std::optional<TopResidualMap> inMm(std::optional<TopResidualMap> m, double mm) {
  if (!m) return m;
  m->x0 /= mm;
  m->y0 /= mm;
  m->cell /= mm;
  for (double& v : m->sum) v /= mm;
  return m;
}

int phaseOf(const std::vector<FrameScore>& frames, size_t k, double peak) {
  const FrameScore& f = frames[k];
  if (!f.contact) return kRest;
  const size_t a = k > 0 ? k - 1 : k, b = k + 1 < frames.size() ? k + 1 : k;
  const double dt = frames[b].time - frames[a].time;
  const double rate = dt > 0 ? (frames[b].force - frames[a].force) / dt : 0.0;
  // Holding: the force changes by less than a tenth of its peak per second.
  if (std::abs(rate) < 0.1 * peak) return kHolding;
  return rate > 0 ? kLoading : kRelease;
}

Localisation localise(const ReplayScore& s, const Scales& k, double alpha, double noiseFloorMm) {
  Localisation L;
  L.cells.assign(Localisation::kPhases, std::vector<CellStats>(kRegionCount));
  L.framesPerPhase.assign(Localisation::kPhases, 0);
  double peak = 0;
  for (const auto& f : s.frames) peak = std::max(peak, f.force);
  // Per cell: each frame's mean signed residual (mm), for the test; sums over points.
  std::vector<std::vector<std::vector<double>>> perFrame(Localisation::kPhases, std::vector<std::vector<double>>(kRegionCount));
  std::vector<std::vector<RegionResiduals>> sums(Localisation::kPhases, std::vector<RegionResiduals>(kRegionCount));
  std::vector<double> rms;
  for (size_t i = 0; i < s.frames.size(); ++i) {
    const FrameScore& f = s.frames[i];
    if (!std::isfinite(f.value)) continue;
    const int ph = phaseOf(s.frames, i, peak);
    L.framesPerPhase[ph] += 1;
    rms.push_back(f.value / k.mm);
    L.frameTimes.push_back(f.time);
    L.frameRmsMm.push_back(f.value / k.mm);
    L.framePhases.push_back(ph);
    for (int r = 0; r < static_cast<int>(f.regions.size()); ++r) {
      const RegionResiduals& rr = f.regions[static_cast<size_t>(r)];
      if (rr.count == 0) continue;
      perFrame[ph][r].push_back(rr.sumSigned / rr.count / k.mm);
      sums[ph][r].count += rr.count;
      sums[ph][r].sumSquared += rr.sumSquared;
      sums[ph][r].sumSigned += rr.sumSigned;
    }
  }
  L.meanMm = mean(rms);
  L.p95Mm = rms.empty() ? kNan : obs::percentile(rms, 0.95);
  // The signed residual of a perfect model is not zero (noise pushed past edges, grazing views):
  // the null of each region in a loaded phase is that region at rest (Welch's t-test over frames,
  // Holm-adjusted); a difference must also be worth seeing (half the noise floor). Any cell whose
  // RMS exceeds 1.5 x the noise floor disagrees too, rest included: what no test against rest can
  // see (a static error) still shows against the noise.
  std::vector<std::pair<double, CellStats*>> tests;
  std::vector<std::pair<CellStats*, double>> effect;  // |difference from rest| of each tested cell
  for (int ph = 0; ph < Localisation::kPhases; ++ph)
    for (int r = 0; r < kRegionCount; ++r) {
      CellStats& c = L.cells[ph][r];
      const auto& v = perFrame[ph][r];
      c.frames = static_cast<int>(v.size());
      c.points = sums[ph][r].count;
      if (c.points == 0) continue;
      c.rmsMm = std::sqrt(sums[ph][r].sumSquared / c.points) / k.mm;
      c.meanSignedMm = sums[ph][r].sumSigned / c.points / k.mm;
      c.aboveNoise = noiseFloorMm > 0 && c.rmsMm > 1.5 * noiseFloorMm;
      const auto& rest = perFrame[kRest][r];
      if (ph == kRest || v.size() < 3 || rest.size() < 3) continue;
      const double se = std::sqrt(variance(v) / v.size() + variance(rest) / rest.size());
      const double diff = mean(v) - mean(rest);
      c.vsRestMm = diff;
      double p = 1;
      if (se > 0) {
        // Welch-Satterthwaite degrees of freedom.
        const double a = variance(v) / v.size(), b = variance(rest) / rest.size();
        const double dof = (a + b) * (a + b) / (a * a / (v.size() - 1) + b * b / (rest.size() - 1));
        boost::math::students_t t(std::max(1.0, dof));
        p = 2 * boost::math::cdf(boost::math::complement(t, std::abs(diff) / se));
      } else if (diff != 0) {
        p = 0;
      }
      tests.push_back({p, &c});
    }
  std::sort(tests.begin(), tests.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  double running = 0;
  for (size_t i = 0; i < tests.size(); ++i) {
    running = std::max(running, std::min(1.0, tests[i].first * static_cast<double>(tests.size() - i)));
    tests[i].second->p = running;
  }
  for (auto& row : L.cells)
    for (CellStats& c : row)
      c.significant = c.aboveNoise || (c.p < alpha && std::abs(c.vsRestMm) > 0.5 * noiseFloorMm);
  return L;
}

// How fit() spends its replays.
struct FitMode {
  bool heldOut = true;   // score the fit on the held-out window
  bool screen = false;   // give up unless a step either way improves the training score
  int budget = 0;        // replays at most (0: --max-evals, or 2 n + 7 for n parameters when more)
  bool coarse = false;   // enough to rank: only the effect's coarseParams() move
  const std::vector<double>* startAt = nullptr;  // refine from these values (a coarse fit's)
  const std::vector<double>* hint = nullptr;     // screen toward these values (the last round's fit)
};

class Auditor {
 public:
  Auditor(const PreparedDataset& data, const AuditOptions& o, AuditProgress* progress)
      : data_(data), o_(o), progress_(progress) {}

  AuditReport run(const SceneDesc& scene) {
    AuditReport rep;
    effectKeys();  // an unknown --effects key is an error before anything runs
    const SceneDesc nominal = replayDescription(scene, data_.data);
    AuditScene as = describe(nominal);
    scales_.mm = 1e-3 / as.units.siOf(Dimension::length());
    scales_.L = o_.replay.score.lengthScale > 0 ? o_.replay.score.lengthScale : scales_.mm;
    scales_.F = data_.score.forceScale > 0 ? data_.score.forceScale : 1.0;
    wrench_ = data_.scoresWrench();
    rep.splitTime = data_.data.start() + o_.trainFraction * (data_.data.end() - data_.data.start());
    split_ = rep.splitTime;

    // The depth noise (from the clouds alone) and the nominal replay, side by side with --jobs 2 or more.
    say("nominal: replaying the dataset through the scene; noise: estimating the depth noise from the clouds");
    auto noise = std::async(o_.jobs > 1 ? std::launch::async : std::launch::deferred, [this] { return depthNoise(); });
    ReplayScore base = replayFull(nominal, folder(o_.residualsBefore));
    const auto [floor, floorSe] = noise.get();
    rep.noiseFloorMm = floor / scales_.mm;
    rep.noiseFloorSeMm = floorSe / scales_.mm;
    if (!base.ok()) throw Error(SourceLoc{scene.file}, "the nominal scene does not replay the dataset: " + base.reason);
    rep.before = localise(base, scales_, o_.alpha, rep.noiseFloorMm);
    rep.topBefore = inMm(base.topMap, scales_.mm);
    topGrid_ = base.topMap;
    if (wrench_) {
      double ss = 0;
      int n = 0;
      for (size_t j = 0; j < base.samples.size(); ++j)
        if (!base.samples[j].contact) {
          ss += data_.data.wrench->force[j].squaredNorm();
          ++n;
        }
      if (n > 0) rep.forceNoise = std::sqrt(ss / n);
      forceNoiseSamples_ = n;
    }

    SceneDesc current = nominal;   // what is replayed
    SceneDesc augmented = scene;   // what the user gets: the scene as written, plus the effects
    std::vector<std::string> remaining = effectKeys();
    const AuditScene asNominal = as;
    Items heldBase = itemsOf(base, split_, kInf, scales_, wrench_);
    // What the rounds found: each effect, its parameters on the nominal scene and its values.
    std::vector<const Effect*> foundEffects;
    std::vector<std::vector<EffectParam>> foundParams;
    std::vector<double> foundValues;
    ReplayScore last = base;
    for (int round = 0; round < o_.rounds; ++round) {
      // Candidates are tried while anything stands above the noise; the confirmation test, not
      // this gate, keeps a control from naming an effect.
      const double gap = heldBase.mmMean();
      const bool quiet = atNoise(gap, last, rep, 1.0);
      say("held-out gap " + formatNumber(gap) + " mm against the noise floor " + formatNumber(rep.noiseFloorMm) + " +- " +
          formatNumber(rep.noiseFloorSeMm) + " mm" +
          (std::isfinite(lastForceRatio_) ? "; force error " + formatNumber(lastForceRatio_) + " x its noise" : std::string()) +
          (quiet ? ": at the noise level" : ""));
      if (quiet) break;
      as = describe(current, &last);
      say("round " + std::to_string(round + 1) + ": fitting " + std::to_string(remaining.size()) + " effects");
      AuditRound r = fitAll(current, last, as, remaining, heldBase, round > 0);
      r.heldoutBeforeMm = gap;
      if (r.candidates.empty()) break;
      // An effect flat over its range stays flat when another is added: later rounds skip it.
      for (const EffectFit& c : r.candidates)
        if (c.status == "ok" && !c.identifiable) {
          remaining.erase(std::remove(remaining.begin(), remaining.end(), c.effect), remaining.end());
          if (round + 1 < o_.rounds)
            notes_.push_back("effect '" + c.effect + "' is flat over its range in round " + std::to_string(round + 1) +
                             ": later rounds do not fit it again");
        }
      refineLeaders(r, current, last, as, heldBase);
      for (const EffectFit& c : r.candidates)
        if (c.status == "ok" && !c.screened) lastFit_[c.effect] = c.values;
      // Holm: the smallest p is compared with alpha / m.
      const EffectFit& best = r.candidates.front();
      r.confirmed = best.status == "ok" && best.deltaBic < 0 && best.identifiable && best.worsens.empty() &&
                    best.pValue < o_.alpha / static_cast<double>(r.candidates.size());
      if (r.candidates.size() > 1) {
        r.runnerUp = r.candidates[1].effect;
        r.margin = r.candidates[1].deltaBic - best.deltaBic;
      }
      if (!r.confirmed) {
        r.heldoutAfterMm = gap;
        rep.rounds.push_back(std::move(r));
        break;
      }
      const Effect& e = effect(best.effect);
      r.heldoutAfterMm = best.heldoutMmAfter;
      rep.found.push_back(best.effect);
      remaining.erase(std::remove(remaining.begin(), remaining.end(), best.effect), remaining.end());
      foundEffects.push_back(&e);
      foundParams.push_back(r.candidates.front().params);
      foundValues.insert(foundValues.end(), r.candidates.front().values.begin(), r.candidates.front().values.end());
      rep.rounds.push_back(std::move(r));
      if (foundEffects.size() > 1) refitTogether(foundEffects, foundParams, foundValues, nominal, asNominal);
      // The scene and the clouds' correction with every effect found at its current values.
      current = nominal;
      augmented = scene;
      correction_ = applyFound(foundEffects, foundParams, foundValues, foundEffects.size(), current, asNominal);
      applyFound(foundEffects, foundParams, foundValues, foundEffects.size(), augmented, asNominal);
      if (foundEffects.size() > 1) rep.jointValues = foundValues;
      last = replayFull(current);
      heldBase = itemsOf(last, split_, kInf, scales_, wrench_);
    }
    if (!o_.residualsAfter.empty()) {
      // The augmented scene's residual series: its last replay's recorded surfaces scored again.
      ReplayOptions ro = residualOptions(folder(o_.residualsAfter));
      last = rescore(last, data_, ro);
    }
    rep.after = localise(last, scales_, o_.alpha, rep.noiseFloorMm);
    rep.topAfter = inMm(last.topMap, scales_.mm);
    rep.remainingGapMm = heldBase.mmMean();
    rep.atNoiseLevel = atNoise(rep.remainingGapMm, last, rep, 1.5);
    rep.verdict = rep.found.empty() ? "no missing effect detected" : "effects found";
    rep.augmented = augmented;
    rep.cloudCorrection = correction_;
    rep.notes = notes_;
    return rep;
  }

 private:
  static constexpr double kInf = std::numeric_limits<double>::infinity();

  // A progress line, stamped with the seconds since the audit started.
  void say(const std::string& s) {
    if (!progress_) return;
    char stamp[24];
    std::snprintf(stamp, sizeof stamp, "[%6.1f s] ", std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
    progress_->message(stamp + s);
  }

  std::vector<std::string> effectKeys() const {
    std::vector<std::string> keys;
    for (const auto& e : library_) keys.push_back(e->key());
    if (o_.effects.empty()) return keys;
    for (const auto& k : o_.effects)
      if (std::find(keys.begin(), keys.end(), k) == keys.end()) {
        std::string all;
        for (const auto& x : keys) all += (all.empty() ? "" : ", ") + x;
        throw Error("--effects: '" + k + "' is not an effect of the library (" + all + ")");
      }
    return o_.effects;
  }

  const Effect& effect(const std::string& key) const {
    for (const auto& e : library_)
      if (e->key() == key) return *e;
    throw Error("no effect '" + key + "'");
  }

  // What effects may know of `desc`; `last`, its latest replay, tells where the instrument
  // touched and how the measured force compared.
  AuditScene describe(const SceneDesc& desc, const ReplayScore* last = nullptr) const {
    AuditScene as = describeScene(desc);
    if (last && wrench_) {
      const WrenchSeries& w = *data_.data.wrench;
      for (const FrameScore& s : last->samples) {
        const auto j = std::lower_bound(w.t.begin(), w.t.end(), s.time) - w.t.begin();
        if (!s.contact || j >= w.size()) continue;
        as.touches.push_back({data_.data.trajectory.sample(s.time).p, w.force[static_cast<size_t>(j)].norm() - s.force});
      }
    }
    return as;
  }

  // The clouds' depth noise (scene units): the median over up to eight frames spread through
  // the dataset, each read again at full resolution, in the camera frame when the dataset has one.
  std::pair<double, double> depthNoise() const {
    std::vector<double> v;
    cloud::ReadOptions ro;
    ro.dropNonFinite = true;
    ro.allowEmpty = true;
    const size_t n = data_.data.frames.size();
    for (size_t s = 0; s < std::min<size_t>(8, n); ++s) {
      const size_t k = s * n / std::min<size_t>(8, n);
      const cloud::PointCloud c = cloud::readCloud(data_.data.frames[k].path, ro);
      // Patches wide against the noise (a plane through a patch not much wider than the noise
      // follows the noise and reads low), narrow against the tissue's curvature: a fiftieth of the
      // frame's points, 20 to 200.
      const int neighbours = std::clamp(c.size() / 50, 20, 200);
      const double e = cloud::planeFitNoise(c, neighbours, 2000,
                                            data_.data.cameraToScene ? cloud::NoiseNeighbours::Image
                                                                     : cloud::NoiseNeighbours::Space);
      if (std::isfinite(e)) v.push_back(e);
    }
    if (v.empty()) return {0.0, 0.0};
    std::sort(v.begin(), v.end());
    const double median = v[v.size() / 2];
    // The median's standard error from the spread between frames (MAD, normal consistency).
    std::vector<double> dev;
    for (double x : v) dev.push_back(std::abs(x - median));
    std::sort(dev.begin(), dev.end());
    const double se = v.size() > 1 ? 1.2533 * 1.4826 * dev[dev.size() / 2] / std::sqrt(static_cast<double>(v.size())) : 0.0;
    return {median, se};
  }

  // Applies the found effects to `desc`, all but effect `skip` (skip = count: none skipped), and
  // returns their cloud correction.
  static std::optional<RigidTransform> applyFound(const std::vector<const Effect*>& effects,
                                                  const std::vector<std::vector<EffectParam>>& params,
                                                  const std::vector<double>& values, size_t skip, SceneDesc& desc,
                                                  const AuditScene& as) {
    std::optional<RigidTransform> correction;
    size_t at = 0;
    for (size_t i = 0; i < effects.size(); ++i) {
      const std::vector<double> v(values.begin() + static_cast<long>(at), values.begin() + static_cast<long>(at + params[i].size()));
      at += params[i].size();
      if (i == skip) continue;
      effects[i]->apply(desc, v, as);
      if (auto c = effects[i]->cloudCorrection(v, as)) correction = correction ? *c * *correction : *c;
    }
    return correction;
  }

  // Backfitting: each effect found is refitted alone with the others at their current values, in
  // two passes. An effect fitted before the next was found has absorbed part of it; a joint
  // minimiser over all their parameters stalls on the contact's kinks where these 1-D and small
  // fits do not.
  void refitTogether(const std::vector<const Effect*>& effects, const std::vector<std::vector<EffectParam>>& params,
                     std::vector<double>& values, const SceneDesc& nominal, const AuditScene& as) {
    for (int pass = 0; pass < 2; ++pass) {
      size_t at = 0;
      for (size_t i = 0; i < effects.size(); ++i) {
        say("refit " + effects[i]->key() + " with the others found (pass " + std::to_string(pass + 1) + ")");
        SceneDesc others = nominal;
        correction_ = applyFound(effects, params, values, i, others, as);
        std::vector<EffectParam> start = params[i];
        for (size_t j = 0; j < start.size(); ++j) start[j].nominal = values[at + j];
        FitMode mode;
        mode.heldOut = false;
        const EffectFit f = fit(*effects[i], start, others, as, Items(), nullptr, mode);
        if (f.status == "ok")
          for (size_t j = 0; j < start.size(); ++j) values[at + j] = f.values[j];
        at += start.size();
      }
    }
    correction_.reset();
  }

  // The candidates were fitted coarsely, enough to rank them. The first --jobs of them (at least
  // two, when there are) are refitted from their values within a small bracket, side by side,
  // and ranked again: a refined fit only improves, and a close runner-up gets its chance.
  void refineLeaders(AuditRound& r, const SceneDesc& current, const ReplayScore& recorded, const AuditScene& as,
                     const Items& heldBase) {
    const size_t n = std::min(r.candidates.size(), static_cast<size_t>(std::max(2, o_.jobs)));
    std::vector<size_t> todo;
    for (size_t i = 0; i < n; ++i) {
      const EffectFit& c = r.candidates[i];
      if (c.status == "ok" && !c.screened && c.identifiable && c.deltaBic < 0 && effect(c.effect).changesSimulation())
        todo.push_back(i);
    }
    if (todo.empty()) return;
    std::string names;
    for (size_t i : todo) names += (names.empty() ? "" : ", ") + r.candidates[i].effect;
    say("refine " + names);
    std::vector<EffectFit> refined(todo.size());
    std::vector<std::thread> pool;
    std::exception_ptr failure;
    std::mutex mutex;
    auto work = [&](size_t k) {
      try {
        const EffectFit& c = r.candidates[todo[k]];
        FitMode mode;
        mode.startAt = &c.values;
        // Brent in a small bracket needs few replays; BOBYQA 2 n + 1 for its first model.
        mode.budget = c.params.size() == 1 ? std::max(4, o_.maxEvaluations / 4) : 2 * static_cast<int>(c.params.size()) + 3;
        refined[k] = fit(effect(c.effect), c.params, current, as, heldBase, &recorded, mode);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!failure) failure = std::current_exception();
      }
    };
    for (size_t k = 1; k < todo.size() && static_cast<int>(k) < o_.jobs; ++k) pool.emplace_back(work, k);
    for (size_t k = 0; k < todo.size(); ++k)
      if (k == 0 || static_cast<int>(k) >= o_.jobs) work(k);
    for (auto& t : pool) t.join();
    if (failure) std::rethrow_exception(failure);
    for (size_t k = 0; k < todo.size(); ++k) {
      EffectFit& c = r.candidates[todo[k]];
      if (refined[k].status != "ok" || refined[k].trainAfter > c.trainAfter) continue;
      refined[k].evaluations += c.evaluations;
      c = std::move(refined[k]);
    }
    std::stable_sort(r.candidates.begin(), r.candidates.end(), rankedBefore);
  }

  // A residual folder, created (empty: none).
  static std::string folder(const std::string& path) {
    if (path.empty()) return path;
    std::error_code ec;
    std::filesystem::create_directories(path, ec);
    if (ec) throw Error(SourceLoc{path}, "cannot create the folder: " + ec.message());
    return path;
  }

  // Whether the held-out gaps are within `factor` x their noise: the cloud gap against the depth
  // noise and, with a wrench, the RMS force error against the force measured out of contact.
  bool atNoise(double gapMm, const ReplayScore& last, const AuditReport& rep, double factor) const {
    // The floor is an estimate: a gap within twice its standard error of it is not above it.
    bool cloud = gapMm <= factor * rep.noiseFloorMm + 2 * rep.noiseFloorSeMm;
    bool force = true;
    if (wrench_ && std::isfinite(rep.forceNoise)) {
      double ss = 0;
      int n = 0;
      for (const auto& w : last.samples)
        if (w.time > split_) ss += w.value * w.value, ++n;
      // Both are RMS values of three-component noise over many samples: each has a relative
      // standard error of 1 / sqrt(6 samples), and a ratio within twice theirs is at the noise.
      const double se = n > 0 && forceNoiseSamples_ > 0 ? std::sqrt(1.0 / (6.0 * n) + 1.0 / (6.0 * forceNoiseSamples_)) : 0.0;
      force = n == 0 || std::sqrt(ss / n) <= (factor + 2 * se) * rep.forceNoise;
      if (n > 0) lastForceRatio_ = std::sqrt(ss / n) / rep.forceNoise;
    }
    return cloud && force;
  }

  // A full replay with regions and recorded surfaces, writing its residual series to `residuals`
  // (empty: none), every few frames so that at most --residual-frames are written.
  ReplayScore replayFull(const SceneDesc& desc, const std::string& residuals = "") const {
    ReplayOptions ro = residualOptions(residuals);
    ro.keepSurfaces = true;
    return replay(desc, data_, ro);
  }
  ReplayOptions residualOptions(const std::string& residuals) const {
    ReplayOptions ro = o_.replay;
    ro.regions = true;
    ro.topMap = true;
    ro.topMapGrid = topGrid_;  // after the nominal replay, its grid: before and after side by side
    ro.cloudCorrection = correction_;
    ro.residualFolder = residuals;
    const int frames = static_cast<int>(data_.data.frames.size());
    ro.residualStride = o_.residualFrames > 0 ? std::max(1, (frames + o_.residualFrames - 1) / o_.residualFrames) : 1;
    return ro;
  }

  // An effect's cloud correction after the one the earlier rounds found.
  std::optional<RigidTransform> compose(const std::optional<RigidTransform>& c) const {
    if (!c) return correction_;
    return correction_ ? std::optional<RigidTransform>(*c * *correction_) : c;
  }

  AuditRound fitAll(const SceneDesc& current, const ReplayScore& recorded, const AuditScene& as,
                    std::vector<std::string> keys, const Items& heldBase, bool screen) {
    // The costliest fits first, so that the threads finish together: the most parameters first,
    // those that only rescore the clouds last.
    std::map<std::string, int> cost;
    for (const std::string& k : keys) {
      const Effect& e = effect(k);
      cost[k] = e.changesSimulation() ? static_cast<int>(e.params(as).size()) : 0;
    }
    std::stable_sort(keys.begin(), keys.end(), [&](const std::string& a, const std::string& b) { return cost[a] > cost[b]; });
    std::vector<EffectFit> fits;
    std::mutex mutex;
    std::atomic<size_t> next{0};
    std::exception_ptr failure;
    auto work = [&] {
      for (;;) {
        const size_t i = next++;
        if (i >= keys.size()) return;
        try {
          const Effect& e = effect(keys[i]);
          const auto params = e.params(as);
          if (params.empty()) {
            std::lock_guard<std::mutex> lock(mutex);
            notes_.push_back("effect '" + keys[i] + "' does not apply to this scene");
            continue;
          }
          FitMode mode;
          mode.screen = screen;
          const auto previous = lastFit_.find(e.key());
          if (previous != lastFit_.end()) mode.hint = &previous->second;
          // Coarse: enough to rank the candidates; the leaders are refined (refineLeaders).
          // A line search takes 6 to 8 replays; BOBYQA's first model of n parameters 2 n + 1.
          mode.coarse = true;
          const size_t lines = e.coarseParams().empty() ? params.size() : e.coarseParams().size();
          mode.budget = lines == 1 ? std::max(6, o_.maxEvaluations / 2)
                        : lines < params.size() ? static_cast<int>(lines) * std::max(6, o_.maxEvaluations / 3)
                                                : 2 * static_cast<int>(params.size()) + 3;
          EffectFit f = fit(e, params, current, as, heldBase, &recorded, mode);
          std::lock_guard<std::mutex> lock(mutex);
          say("  " + f.effect + ": " + (f.screened ? std::string("no better near the scene's values") : f.status) + (f.status == "ok" && !f.screened ? ", held-out " + formatNumber(f.heldoutMmBefore) + " -> " +
                                                                           formatNumber(f.heldoutMmAfter) + " mm, p " +
                                                                           formatNumber(f.pValue) +
                                                                           (f.worsens.empty() ? "" : ", worsens the " + f.worsens)
                                                                     : ""));
          fits.push_back(std::move(f));
        } catch (...) {
          std::lock_guard<std::mutex> lock(mutex);
          if (!failure) failure = std::current_exception();
          next = keys.size();
        }
      }
    };
    std::vector<std::thread> pool;
    for (int j = 1; j < std::min<int>(o_.jobs, static_cast<int>(keys.size())); ++j) pool.emplace_back(work);
    work();
    for (auto& t : pool) t.join();
    if (failure) std::rethrow_exception(failure);
    std::sort(fits.begin(), fits.end(), rankedBefore);
    AuditRound r;
    r.candidates = std::move(fits);
    return r;
  }

  // Fits one effect on the training window, then (with `heldOut`) scores the fit on the held-out
  // window. `recorded` is a full replay of `current` that kept its surfaces, and the effect's
  // nominal values leave `current` as it is: it gives the training score at the nominal values
  // without a replay. An effect that only corrects the clouds is scored on such a replay again
  // instead of running the scene (one is run when `recorded` is nullptr).
  EffectFit fit(const Effect& e, const std::vector<EffectParam>& params, const SceneDesc& current, const AuditScene& as,
                const Items& heldBase, const ReplayScore* recorded, const FitMode& mode = {}) const {
    const bool heldOut = mode.heldOut, screen = mode.screen;
    const bool nominalIsCurrent = recorded != nullptr;
    ReplayScore own;
    if (!recorded && !e.changesSimulation()) {
      own = replayFull(current);
      if (!own.ok()) {
        EffectFit f;
        f.effect = e.key();
        f.what = e.what();
        f.params = params;
        f.status = "the scene without this effect failed: " + own.reason;
        return f;
      }
      recorded = &own;
    }
    EffectFit f;
    f.effect = e.key();
    f.what = e.what();
    f.params = params;
    const size_t d = params.size();
    const bool cloudOnly = !e.changesSimulation();
    // A replay is the cost: an effect that only moves the clouds gets many more evaluations.
    const int budget = cloudOnly      ? std::max(3 * o_.maxEvaluations / 2, 2 * static_cast<int>(d) + 9)
                       : mode.budget > 0 ? mode.budget
                                         : std::max(o_.maxEvaluations, d > 1 ? 2 * static_cast<int>(d) + 7 : 0);
    auto toU = [&](size_t j, double v) { return params[j].scale == Scale::Log ? std::log10(v) : v; };
    auto fromU = [&](size_t j, double u) { return params[j].scale == Scale::Log ? std::pow(10.0, u) : u; };
    auto values = [&](const std::vector<double>& s) {
      std::vector<double> v(d);
      for (size_t j = 0; j < d; ++j) {
        const double a = toU(j, params[j].lo), b = toU(j, params[j].hi);
        v[j] = fromU(j, a + std::clamp(s[j], 0.0, 1.0) * (b - a));
      }
      return v;
    };
    std::vector<double> s0(d);
    bool nominalInside = true;
    for (size_t j = 0; j < d; ++j) {
      const double a = toU(j, params[j].lo), b = toU(j, params[j].hi);
      nominalInside = nominalInside && params[j].nominal >= params[j].lo && params[j].nominal <= params[j].hi;
      s0[j] = b > a ? (toU(j, std::clamp(params[j].nominal, params[j].lo, params[j].hi)) - a) / (b - a) : 0.5;
    }
    // The parameters a coarse fit moves, in the order it moves them; a refinement moves them all.
    std::vector<size_t> order = mode.coarse ? e.coarseParams() : std::vector<size_t>();
    if (order.empty())
      for (size_t j = 0; j < d; ++j) order.push_back(j);
    double lo = kInf, hi = -kInf, seTrain = 0;
    std::vector<double> bestS;
    double bestM = kInf;
    struct Seen {
      std::vector<double> s;
      double m;
      Items items;
    };
    std::vector<Seen> seen;  // every point scored
    auto note = [&](const std::vector<double>& s, const Items& it) {
      const double m = it.metric();
      lo = std::min(lo, m);
      hi = std::max(hi, m);
      if (m < bestM) {
        bestM = m;
        bestS = s;
        seTrain = it.se();
      }
      seen.push_back({s, m, it});
      return m;
    };
    auto itemsAt = [&](const std::vector<double>& s) {
      for (const Seen& x : seen)
        if (x.s == s) return x.items;
      return Items();
    };
    const std::string currentText = nominalIsCurrent && !cloudOnly ? io::formatScene(current) : std::string();
    auto evaluate = [&](const std::vector<double>& s) {
      for (const Seen& x : seen)
        if (x.s == s) return x.m;
      const auto v = values(s);
      ReplayOptions ro = o_.replay;
      ro.to = split_;
      ro.cloudCorrection = compose(e.cloudCorrection(v, as));
      ReplayScore sc;
      if (cloudOnly) {
        sc = rescore(*recorded, data_, ro);
      } else {
        SceneDesc desc = current;
        e.apply(desc, v, as);
        // Values that change nothing (an inclusion as stiff as the rest) score as the scene does.
        if (nominalIsCurrent && io::formatScene(desc) == currentText)
          return note(s, itemsOf(*recorded, -kInf, split_, scales_, wrench_));
        ++f.evaluations;
        sc = replay(desc, data_, ro);
      }
      if (!sc.ok()) return 1e30;
      return note(s, itemsOf(sc, -kInf, split_, scales_, wrench_));
    };
    // The nominal values leave the scene as it is: their training score is the recorded one's.
    f.trainBefore = nominalIsCurrent && nominalInside ? note(s0, itemsOf(*recorded, -kInf, split_, scales_, wrench_))
                                                      : evaluate(s0);
    const double base = f.trainBefore;
    bool flat = false;
    if (screen && nominalIsCurrent && !cloudOnly) {
      // Later rounds: a step must lower the training score by more than twice the paired
      // standard error, or the effect is not fitted again. The step goes toward the effect's fit
      // in the previous round when it moved (what it absorbed then is where a remaining effect
      // would show); else a step either way along each parameter.
      const Items baseItems = itemsAt(s0);
      std::vector<std::vector<double>> probes;
      if (mode.hint) {
        std::vector<double> delta(d);
        double span = 0;
        for (size_t j = 0; j < d; ++j) {
          const double a = toU(j, params[j].lo), b = toU(j, params[j].hi);
          const double u = b > a ? (toU(j, std::clamp(mode.hint->at(j), params[j].lo, params[j].hi)) - a) / (b - a) : 0.5;
          delta[j] = u - s0[j];
          span = std::max(span, std::abs(delta[j]));
        }
        if (span > 1e-3) {
          std::vector<double> p(d);
          for (size_t j = 0; j < d; ++j) p[j] = std::clamp(s0[j] + delta[j] * std::min(1.0, 0.15 / span), 0.0, 1.0);
          probes.push_back(p);
        }
      }
      if (probes.empty())
        for (size_t j : order)
          for (double dir : {-1.0, 1.0}) {
            std::vector<double> p = s0;
            p[j] = std::clamp(s0[j] + dir * 0.15, 0.0, 1.0);
            if (p[j] != s0[j]) probes.push_back(p);
          }
      bool better = false;
      for (const auto& p : probes) {
        const double m = evaluate(p);
        if (seen.back().s == p && base - m > 2 * pairedSe(baseItems, seen.back().items)) {
          better = true;
          break;
        }
      }
      if (!better) {
        f.screened = true;
        f.values = values(s0);
        f.trainAfter = base;
        f.identifiable = hi - lo > 2 * seTrain;
        if (!heldOut) return f;
        f.heldoutBefore = f.heldoutAfter = heldBase.metric();
        f.heldoutMmBefore = f.heldoutMmAfter = heldBase.mmMean();
        f.deltaBic = bic(heldBase, static_cast<int>(d)) - bic(heldBase, 0);
        f.pValue = 1;
        return f;
      }
    }
    std::vector<double> from;  // the refinement's start, in [0, 1]
    if (mode.startAt) {
      for (size_t j = 0; j < d; ++j) {
        const double a = toU(j, params[j].lo), b = toU(j, params[j].hi);
        from.push_back(b > a ? (toU(j, std::clamp(mode.startAt->at(j), params[j].lo, params[j].hi)) - a) / (b - a) : 0.5);
      }
    }
    // A search along parameter j from point p (score fp, standard error se), in at most `budget`
    // replays; returns whether the score is flat along it. Probe either side first. Downhill on
    // one side: walk that way by growing steps until the score rises, then Brent inside that
    // bracket. Uphill on both: p is a minimum, refined between the probes. Otherwise (flat near p,
    // or p at the end of the range, where a score that first rises may still fall further on) the
    // ends of the range decide between flat and a search of it all.
    auto line = [&](std::vector<double> p, double fp, double se, size_t j, int budget1) {
      const double step = 0.15, x0 = p[j];
      const size_t before = seen.size();
      double lo1 = fp, hi1 = fp;
      auto at = [&](double x) {
        p[j] = std::clamp(x, 0.0, 1.0);
        const double m = evaluate(p);
        if (m < 1e30) lo1 = std::min(lo1, m), hi1 = std::max(hi1, m);
        return m;
      };
      const double a = std::max(0.0, x0 - step), b = std::min(1.0, x0 + step);
      const double fa = a < x0 ? at(a) : kInf, fb = b > x0 ? at(b) : kInf;
      double left = 0, right = 1;
      if (std::min(fa, fb) < fp - se) {
        const double dir = fa <= fb ? -1 : 1;
        double prev = x0, cur = dir < 0 ? a : b, fcur = std::min(fa, fb), len = step;
        left = std::min(prev, cur), right = std::max(prev, cur);
        for (;;) {
          len *= 1.618;
          const double next = std::clamp(cur + dir * len, 0.0, 1.0);
          if (next == cur) break;
          const double fn = at(next);
          left = std::min(prev, next), right = std::max(prev, next);
          if (fn >= fcur) break;
          prev = cur, cur = next, fcur = fn;
          if (next == 0.0 || next == 1.0) {
            left = std::min(prev, cur), right = std::max(prev, cur);
            break;
          }
        }
      } else if (std::isfinite(fa) && std::isfinite(fb) && fa > fp + se && fb > fp + se) {
        left = a, right = b;
      } else {
        for (double x : {0.0, 1.0})
          if (std::abs(x - x0) > step) at(x);
        if (hi1 - lo1 <= 2 * se) return true;
      }
      const int used = static_cast<int>(seen.size() - before);
      boost::uintmax_t it = static_cast<boost::uintmax_t>(std::max(2, budget1 - used));
      // Shifted by 1 so that Brent's relative tolerance (2^-9) is an absolute one of 0.2 to 0.4 %.
      boost::math::tools::brent_find_minima([&](double x) { return at(x - 1); }, left + 1, right + 1, 10, it);
      return false;
    };
    if (!from.empty() && d == 1) {
      // Refinement of a coarse fit: Brent within a small bracket around it.
      boost::uintmax_t it = static_cast<boost::uintmax_t>(std::max(2, budget));
      const double lo1 = std::max(0.0, from[0] - 0.06), hi1 = std::min(1.0, from[0] + 0.06);
      boost::math::tools::brent_find_minima([&](double x) { return evaluate({std::clamp(x - 1, 0.0, 1.0)}); }, lo1 + 1, hi1 + 1,
                                            10, it);
    } else if (from.empty() && (d == 1 || order.size() < d)) {
      // One parameter, or a coarse fit of the few that rank the effect: a line search along each
      // in turn, from the best point so far; the rest stay where they start until a refinement.
      flat = true;
      const int share = budget / static_cast<int>(order.size());
      for (size_t j : order) {
        flat = line(bestS.empty() ? s0 : bestS, bestS.empty() ? base : bestM, seTrain, j, share) && flat;
      }
    } else {
      nlopt::opt opt(nlopt::LN_BOBYQA, static_cast<unsigned>(d));
      opt.set_lower_bounds(std::vector<double>(d, 0.0));
      opt.set_upper_bounds(std::vector<double>(d, 1.0));
      opt.set_xtol_abs(1e-3);
      opt.set_maxeval(budget);
      if (!from.empty()) opt.set_initial_step(0.05);
      std::function<double(const std::vector<double>&)> fn = evaluate;
      opt.set_min_objective(
          [](const std::vector<double>& s, std::vector<double>&, void* p) {
            return (*static_cast<std::function<double(const std::vector<double>&)>*>(p))(s);
          },
          &fn);
      std::vector<double> s = from.empty() ? s0 : from;
      double v = 0;
      try {
        opt.optimize(s, v);
      } catch (const nlopt::roundoff_limited&) {
      } catch (const std::runtime_error& err) {
        if (bestS.empty()) f.status = std::string("the minimiser failed: ") + err.what();
      }
    }
    if (bestS.empty()) {
      f.status = "every replay of the fit failed";
      return f;
    }
    f.values = values(bestS);
    f.trainAfter = bestM;
    f.identifiable = !flat && hi - lo > 2 * seTrain;
    if (!heldOut) return f;
    f.heldoutBefore = heldBase.metric();
    f.heldoutMmBefore = heldBase.mmMean();
    if ((bestS == s0 && nominalIsCurrent) || flat) {
      // Nothing better than the scene as it is: the held-out score is the scene's.
      f.values = values(s0);
      f.trainAfter = base;
      f.heldoutAfter = f.heldoutBefore;
      f.heldoutMmAfter = f.heldoutMmBefore;
      f.deltaBic = bic(heldBase, static_cast<int>(d)) - bic(heldBase, 0);
      f.pValue = 1;
      return f;
    }
    // The held-out score of the fitted values: one full replay.
    ReplayOptions ro = o_.replay;
    ro.cloudCorrection = compose(e.cloudCorrection(f.values, as));
    ReplayScore full;
    if (cloudOnly) {
      full = rescore(*recorded, data_, ro);
    } else {
      SceneDesc desc = current;
      e.apply(desc, f.values, as);
      ++f.evaluations;
      full = replay(desc, data_, ro);
    }
    if (!full.ok()) {
      f.status = "the fitted scene failed on the held-out frames: " + full.reason;
      return f;
    }
    const Items held = itemsOf(full, split_, kInf, scales_, wrench_);
    f.heldoutAfter = held.metric();
    f.heldoutMmAfter = held.mmMean();
    f.deltaBic = bic(held, static_cast<int>(d)) - bic(heldBase, 0);
    f.pValue = pairedP(heldBase, held);
    f.worsens = worsenedStream(heldBase, held, o_.alpha);
    return f;
  }

  const PreparedDataset& data_;
  const AuditOptions& o_;
  AuditProgress* progress_;
  std::vector<std::unique_ptr<Effect>> library_ = effectLibrary();
  Scales scales_;
  std::optional<TopResidualMap> topGrid_;  // the nominal replay's top-surface map
  bool wrench_ = false;
  double split_ = 0;
  std::vector<std::string> notes_;
  std::optional<RigidTransform> correction_;  // of the clouds, found by earlier rounds
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  int forceNoiseSamples_ = 0;                           // out of contact, that forceNoise is read on
  mutable double lastForceRatio_ = kNan;                // held-out RMS force error / force noise, at the last gate
  std::map<std::string, std::vector<double>> lastFit_;  // each effect's values in the last round it was fitted
};

}  // namespace

AuditScene describeScene(const SceneDesc& desc) {
  AuditScene as;
  as.desc = desc;
  const AttrDesc* u = desc.root.find("units");
  as.units = u ? UnitSystem::parse(u->value) : UnitSystem();
  auto scene = buildScene(desc);
  scene->init();
  for (MechanicalObject* m : scene->all<MechanicalObject>())
    for (Eigen::Index i = 0; i < m->x0.cols(); ++i) as.tissueBox.extend(m->x0.col(i));
  const auto spheres = scene->all<SphereCollisionModel>();
  if (!spheres.empty()) as.instrumentRadius = spheres.front()->radius();
  for (TetrahedronFEMForceField* f : scene->all<TetrahedronFEMForceField>()) {
    const TetList& t = f->tetrahedra();
    Eigen::Matrix3Xd X(3, 4 * t.cols());
    for (Eigen::Index e = 0; e < t.cols(); ++e)
      for (int k = 0; k < 4; ++k) X.col(4 * e + k) = f->mstate().x0.col(t(k, e));
    as.femElements.push_back(std::move(X));
  }
  return as;
}

const char* Localisation::phaseName(int phase) {
  static const char* const names[] = {"rest", "loading", "holding", "release"};
  return phase >= 0 && phase < kPhases ? names[phase] : "?";
}

AuditReport runAudit(const SceneDesc& scene, const PreparedDataset& data, const AuditOptions& options,
                     AuditProgress* progress) {
  if (!(options.trainFraction > 0 && options.trainFraction < 1)) throw Error("--train: must be between 0 and 1");
  if (options.rounds < 1) throw Error("--rounds: must be at least 1");
  if (options.jobs < 1) throw Error("--jobs: must be at least 1");
  Auditor a(data, options, progress);
  return a.run(scene);
}

namespace {

using Json = nlohmann::ordered_json;

Json num(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

Json fitJson(const EffectFit& f) {
  Json params = Json::object();
  for (size_t j = 0; j < f.params.size() && j < f.values.size(); ++j) params[f.params[j].name] = f.values[j];
  return {{"effect", f.effect},
          {"status", f.status},
          {"params", params},
          {"evaluations", f.evaluations},
          {"train_before", num(f.trainBefore)},
          {"train_after", num(f.trainAfter)},
          {"heldout_before", num(f.heldoutBefore)},
          {"heldout_after", num(f.heldoutAfter)},
          {"heldout_before_mm", num(f.heldoutMmBefore)},
          {"heldout_after_mm", num(f.heldoutMmAfter)},
          {"delta_bic", num(f.deltaBic)},
          {"p_value", num(f.pValue)},
          {"identifiable", f.identifiable},
          {"worsens", f.worsens.empty() ? Json(nullptr) : Json(f.worsens)},
          {"screened_out", f.screened}};
}

Json localisationJson(const Localisation& L) {
  Json cells = Json::array();
  for (int ph = 0; ph < Localisation::kPhases; ++ph)
    for (int r = 0; r < kRegionCount; ++r) {
      const CellStats& c = L.cells[ph][r];
      if (c.points == 0) continue;
      cells.push_back({{"phase", Localisation::phaseName(ph)},
                       {"region", regionName(r)},
                       {"frames", c.frames},
                       {"points", c.points},
                       {"rms_mm", num(c.rmsMm)},
                       {"mean_signed_mm", num(c.meanSignedMm)},
                       {"vs_rest_mm", num(c.vsRestMm)},
                       {"p_value", num(c.p)},
                       {"above_noise", c.aboveNoise},
                       {"disagrees", c.significant}});
    }
  return {{"mean_mm", num(L.meanMm)}, {"p95_mm", num(L.p95Mm)}, {"cells", cells}};
}

}  // namespace

std::string auditJson(const AuditReport& r, const std::string& scene, const std::string& data,
                      const std::string& augmentedScene) {
  Json j;
  j["scene"] = scene;
  j["data"] = data;
  j["noise_floor_mm"] = num(r.noiseFloorMm);
  j["noise_floor_se_mm"] = num(r.noiseFloorSeMm);
  j["force_noise"] = num(r.forceNoise);
  j["verdict"] = r.verdict;
  j["found"] = r.found;
  Json rounds = Json::array();
  for (const auto& rd : r.rounds) {
    const EffectFit* w = rd.candidates.empty() ? nullptr : &rd.candidates.front();
    Json params = Json::object();
    if (w)
      for (size_t k = 0; k < w->params.size() && k < w->values.size(); ++k) params[w->params[k].name] = w->values[k];
    Json cands = Json::array();
    for (const auto& c : rd.candidates) cands.push_back(fitJson(c));
    rounds.push_back({{"effect", rd.confirmed && w ? Json(w->effect) : Json(nullptr)},
                      {"best_candidate", w ? Json(w->effect) : Json(nullptr)},
                      {"confirmed", rd.confirmed},
                      {"params", params},
                      {"heldout_before_mm", num(rd.heldoutBeforeMm)},
                      {"heldout_after_mm", num(rd.heldoutAfterMm)},
                      {"runner_up", rd.runnerUp.empty() ? Json(nullptr) : Json(rd.runnerUp)},
                      {"margin", num(rd.margin)},
                      {"p_value", w ? num(w->pValue) : Json(nullptr)},
                      {"candidates", cands}});
  }
  j["rounds"] = rounds;
  if (!r.jointValues.empty()) {
    Json jv = Json::object();
    size_t at = 0;
    for (const auto& rd : r.rounds) {
      if (!rd.confirmed) continue;
      const EffectFit& w = rd.candidates.front();
      for (const auto& p : w.params)
        if (at < r.jointValues.size()) jv[w.effect + "." + p.name] = r.jointValues[at++];
    }
    j["refit"] = jv;
  }
  Json cands = Json::array();
  for (const auto& rd : r.rounds)
    for (const auto& c : rd.candidates) cands.push_back(fitJson(c));
  j["candidates"] = cands;
  j["remaining_gap_mm"] = num(r.remainingGapMm);
  j["at_noise_level"] = r.atNoiseLevel;
  j["augmented_scene"] = augmentedScene;
  if (r.cloudCorrection) {
    Json m = Json::array();
    for (int i = 0; i < 4; ++i) {
      Json row = Json::array();
      for (int k = 0; k < 4; ++k) row.push_back(r.cloudCorrection->matrix()(i, k));
      m.push_back(row);
    }
    j["cloud_correction"] = m;
  }
  j["split_time"] = r.splitTime;
  j["before"] = localisationJson(r.before);
  j["after"] = localisationJson(r.after);
  j["notes"] = r.notes;
  return j.dump(2) + "\n";
}

std::string auditMarkdown(const AuditReport& r, const std::string& scene, const std::string& data,
                          const std::string& augmentedScene) {
  auto fmt = [](double v) {
    std::ostringstream o;
    o.precision(4);
    o << v;
    return o.str();
  };
  std::ostringstream m;
  m.precision(4);
  m << "# Model audit\n\n"
    << "Scene `" << scene << "`, dataset `" << data << "`.\n\n"
    << "**Verdict: " << r.verdict << "**";
  if (!r.found.empty()) {
    m << " — ";
    for (size_t i = 0; i < r.found.size(); ++i) m << (i ? ", " : "") << "`" << r.found[i] << "`";
  }
  m << ". Depth noise of the clouds (noise floor): " << r.noiseFloorMm << " mm. Remaining held-out gap: "
    << r.remainingGapMm << " mm (" << (r.atNoiseLevel ? "at" : "above") << " the noise level, 1.5 x the floor). "
    << "Training frames end at t = " << r.splitTime << " s; the rest are held out.\n\n"
    << "Augmented scene: `" << augmentedScene << "`.\n\n";
  m << "## Before and after\n\n| | mean (mm) | 95th percentile (mm) |\n|---|---|---|\n"
    << "| nominal scene | " << r.before.meanMm << " | " << r.before.p95Mm << " |\n"
    << "| augmented scene | " << r.after.meanMm << " | " << r.after.p95Mm << " |\n\n";
  m << "## Where the nominal scene disagrees\n\nPer phase and surface region: RMS and mean signed residual "
       "(+: the cloud lies outside the simulated surface), the change of the mean signed residual from the same region "
       "at rest and its p (Welch's t-test over frames, Holm-adjusted). A cell disagrees when its RMS exceeds 1.5 x the "
       "noise floor, or when it moves from rest by more than half the floor at p < alpha.\n\n"
       "| phase | region | frames | RMS (mm) | mean signed (mm) | vs rest (mm) | p | |\n|---|---|---|---|---|---|---|---|\n";
  for (int ph = 0; ph < Localisation::kPhases; ++ph)
    for (int rg = 0; rg < kRegionCount; ++rg) {
      const CellStats& c = r.before.cells[ph][rg];
      if (c.points == 0) continue;
      m << "| " << Localisation::phaseName(ph) << " | " << regionName(rg) << " | " << c.frames << " | " << c.rmsMm << " | "
        << c.meanSignedMm << " | " << (ph == kRest ? std::string("") : fmt(c.vsRestMm)) << " | "
        << (ph == kRest ? std::string("") : fmt(c.p)) << " | " << (c.significant ? "**disagrees**" : "") << " |\n";
    }
  for (size_t i = 0; i < r.rounds.size(); ++i) {
    const AuditRound& rd = r.rounds[i];
    m << "\n## Round " << i + 1 << "\n\n"
      << (rd.confirmed ? "Added `" + rd.candidates.front().effect + "`"
                       : std::string("No candidate passed the test against the nominal scene"))
      << ". Held-out gap " << rd.heldoutBeforeMm << " -> " << rd.heldoutAfterMm << " mm.\n\n"
      << "| rank | effect | fitted | held-out (mm) | delta BIC | p | identifiable | worsens |\n|---|---|---|---|---|---|---|---|\n";
    for (size_t k = 0; k < rd.candidates.size(); ++k) {
      const EffectFit& f = rd.candidates[k];
      std::ostringstream v;
      v.precision(4);
      for (size_t j = 0; j < f.values.size(); ++j) v << (j ? ", " : "") << f.params[j].name << " " << f.values[j];
      m << "| " << k + 1 << " | `" << f.effect << "` | "
        << (f.status != "ok" ? f.status : f.screened ? std::string("not refitted: no better a step either way") : v.str()) << " | "
        << f.heldoutMmBefore << " -> " << f.heldoutMmAfter << " | " << f.deltaBic << " | " << f.pValue << " | "
        << (f.identifiable ? "yes" : "no: flat over its range") << " | " << f.worsens << " |\n";
    }
  }
  if (!r.jointValues.empty()) {
    m << "\n## Refitted together\n\nEach effect found, refitted with the others at their values (an effect fitted alone "
         "absorbs part of the one found after it): ";
    size_t at = 0;
    for (const auto& rd : r.rounds) {
      if (!rd.confirmed) continue;
      for (const auto& p : rd.candidates.front().params) {
        if (at >= r.jointValues.size()) break;
        m << (at ? ", " : "") << rd.candidates.front().effect << "." << p.name << " " << fmt(r.jointValues[at]);
        ++at;
      }
    }
    m << ".\n";
  }
  if (!r.notes.empty()) {
    m << "\n## Notes\n\n";
    for (const auto& n : r.notes) m << "- " << n << "\n";
  }
  return m.str();
}

}  // namespace viscera::study
