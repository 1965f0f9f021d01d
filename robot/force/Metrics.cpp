#include "robot/force/Metrics.h"

#include <cmath>
#include <limits>

#include "core/Error.h"

namespace viscera::robot {

ErrorMeasures errorMeasures(const Eigen::MatrixXd& estimate, const Eigen::MatrixXd& truth) {
  if (estimate.rows() != truth.rows() || estimate.cols() != truth.cols() || truth.rows() == 0)
    throw Error("error measures: estimate and truth need the same, non-empty shape");
  const Eigen::Index m = truth.cols();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ErrorMeasures e{Eigen::VectorXd(m), Eigen::VectorXd(m), Eigen::VectorXd(m), Eigen::VectorXd(m)};
  for (Eigen::Index c = 0; c < m; ++c) {
    const double sq = (estimate.col(c) - truth.col(c)).squaredNorm();
    const double norm = truth.col(c).norm();
    e.range[c] = truth.col(c).maxCoeff() - truth.col(c).minCoeff();
    e.rmse[c] = std::sqrt(sq / static_cast<double>(truth.rows()));
    e.nrmse[c] = e.range[c] > 0 ? e.rmse[c] / e.range[c] : nan;
    e.rele[c] = norm > 0 ? std::sqrt(sq) / norm : nan;
  }
  return e;
}

}  // namespace viscera::robot
