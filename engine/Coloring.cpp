#include "engine/Coloring.h"

#include <algorithm>
#include <cstdint>

namespace viscera {

ElementColoring colorElements(const Eigen::Ref<const Eigen::MatrixXi>& el, int nodeCount, int run) {
  ElementColoring result;
  result.run = run = std::max(run, 1);
  std::vector<std::vector<int>>& colors = result.colors;
  // used[node] holds the colors already taken around that node, 64 per word.
  std::vector<std::vector<uint64_t>> used(nodeCount);
  const int count = static_cast<int>(el.cols());
  for (int first = 0; first < count; first += run) {
    const int last = std::min(first + run, count);
    // Greedy: the lowest color free at every node of the run.
    int c = 0;
    for (;; ++c) {
      const size_t w = c / 64;
      const uint64_t bit = uint64_t(1) << (c % 64);
      bool taken = false;
      for (int e = first; e < last && !taken; ++e)
        for (int k = 0; k < el.rows() && !taken; ++k) {
          const auto& u = used[el(k, e)];
          taken = w < u.size() && (u[w] & bit);
        }
      if (!taken) break;
    }
    const size_t w = c / 64;
    for (int e = first; e < last; ++e)
      for (int k = 0; k < el.rows(); ++k) {
        auto& u = used[el(k, e)];
        if (u.size() <= w) u.resize(w + 1, 0);
        u[w] |= uint64_t(1) << (c % 64);
      }
    if (static_cast<int>(colors.size()) <= c) colors.resize(c + 1);
    for (int e = first; e < last; ++e) colors[c].push_back(e);
  }
  return result;
}

}  // namespace viscera
