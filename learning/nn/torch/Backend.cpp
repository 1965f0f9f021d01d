// The plugin's entry point: the table of LibTorch's implementations (learning/nn/Backend.h).
#include "learning/nn/Backend.h"
#include "learning/nn/torch/GridUNet.h"

namespace viscera::learning {
namespace {

}  // namespace

// learning/nn/torch/Regressor.cpp
std::unique_ptr<Regressor::Impl> newTrainedRegressor(const RegressorArchitecture&, const RegressorTrainOptions&,
                                                      const RegressorData&, const RegressorData&,
                                                      const std::function<void(const RegressorEpochReport&)>&);
std::unique_ptr<Regressor::Impl> loadSavedRegressor(const std::string& folder);

namespace {

void setThreads(int threads) {
  if (threads > 0) torch::set_num_threads(threads);
}

const LearningBackend kTorchBackend{&newTorchStepper,   &loadTorchStepper,    &torchTrainStepper, &newTorchCorrector,
                                    &loadTorchCorrector, &torchTrainCorrector, &newTrainedRegressor, &loadSavedRegressor,
                                    &torchMeasureGemm,  &setThreads};

}  // namespace
}  // namespace viscera::learning

extern "C" __attribute__((visibility("default"))) const viscera::learning::LearningBackend* viscera_learning_backend() {
  return &viscera::learning::kTorchBackend;
}
