// LibTorch's backend of the learned components, in a plugin (libviscera_torch.so) loaded on first
// use: linking LibTorch into every program would cost each of them most of a second at start-up
// (its operator registry), whether it uses a network or not. The plugin exports
// `viscera_learning_backend`, which returns this table; the plugin's own references to Viscera's
// code resolve against the program that loads it (programs export their symbols).
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "learning/nn/Corrector.h"
#include "learning/nn/Regressor.h"
#include "learning/nn/Stepper.h"

namespace viscera::learning {

struct LearningBackend {
  std::unique_ptr<Stepper::Impl> (*newStepper)(const RestMesh&, const StepperArchitecture&, const StepperNormalisers&, double,
                                               const std::string&, std::uint64_t);
  std::unique_ptr<Stepper::Impl> (*loadStepper)(const std::string& folder);
  void (*trainStepper)(const StepperTrainOptions&, const std::function<void(const EpochReport&)>&);
  std::unique_ptr<Corrector::Impl> (*newCorrector)(const RestMesh&, const GridShape&, const Eigen::Vector3d&,
                                                   const CorrectorArchitecture&, const std::string&, std::uint64_t);
  std::unique_ptr<Corrector::Impl> (*loadCorrector)(const std::string& folder);
  void (*trainCorrector)(const CorrectorTrainOptions&, const std::function<void(const CorrectorEpochReport&)>&);
  std::unique_ptr<Regressor::Impl> (*trainRegressor)(const RegressorArchitecture&, const RegressorTrainOptions&,
                                                     const RegressorData&, const RegressorData&,
                                                     const std::function<void(const RegressorEpochReport&)>&);
  std::unique_ptr<Regressor::Impl> (*loadRegressor)(const std::string& folder);
  GemmSpeed (*measureGemm)(int m, int k, int n, int repeats);
  void (*setThreads)(int threads);
};

// The backend, loaded once: from $VISCERA_TORCH_PLUGIN when set, else libviscera_torch.so beside
// the program, else where the build put it. Throws Error saying why when there is none (a build
// without LibTorch, or the plugin missing or failing to load).
const LearningBackend& learningBackend();

}  // namespace viscera::learning

// The plugin's entry point.
extern "C" const viscera::learning::LearningBackend* viscera_learning_backend();
