// The model audit (docs/user-guide.md, "Model audit"): where and when a simulation disagrees with a
// measured dataset, which missing effect explains it, the scene with that effect added, and how
// much of the gap it closes on frames the fit never saw.
//
//  1. Localise: replay the dataset through the scene; residuals per frame, per surface region and
//     per phase (rest, loading, holding, release); a region disagrees in a phase when its RMS stands
//     above 1.5 x the noise floor or its signed residual moves from rest (Welch's t-test, Holm). The noise floor comes from the clouds themselves: the
//     RMS distance of each point to the plane through its nearest neighbours (study/Noise.h).
//  2. Fit every effect of the library (study/effects) on the training frames (the first 60 % of
//     the measurements' time span) with the search's minimisers, score it on the held-out rest.
//  3. Rank by held-out BIC (held-out improvement, penalised per parameter); the winner must beat
//     the nominal scene in a one-sided paired test at level alpha / m (Bonferroni-Holm over the m
//     candidates tried), or nothing is named.
//  4. Add the winner and repeat while the held-out gap stands above the noise floor; from the
//     second effect on, everything found is refitted together (backfitting). The result is at the noise level
//     when the gap is within 1.5 x the floor.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "study/Replay.h"
#include "study/effects/Effect.h"

namespace viscera::study {

struct AuditOptions {
  int jobs = 1;                    // effects fitted at once (threads)
  int rounds = 3;                  // effects added at most
  std::vector<std::string> effects;  // keys to try (empty: the whole library)
  double trainFraction = 0.6;      // training: the first part of the measurements' time span
  int maxEvaluations = 16;         // replays per fit at most
  double alpha = 0.05;             // family-wise error rate of the confirmation test
  ReplayOptions replay;            // scoring; threads per replay
  // When set, the nominal and the final replays write their per-frame residuals here for
  // ParaView (ReplayOptions::residualFolder).
  std::string residualsBefore, residualsAfter;
  int residualFrames = 150;  // frames per residual series at most, evenly spaced (0: all)
};

// Residual statistics of one region in one phase, over the frames that have points there.
struct CellStats {
  int frames = 0, points = 0;
  double rmsMm = 0, meanSignedMm = 0;  // over points
  double vsRestMm = std::numeric_limits<double>::quiet_NaN();  // mean signed residual minus the region's at rest
  double p = 1;                        // Welch's t-test of that change over frames (Holm-adjusted); 1 at rest
  bool aboveNoise = false;             // RMS > 1.5 x the noise floor
  bool significant = false;            // disagrees: above the noise, or a change from rest worth seeing at p < alpha
};
struct Localisation {
  static constexpr int kPhases = 4;           // rest, loading, holding, release
  static const char* phaseName(int phase);
  std::vector<std::vector<CellStats>> cells;  // [phase][region]
  std::vector<int> framesPerPhase;            // kPhases
  double meanMm = 0, p95Mm = 0;               // per-frame RMS distance: mean and 95th percentile
  double forceRms = std::numeric_limits<double>::quiet_NaN();  // RMS force error (scene units)
  std::vector<double> frameTimes, frameRmsMm; // the residual over time
  std::vector<int> framePhases;
};

struct EffectFit {
  std::string effect, what;
  std::vector<EffectParam> params;
  std::vector<double> values;       // fitted
  int evaluations = 0;
  std::string status = "ok";        // or why the fit failed
  double trainBefore = 0, trainAfter = 0, heldoutBefore = 0, heldoutAfter = 0;  // metric
  double heldoutMmBefore = 0, heldoutMmAfter = 0;  // held-out mean per-frame RMS distance
  double deltaBic = 0;              // held-out BIC(with the effect) - BIC(without): < 0 favours it
  double pValue = 1;                // one-sided paired test that the effect lowers the held-out metric
  bool identifiable = true;         // the training metric changes over the range by more than its noise
  bool screened = false;            // later rounds: no step either way improved it, so it was not fitted
  std::string worsens;              // "surface" or "force": the held-out stream it makes significantly worse
};

struct AuditRound {
  std::vector<EffectFit> candidates;  // ranked, best first
  bool confirmed = false;             // the first candidate passed the test
  std::string runnerUp;
  double margin = 0;                  // runner-up's held-out BIC change - the winner's (>= 0)
  double heldoutBeforeMm = 0, heldoutAfterMm = 0;
};

struct AuditReport {
  double noiseFloorMm = 0;            // depth noise of the clouds
  double noiseFloorSeMm = 0;          // its standard error (spread between the frames it is read on)
  double forceNoise = std::numeric_limits<double>::quiet_NaN();  // RMS |measured force| out of contact
  std::string verdict;                // "effects found" or "no missing effect detected"
  std::vector<std::string> found;     // effect keys, in order added
  std::vector<AuditRound> rounds;
  std::vector<double> jointValues;  // with two effects or more: their parameters refitted together, in round order
  Localisation before, after;
  std::optional<TopResidualMap> topBefore, topAfter;  // the top surface's residual map (mm), nominal and augmented
  double remainingGapMm = 0;          // held-out mean per-frame RMS distance at the end
  bool atNoiseLevel = false;
  SceneDesc augmented;
  std::optional<RigidTransform> cloudCorrection;  // the registration effect's, when found (scene frame)
  double splitTime = 0;               // training frames end here (dataset time)
  std::vector<std::string> notes;     // e.g. effects that do not apply, fits that failed
};

struct AuditProgress {
  virtual ~AuditProgress() = default;
  virtual void message(const std::string& line) {}
};

// What an effect may know of a scene: its units, the tissue's box, the instrument's radius and the
// FEM elements (built and initialised once). AuditScene::touches stays empty.
AuditScene describeScene(const SceneDesc& desc);

AuditReport runAudit(const SceneDesc& scene, const PreparedDataset& data, const AuditOptions& options,
                     AuditProgress* progress = nullptr);

// report.json (see the user guide for its fields) and report.md.
std::string auditJson(const AuditReport& r, const std::string& scene, const std::string& data,
                      const std::string& augmentedScene);
std::string auditMarkdown(const AuditReport& r, const std::string& scene, const std::string& data,
                          const std::string& augmentedScene);

}  // namespace viscera::study
