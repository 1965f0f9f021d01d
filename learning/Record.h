// Recording rollouts for a learned stepper (`viscera learn record`): many randomised palpations of
// one scene's deformable body, each a variant of the scene whose instrument follows a generated
// trajectory, run in parallel through the library run and written as rollouts (Rollout.h).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "learning/data/Rollout.h"
#include "motion/Palpation.h"

namespace viscera::learning {

struct RecordOptions {
  std::string scene;                  // a scene with one deformable body and one instrument driven
                                      // by a TrajectoryDriver, with a sphere collision model
  std::vector<std::string> sets;      // ADDRESS=VALUE edits of the scene
  std::string out;                    // the folder to create (must not exist)
  int rollouts = 8;
  double time = 20;                   // simulated time of each rollout (the scene's time unit)
  double rate = 30;                   // frames per unit time (rounded to a whole number of steps)
  double depthMin = 2, depthMax = 6;  // poke depth past the undeformed face (the scene's length unit)
  double speedMin = 5, speedMax = 15; // approach / press / retract speed (length per time unit)
  std::vector<motion::Face> faces = {motion::Face::Top, motion::Face::XMin, motion::Face::XMax, motion::Face::YMin,
                                     motion::Face::YMax};
  std::uint64_t seed = 1;             // rollout k draws from seed + k
  bool sceneTrajectory = false;       // one rollout along the scene's own trajectory (a held-out
                                      // palpation) instead of generated ones
  int jobs = 0;                       // rollouts run at once (0: one per core)
};

struct RecordResult {
  int rollouts = 0, diverged = 0;
  long frames = 0;
  double wallSeconds = 0, simulatedTime = 0;
};

// Records the rollouts into `out` (written under a temporary name and renamed when complete).
// `progress` is told about each finished rollout. Input errors throw viscera::Error; a rollout that
// diverges keeps its frames up to the divergence and is marked in the index.
RecordResult record(const RecordOptions& options, const std::function<void(const std::string&)>& progress = {});

// Pairs for a learned correction (learning/data/Pairs.h, `viscera learn record --data`): the scene
// replays a measured dataset (study/Replay.h) and at each camera frame its body on a regular grid is
// kept beside the frame's cloud (in the scene frame, at most `maxPoints` points chosen evenly).
struct PairOptions {
  std::string scene, data, out;
  std::vector<std::string> sets;
  int maxPoints = 4000;
};
struct PairResult {
  int frames = 0;
  double wallSeconds = 0, cloudRms = 0;  // cloudRms: the replay's mean per-frame cloud -> surface RMS
};
PairResult recordPairs(const PairOptions& options);

// The rest mesh (nodes, tetrahedra, fixed nodes) of a scene's one deformable body, as a recording
// of it would hold; `sets` are ADDRESS=VALUE edits. Throws Error naming the scene.
RestMesh sceneRestMesh(const std::string& scene, const std::vector<std::string>& sets = {});

}  // namespace viscera::learning
