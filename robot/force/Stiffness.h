// Stiffness identification from force against tool displacement (dissertation §2.4.7): in each
// contact (a run of samples with a force above a threshold), the slope of the force along its mean
// direction against the tip's displacement along it; the stiffness is the median over contacts.
#pragma once

#include <Eigen/Core>

namespace viscera::robot {

struct StiffnessFit {
  double stiffness = 0;   // N/m, the median slope
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();  // unit, the mean force's direction in contact
  int episodes = 0;       // contacts fitted
  int samples = 0;        // in those contacts
  double r2 = 0;          // median of the fits' coefficients of determination
  double threshold = 0;   // N, the contact threshold used
};

// tips, forces: samples x 3 (m, N; the force the tool applies). Contact: |F| above `threshold`
// (N); with threshold 0, above a fifth of the 99th percentile of |F| (above an estimate's noise in
// free motion). Contacts shorter than 10 samples, or whose peak stays below half the 99th
// percentile of |F| (an estimate's noise crossing the threshold), are left out. Throws
// viscera::Error when no contact remains.
StiffnessFit identifyStiffness(const Eigen::MatrixXd& tips, const Eigen::MatrixXd& forces, double threshold);

}  // namespace viscera::robot
