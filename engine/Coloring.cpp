#include "engine/Coloring.h"

#include <cstdint>

namespace viscera {

std::vector<std::vector<int>> colorElements(const Eigen::Ref<const Eigen::MatrixXi>& el, int nodeCount) {
  std::vector<std::vector<int>> colors;
  // used[node] holds the colors already taken around that node, 64 per word.
  std::vector<std::vector<uint64_t>> used(nodeCount);
  for (int e = 0; e < el.cols(); ++e) {
    int c = 0;
    for (;; ++c) {
      const size_t w = c / 64;
      const uint64_t bit = uint64_t(1) << (c % 64);
      bool taken = false;
      for (int k = 0; k < el.rows() && !taken; ++k) {
        const auto& u = used[el(k, e)];
        taken = w < u.size() && (u[w] & bit);
      }
      if (!taken) break;
    }
    const size_t w = c / 64;
    for (int k = 0; k < el.rows(); ++k) {
      auto& u = used[el(k, e)];
      if (u.size() <= w) u.resize(w + 1, 0);
      u[w] |= uint64_t(1) << (c % 64);
    }
    if (static_cast<int>(colors.size()) <= c) colors.resize(c + 1);
    colors[c].push_back(e);
  }
  return colors;
}

}  // namespace viscera
