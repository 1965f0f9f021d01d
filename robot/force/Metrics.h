// Error measures of force estimation (dissertation §2.4.4), per column of a series:
//   NRMSE (Eq. 2.7) = RMS(estimate - truth) / (max(truth) - min(truth))
//   RelE  (Eq. 2.8) = ||estimate - truth||_2 / ||truth||_2
#pragma once

#include <Eigen/Core>

namespace viscera::robot {

struct ErrorMeasures {
  Eigen::VectorXd rmse, nrmse, rele, range;  // one entry per column; NaN where undefined (zero range / norm)
};

// estimate and truth: samples x columns, the same shape (viscera::Error otherwise).
ErrorMeasures errorMeasures(const Eigen::MatrixXd& estimate, const Eigen::MatrixXd& truth);

}  // namespace viscera::robot
