// Small networks from a window of feature vectors to a few outputs: the force estimators'
// networks (dissertation §2.3-2.5). Architectures:
//  - "mlp": the window flattened, `layers` hidden layers of `hidden` units, a linear output;
//  - "lstm": an LSTM of `hidden` units over the window, then two fully connected layers (ReLU).
// With `perOutput` each output column gets a network of its own (the per-joint networks; a single
// network for all outputs otherwise). Inputs and outputs are standardised with the training data's
// statistics; with outputScaling "range" the outputs are instead mapped from the training range
// to [-1, 1] (the direct estimator's scaled output), and with "none" they are left in their units
// (a single network for all joints then weighs each joint by its effort's scale, as the one
// compared in dissertation Table 2-4).
//
// A model is a folder: config.json (kind "regressor", the architecture, normalisation, training
// notes) and weights.pt.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace viscera::learning {

struct RegressorArchitecture {
  std::string kind = "mlp";          // "mlp" or "lstm"
  int window = 1;                    // feature vectors per sample (oldest first)
  int features = 12;                 // per feature vector
  int outputs = 6;
  int hidden = 100;
  int layers = 1;                    // hidden layers of an mlp
  std::string activation = "tanh";   // of an mlp's hidden layers: tanh, relu or leakyrelu
  bool perOutput = true;
  std::string outputScaling = "standard";  // "standard", "range" or "none"
};

// Samples in memory: x is samples x (window * features), oldest vector first; y samples x outputs.
struct RegressorData {
  Eigen::MatrixXf x, y;
  int samples() const { return static_cast<int>(x.rows()); }
};

struct RegressorTrainOptions {
  int epochs = 100;
  int batch = 256;
  double learningRate = 1e-3;
  std::string loss = "mse";  // "mse" or "mae" (in normalised units)
  double weightDecay = 0;    // L2 penalty on the weights (Adam's weight_decay)
  int patience = 0;          // epochs without a better validation loss before stopping; 0: never
  std::uint64_t seed = 1;
};

struct RegressorEpochReport {
  int epoch = 0;
  double trainLoss = 0, validationLoss = 0;  // normalised units; validation NaN without data
  double seconds = 0;
  bool best = false;
};

class Regressor {
 public:
  struct Impl {
    virtual ~Impl() = default;
    virtual Eigen::MatrixXf predict(const Eigen::MatrixXf& x) const = 0;
    virtual void save(const std::string& folder, const std::string& notes) const = 0;
    virtual const RegressorArchitecture& architecture() const = 0;
    virtual std::int64_t parameters() const = 0;
    virtual const std::string& notes() const = 0;
  };

  // Trains a new network on `train` (validation: `validation`, may be empty; the weights of its best
  // epoch are kept). `progress` is called after each epoch.
  static Regressor train(const RegressorArchitecture& arch, const RegressorTrainOptions& options, const RegressorData& train,
                         const RegressorData& validation, const std::function<void(const RegressorEpochReport&)>& progress = {});
  static Regressor load(const std::string& folder);
  explicit Regressor(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

  // Outputs for samples x (window * features) inputs, in the training data's units.
  Eigen::MatrixXf predict(const Eigen::MatrixXf& x) const { return impl_->predict(x); }
  void save(const std::string& folder, const std::string& notes) const { impl_->save(folder, notes); }
  const RegressorArchitecture& architecture() const { return impl_->architecture(); }
  std::int64_t parameters() const { return impl_->parameters(); }
  const std::string& notes() const { return impl_->notes(); }

 private:
  std::shared_ptr<Impl> impl_;
};

}  // namespace viscera::learning
