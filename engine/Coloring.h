// Coloring of elements so that elements of one color share no node: each color can be processed
// in parallel and results do not depend on the thread count. Elements are colored in runs of
// consecutive elements (a run takes one color and one thread), so that each thread walks
// neighbouring elements in mesh order and its scattered writes stay in cache: with single
// elements colored, one color spreads over the whole mesh, and the gel phantom's step took 1.4x
// as long. Runs of 256 (fewer colors, fewer sweeps over the matrix per assembly) made its one-
// thread step 5 % faster than runs of 32; longer runs gained nothing more.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace viscera {

struct ElementColoring {
  int run = 1;                           // elements per run
  std::vector<std::vector<int>> colors;  // element ids by color: whole runs, in increasing order
};

// `elements` is k x #elements of node indices.
ElementColoring colorElements(const Eigen::Ref<const Eigen::MatrixXi>& elements, int nodeCount, int run = 256);

// Runs fn(element) for every element, color by color, in parallel over the runs of a color.
template <class Fn>
void forEachColored(const ElementColoring& coloring, Fn&& fn);

// Runs fn(first, count) for every run, the consecutive elements first .. first + count - 1,
// color by color, in parallel over the runs of a color.
template <class Fn>
void forEachColoredRun(const ElementColoring& coloring, Fn&& fn);

}  // namespace viscera

#include <tbb/parallel_for.h>

template <class Fn>
void viscera::forEachColoredRun(const ElementColoring& coloring, Fn&& fn) {
  const size_t run = coloring.run;
  for (const auto& c : coloring.colors) {
    const size_t runs = (c.size() + run - 1) / run;
    auto body = [&](size_t k) { fn(c[k * run], static_cast<int>(std::min(run, c.size() - k * run))); };
    if (c.size() < 256) {
      for (size_t k = 0; k < runs; ++k) body(k);
      continue;
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, runs, (128 + run - 1) / run), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t k = r.begin(); k < r.end(); ++k) body(k);
    });
  }
}

template <class Fn>
void viscera::forEachColored(const ElementColoring& coloring, Fn&& fn) {
  forEachColoredRun(coloring, [&](int first, int count) {
    for (int e = first; e < first + count; ++e) fn(e);
  });
}
