// Greedy coloring of elements so that elements of one color share no node: each color can be
// processed in parallel and results do not depend on the thread count.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace viscera {

// `elements` is k x #elements of node indices; returns element ids grouped by color.
std::vector<std::vector<int>> colorElements(const Eigen::Ref<const Eigen::MatrixXi>& elements, int nodeCount);

// Runs fn(element) for every element, color by color, in parallel within a color.
template <class Fn>
void forEachColored(const std::vector<std::vector<int>>& colors, Fn&& fn);

}  // namespace viscera

#include <tbb/parallel_for.h>

template <class Fn>
void viscera::forEachColored(const std::vector<std::vector<int>>& colors, Fn&& fn) {
  for (const auto& c : colors) {
    if (c.size() < 256) {
      for (int e : c) fn(e);
      continue;
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, c.size(), 128), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t k = r.begin(); k < r.end(); ++k) fn(c[k]);
    });
  }
}
