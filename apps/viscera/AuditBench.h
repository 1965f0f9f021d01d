// `viscera audit bench`: the audit's confusion matrix, detection and false-discovery rates over
// planted effects (see docs/user-guide.md, "Model audit").
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/SceneDesc.h"

namespace viscera {

struct AuditBenchArgs {
  std::string scene, out = "audit-bench", forceNoise = "2 mN";
  std::vector<std::string> effects;           // planted (empty: every effect that applies)
  std::vector<double> strengths = {0.5, 1.0};  // Effect::plant strengths
  int seeds = 2, jobs = 1;
  double time = 0;  // simulated time of each case
  bool keep = false;  // keep each case's truth scene and dataset
};

int auditBench(const AuditBenchArgs& a);

// Makes the input file attributes of `el` (trajectories, meshes) absolute, relative to
// `sceneDir`, so that a description written elsewhere still finds them. Outputs stay relative.
void absolutiseInputs(ElementDesc& el, const std::filesystem::path& sceneDir);

}  // namespace viscera
