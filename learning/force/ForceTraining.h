// Training force models (learning/force/ForceModel.h) on joint-state logs, and the recordings they
// are trained and evaluated on.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "learning/force/ForceModel.h"

namespace viscera::learning {

// One recording: joint states and, when measured, the tip wrench (a force sensor) and Jacobians.
struct ForceRecording {
  std::string name;
  robot::JointStateLog joints;
  std::optional<robot::Series> wrench;    // t, Fx..Tz
  std::optional<robot::Series> jacobian;  // t, J11..J6n
};

// Reads a recording: a folder holding joints.csv (and, when present, wrench.csv and jacobian.csv)
// or a joint-state log file itself. `columns`: the joint log's column map (robot/force/ArmLogs.h).
ForceRecording readForceRecording(const std::string& path, int dof = 6, const std::string& columns = "");
// The recording at `rate`: joint states averaged over each new period (1 kHz -> 200 Hz), the wrench
// and Jacobian interpolated at the new times, over the span all of them cover.
ForceRecording resampleRecording(const ForceRecording& r, double rate);

struct ForceTrainSpec {
  std::string kind = "mlp";  // physical, mlp, snn, lstm, correction, direct
  double rate = 200;         // Hz the model works at
  int window = 0;            // 0: the kind's default (mlp, snn 1; lstm 10; correction 30; direct 10)
  int hidden = 0;            // 0: the kind's default (mlp, snn 100; lstm 64; correction 256; direct 100)
  int epochs = 0;            // 0: the kind's default
  int batch = 256;
  double learningRate = 1e-3;
  double weightDecay = 0;    // L2 penalty on the networks' weights
  double validation = 0.1;   // the last share of each recording, kept out of training
  int patience = 0;
  std::uint64_t seed = 1;
  std::string base;          // a base model's folder (correction: required; mlp/lstm: a residual over it)
  bool forces = true;        // direct: forces only (3 outputs) rather than the wrench (6)
};

struct ForceTrainReport {
  std::string line;  // one line for the terminal
};

// Trains (or, for "physical", identifies) a model on recordings already at spec.rate. Free-space
// kinds take every recording's measured efforts as free-space efforts; "direct" needs each
// recording's wrench. Throws Error for a kind it does not know or data that do not fit.
ForceModel trainForceModel(const ForceTrainSpec& spec, const std::vector<ForceRecording>& recordings,
                           const std::function<void(const ForceTrainReport&)>& progress = {});

// `rows` appended below the rows of `to` (which may be empty): samples of several recordings in one.
template <class Matrix>
void appendRows(Matrix& to, const Matrix& rows) {
  Matrix joined(to.rows() + rows.rows(), rows.cols());
  if (to.rows() > 0) joined.topRows(to.rows()) = to;
  joined.bottomRows(rows.rows()) = rows;
  to.swap(joined);
}

// The wrench series of a recording at its joint samples (samples x 6), or an Error without one.
Eigen::MatrixXd wrenchAtJoints(const ForceRecording& r);

}  // namespace viscera::learning
