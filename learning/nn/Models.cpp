// The learned components' models through LibTorch's backend, a plugin loaded on first use
// (learning/nn/Backend.h).
#include <dlfcn.h>
#include <unistd.h>

#include <climits>
#include <cstdlib>
#include <filesystem>
#include <mutex>

#include "core/Error.h"
#include "learning/nn/Backend.h"

namespace viscera::learning {

namespace {

const char kPluginName[] = "libviscera_torch.so";

struct Loaded {
  const LearningBackend* backend = nullptr;
  std::string why;
};

std::string programFolder() {
  char buf[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return "";
  buf[n] = 0;
  return std::filesystem::path(buf).parent_path().string();
}

Loaded load() {
  Loaded out;
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("VISCERA_TORCH_PLUGIN"); env && *env) {
    candidates.push_back(env);
  } else {
    if (const std::string dir = programFolder(); !dir.empty()) candidates.push_back(dir + "/" + kPluginName);
#ifdef VISCERA_TORCH_PLUGIN_PATH
    candidates.push_back(VISCERA_TORCH_PLUGIN_PATH);
#endif
  }
#ifndef VISCERA_TORCH_PLUGIN_PATH
  if (candidates.size() <= 1 && !std::getenv("VISCERA_TORCH_PLUGIN"))
    out.why = "this build of Viscera has no LibTorch (configured with VISCERA_WITH_TORCH=OFF or without libtorch-dev)";
#endif
  for (const std::string& path : candidates) {
    if (!std::filesystem::exists(path)) continue;
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      out.why = std::string("cannot load the LibTorch plugin ") + path + ": " + ::dlerror();
      return out;
    }
    auto entry = reinterpret_cast<const LearningBackend* (*)()>(::dlsym(handle, "viscera_learning_backend"));
    if (!entry) {
      out.why = "the LibTorch plugin " + path + " has no entry point viscera_learning_backend";
      return out;
    }
    out.backend = entry();
    return out;
  }
  if (out.why.empty()) {
    out.why = std::string("the LibTorch plugin ") + kPluginName + " was not found (looked for";
    for (const std::string& c : candidates) out.why += " " + c;
    out.why += "; VISCERA_TORCH_PLUGIN names another)";
  }
  return out;
}

const Loaded& loaded() {
  static const Loaded l = load();
  return l;
}

}  // namespace

const LearningBackend& learningBackend() {
  const Loaded& l = loaded();
  if (!l.backend) throw Error("learned components are not available: " + l.why);
  return *l.backend;
}

bool torchAvailable() { return loaded().backend != nullptr; }

void setTorchThreads(int threads) {
  if (threads > 0) learningBackend().setThreads(threads);
}

const char* outputName(StepperArchitecture::Output o) {
  return o == StepperArchitecture::Output::NextOffset ? "next offset" : "update";
}

Stepper::Stepper(const RestMesh& mesh, const StepperArchitecture& arch, const StepperNormalisers& norm, double framePeriod,
                 const std::string& units, std::uint64_t seed)
    : impl_(learningBackend().newStepper(mesh, arch, norm, framePeriod, units, seed)) {}

Stepper Stepper::load(const std::string& folder) { return Stepper(learningBackend().loadStepper(folder)); }

void trainStepper(const StepperTrainOptions& options, const std::function<void(const EpochReport&)>& progress) {
  learningBackend().trainStepper(options, progress);
}

Corrector::Corrector(const RestMesh& mesh, const GridShape& grid, const Eigen::Vector3d& viewDirection,
                     const CorrectorArchitecture& arch, const std::string& units, std::uint64_t seed)
    : impl_(learningBackend().newCorrector(mesh, grid, viewDirection, arch, units, seed)) {}

Corrector Corrector::load(const std::string& folder) { return Corrector(learningBackend().loadCorrector(folder)); }

void trainCorrector(const CorrectorTrainOptions& options, const std::function<void(const CorrectorEpochReport&)>& progress) {
  learningBackend().trainCorrector(options, progress);
}

Regressor Regressor::train(const RegressorArchitecture& arch, const RegressorTrainOptions& options, const RegressorData& train,
                           const RegressorData& validation, const std::function<void(const RegressorEpochReport&)>& progress) {
  return Regressor(learningBackend().trainRegressor(arch, options, train, validation, progress));
}

Regressor Regressor::load(const std::string& folder) { return Regressor(learningBackend().loadRegressor(folder)); }

GemmSpeed measureGemm(int m, int k, int n, int repeats) { return learningBackend().measureGemm(m, k, n, repeats); }

}  // namespace viscera::learning
