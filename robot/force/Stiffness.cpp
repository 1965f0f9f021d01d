#include "robot/force/Stiffness.h"

#include <algorithm>
#include <vector>

#include "core/Error.h"

namespace viscera::robot {

StiffnessFit identifyStiffness(const Eigen::MatrixXd& tips, const Eigen::MatrixXd& forces, double threshold) {
  if (tips.rows() != forces.rows() || tips.cols() != 3 || forces.cols() != 3)
    throw Error("stiffness: tips and forces need 3 columns and the same samples");
  if (threshold <= 0 && forces.rows() > 0) {
    std::vector<double> norms(static_cast<size_t>(forces.rows()));
    for (Eigen::Index i = 0; i < forces.rows(); ++i) norms[static_cast<size_t>(i)] = forces.row(i).norm();
    const size_t k = static_cast<size_t>(0.99 * static_cast<double>(norms.size() - 1));
    std::nth_element(norms.begin(), norms.begin() + static_cast<std::ptrdiff_t>(k), norms.end());
    threshold = 0.2 * norms[k];
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::vector<Eigen::Index> contact;
  for (Eigen::Index i = 0; i < forces.rows(); ++i)
    if (forces.row(i).norm() > threshold) {
      sum += forces.row(i).transpose();
      contact.push_back(i);
    }
  if (contact.size() < 10 || sum.norm() == 0)
    throw Error("stiffness: " + std::to_string(contact.size()) + " samples with a force above " + std::to_string(threshold) +
                " N; at least 10 are needed");
  StiffnessFit fit;
  fit.direction = sum.normalized();
  // Least squares F = k x + b over the contact samples (x, F along the direction).
  double sx = 0, sf = 0, sxx = 0, sxf = 0, sff = 0;
  for (Eigen::Index i : contact) {
    const double x = tips.row(i).dot(fit.direction), f = forces.row(i).dot(fit.direction);
    sx += x, sf += f, sxx += x * x, sxf += x * f, sff += f * f;
  }
  const double n = static_cast<double>(contact.size());
  const double vx = sxx - sx * sx / n, cxf = sxf - sx * sf / n, vf = sff - sf * sf / n;
  if (!(vx > 0)) throw Error("stiffness: the tip did not move along the force in contact");
  fit.stiffness = cxf / vx;
  const double b = (sf - fit.stiffness * sx) / n;
  fit.intercept = fit.stiffness != 0 ? -b / fit.stiffness : 0;
  fit.samples = static_cast<int>(contact.size());
  fit.r2 = vf > 0 ? cxf * cxf / (vx * vf) : 0;
  return fit;
}

}  // namespace viscera::robot
