// The plugin's entry point: the table of LibTorch's implementations (learning/nn/Backend.h).
#include "learning/nn/Backend.h"
#include "learning/nn/torch/GridUNet.h"

namespace viscera::learning {
namespace {

void setThreads(int threads) {
  if (threads > 0) torch::set_num_threads(threads);
}

const LearningBackend kTorchBackend{&newTorchStepper,   &loadTorchStepper,    &torchTrainStepper, &newTorchCorrector,
                                    &loadTorchCorrector, &torchTrainCorrector, &torchMeasureGemm,  &setThreads};

}  // namespace
}  // namespace viscera::learning

extern "C" __attribute__((visibility("default"))) const viscera::learning::LearningBackend* viscera_learning_backend() {
  return &viscera::learning::kTorchBackend;
}
