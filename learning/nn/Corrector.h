// The learned correction (dissertation §4.3): a U-Net over a body's regular grid that maps the
// simulated nodes and the instrument to a per-node correction, trained so that the corrected surface
// meets measured point clouds. In 2D mode it sees and moves only the grid's face towards the camera
// (the observed vertices); in 3D mode every node. The instrument's position and velocity join at the
// bottleneck, as features of every cell. Corrections are limited to `maxCorrection` cells along each
// axis (tanh); fixed nodes are never moved.
//
// Training loss: the one-sided Chamfer distance from the measured cloud to the corrected boundary
// surface refined three times (bilinear on each face): the mean squared distance from each cloud
// point to its closest refined vertex. A model is a folder like the stepper's (config.json,
// weights.pt, mesh.bin), of kind "corrector".
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "learning/data/Pairs.h"
#include "learning/nn/Stepper.h"

namespace viscera::learning {

struct CorrectorArchitecture {
  bool threeD = false;        // false: the observed face only (2D U-Net)
  int width = 64;             // features of the first block; 2x and 4x in the next two
  double maxCorrection = 0.5; // cells along each axis
};

class Corrector {
 public:
  // What a backend implements (learning/nn/Backend.h).
  struct Impl {
    virtual ~Impl() = default;
    virtual void checkMesh(const RestMesh& mesh, const std::string& what) const = 0;
    virtual void save(const std::string& folder, const std::string& training) const = 0;
    virtual Eigen::Matrix3Xd correct(const Eigen::Matrix3Xd& x, const InstrumentInput& instrument) const = 0;
    virtual const std::vector<int>& movableNodes() const = 0;
    virtual const RestMesh& mesh() const = 0;
    virtual const GridShape& grid() const = 0;
    virtual const CorrectorArchitecture& architecture() const = 0;
    virtual const std::string& units() const = 0;
    virtual const std::string& training() const = 0;
    virtual std::int64_t parameters() const = 0;
    virtual Eigen::Matrix3Xd refinedSurface(const Eigen::Matrix3Xd& x) const = 0;
  };

  // A new network; its last layer starts at zero, so a new corrector changes nothing.
  Corrector(const RestMesh& mesh, const GridShape& grid, const Eigen::Vector3d& viewDirection,
            const CorrectorArchitecture& arch, const std::string& units, std::uint64_t seed);
  static Corrector load(const std::string& folder);
  explicit Corrector(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

  void checkMesh(const RestMesh& mesh, const std::string& what) const { impl_->checkMesh(mesh, what); }
  void save(const std::string& folder, const std::string& training) const { impl_->save(folder, training); }

  // The corrected nodes for simulated nodes `x` and the instrument then.
  Eigen::Matrix3Xd correct(const Eigen::Matrix3Xd& x, const InstrumentInput& instrument) const { return impl_->correct(x, instrument); }
  // The nodes the correction may move (2D: the observed face, fixed nodes left out).
  const std::vector<int>& movableNodes() const { return impl_->movableNodes(); }

  const RestMesh& mesh() const { return impl_->mesh(); }
  const GridShape& grid() const { return impl_->grid(); }
  const CorrectorArchitecture& architecture() const { return impl_->architecture(); }
  const std::string& units() const { return impl_->units(); }
  const std::string& training() const { return impl_->training(); }
  std::int64_t parameters() const { return impl_->parameters(); }
  // Points of the boundary surface refined three times, for nodes x (what the loss compares with).
  Eigen::Matrix3Xd refinedSurface(const Eigen::Matrix3Xd& x) const { return impl_->refinedSurface(x); }

  Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

// The one-sided Chamfer terms from `cloud` to `points`: the mean distance and the mean squared
// distance from each cloud point to its closest point (brute force; what the training minimises).
struct CloudDistance {
  double mean = 0, meanSquared = 0;
};
CloudDistance cloudToPoints(const Eigen::Matrix3Xf& cloud, const Eigen::Matrix3Xd& points);

struct CorrectorTrainOptions {
  std::vector<std::string> data;  // pair folders (one mesh)
  std::string out;
  CorrectorArchitecture architecture;
  int epochs = 40;
  int batch = 8;
  double learningRate = 1e-3;
  double validation = 0.2;   // the last share of each pair folder's frames, held out
  int maxPoints = 1000;      // cloud points per frame used in the loss (evenly chosen)
  std::uint64_t seed = 1;
  int threads = 0;
  bool resume = false;
  std::string command;
};
struct CorrectorEpochReport {
  int epoch = 0, epochs = 0;
  double trainLoss = 0;          // mean squared cloud -> refined surface distance (length^2)
  double heldOutBefore = 0;      // held-out mean cloud -> refined surface distance, uncorrected
  double heldOutAfter = 0;       // ... corrected
  double learningRate = 0, seconds = 0;
  bool best = false;
};
void trainCorrector(const CorrectorTrainOptions& options, const std::function<void(const CorrectorEpochReport&)>& progress);

// Per frame of a pair folder: the cloud's distance to the refined surface (and to the exact boundary
// surface) before and after the correction, and the model's time.
struct CorrectionEvaluation {
  std::vector<double> time, before, after, beforeSquared, afterSquared;
  double meanBefore = 0, meanAfter = 0, meanSquaredBefore = 0, meanSquaredAfter = 0, msPerFrame = 0;
  // The same frames' mean exact distance from the cloud to the body's boundary surface (closest
  // points on its triangles, as dataset scores measure it), without and with the correction.
  std::vector<double> surfaceBefore, surfaceAfter;
  double meanSurfaceBefore = 0, meanSurfaceAfter = 0;
  // Standard error of the mean per-frame improvement (before - after): the noise of the comparison.
  double improvementSe = 0;
};
CorrectionEvaluation evaluateCorrector(const Corrector& model, const PairSet& pairs, int maxPoints = 0);

}  // namespace viscera::learning
