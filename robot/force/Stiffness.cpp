#include "robot/force/Stiffness.h"

#include <algorithm>
#include <vector>

#include "core/Error.h"

namespace viscera::robot {

StiffnessFit identifyStiffness(const Eigen::MatrixXd& tips, const Eigen::MatrixXd& forces, double threshold) {
  if (tips.rows() != forces.rows() || tips.cols() != 3 || forces.cols() != 3)
    throw Error("stiffness: tips and forces need 3 columns and the same samples");
  const Eigen::Index n = forces.rows();
  double p99 = 0;
  if (n > 0) {
    std::vector<double> norms(static_cast<size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i) norms[static_cast<size_t>(i)] = forces.row(i).norm();
    const size_t k = static_cast<size_t>(0.99 * static_cast<double>(norms.size() - 1));
    std::nth_element(norms.begin(), norms.begin() + static_cast<std::ptrdiff_t>(k), norms.end());
    p99 = norms[k];
  }
  if (threshold <= 0) threshold = 0.2 * p99;
  // Contact episodes: runs of samples above the threshold. Each palpation presses a different spot,
  // whose surface sits at another displacement, so each gets its own line; the stiffness is the
  // median of their slopes.
  StiffnessFit fit;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::vector<double> slopes, r2s;
  constexpr Eigen::Index minEpisode = 10;
  for (Eigen::Index i = 0; i < n;) {
    if (!(forces.row(i).norm() > threshold)) {
      ++i;
      continue;
    }
    Eigen::Index end = i;
    double peak = 0;
    for (; end < n && forces.row(end).norm() > threshold; ++end) peak = std::max(peak, forces.row(end).norm());
    // A press, not a blip of an estimate's noise above the threshold: it reaches half the typical peak.
    if (end - i >= minEpisode && peak >= 0.5 * p99) {
      const Eigen::Vector3d d = forces.middleRows(i, end - i).colwise().sum().transpose().normalized();
      double sx = 0, sf = 0, sxx = 0, sxf = 0, sff = 0;
      for (Eigen::Index k = i; k < end; ++k) {
        const double x = tips.row(k).dot(d), f = forces.row(k).dot(d);
        sx += x, sf += f, sxx += x * x, sxf += x * f, sff += f * f;
      }
      const double m = static_cast<double>(end - i);
      const double vx = sxx - sx * sx / m, cxf = sxf - sx * sf / m, vf = sff - sf * sf / m;
      if (vx > 0) {
        slopes.push_back(cxf / vx);
        r2s.push_back(vf > 0 ? cxf * cxf / (vx * vf) : 0);
        sum += forces.middleRows(i, end - i).colwise().sum().transpose();
        fit.samples += static_cast<int>(end - i);
      }
    }
    i = end;
  }
  if (slopes.empty())
    throw Error("stiffness: no contact of at least " + std::to_string(minEpisode) + " samples with a force above " +
                std::to_string(threshold) + " N in which the tool moved");
  fit.episodes = static_cast<int>(slopes.size());
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t h = v.size() / 2;
    return v.size() % 2 ? v[h] : (v[h - 1] + v[h]) / 2;
  };
  fit.stiffness = median(slopes);
  fit.r2 = median(r2s);
  fit.direction = sum.normalized();
  fit.threshold = threshold;
  return fit;
}

}  // namespace viscera::robot
