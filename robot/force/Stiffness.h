// Stiffness identification from force against tool displacement (dissertation §2.4.7): the slope of
// the force along the pressing direction against the tip's displacement along it, over the samples
// in contact.
#pragma once

#include <Eigen/Core>

namespace viscera::robot {

struct StiffnessFit {
  double stiffness = 0;   // N/m, the slope
  double intercept = 0;   // m: the displacement where the fitted force is zero (the surface)
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();  // unit, the mean force's direction in contact
  int samples = 0;        // in contact (force along the direction above the threshold)
  double r2 = 0;          // of the linear fit
};

// tips, forces: samples x 3 (m, N; the force the tool applies). Contact: |F| above `threshold`
// (N); with threshold 0, above a fifth of the 99th percentile of |F| (above an estimate's noise in
// free motion). Throws viscera::Error when fewer than 10 samples are in contact.
StiffnessFit identifyStiffness(const Eigen::MatrixXd& tips, const Eigen::MatrixXd& forces, double threshold);

}  // namespace viscera::robot
