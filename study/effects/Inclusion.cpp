// `inclusion`: the tissue holds a stiffer (or softer) region, e.g. a tumour. Five parameters: the
// centre of a sphere, its radius and the ratio of its Young's modulus to the tissue's. Written as
// SOFA writes heterogeneous tissue: a per-element youngModulus on the TetrahedronFEMForceField.
//
// Each element's modulus is E_e (1 + (ratio - 1) phi_e), phi_e the share of the element inside the
// sphere, estimated on 15 points of the element with a boundary smoothed over a quarter of its
// size. A hard in/out test (SphereROI) makes the score a staircase in the centre and radius that
// no minimiser can walk; the share is smooth in both.
#include <algorithm>
#include <cmath>
#include <random>

#include "study/effects/Effect.h"

namespace viscera::study {

namespace {

class Inclusion : public Effect {
 public:
  std::string key() const override { return "inclusion"; }
  std::string what() const override {
    return "a sphere of tissue (centre, radius) whose Young's modulus is `ratio` times the rest's";
  }
  std::vector<EffectParam> params(const AuditScene& s) const override {
    SceneDesc d = s.desc;
    const auto fems = elementsOf(d.root, "TetrahedronFEMForceField");
    if (fems.empty() || fems.size() != s.femElements.size() || s.tissueBox.isEmpty()) return {};
    for (ElementDesc* f : fems)
      if (isLink(*f, "youngModulus")) return {};  // set by engines: not ours to rewrite
    const Eigen::Vector3d lo = s.tissueBox.min(), hi = s.tissueBox.max();
    const double small = s.tissueBox.sizes().minCoeff();
    const double r0 = 0.25 * small;
    const Eigen::Vector3d c0 = start(s, r0);
    return {{"x", lo.x(), hi.x(), c0.x(), Scale::Linear, "scene length"},
            {"y", lo.y(), hi.y(), c0.y(), Scale::Linear, "scene length"},
            {"z", lo.z(), hi.z(), c0.z(), Scale::Linear, "scene length"},
            {"radius", 0.1 * small, 0.5 * small, r0, Scale::Linear, "scene length"},
            {"ratio", 0.1, 10.0, 1.0, Scale::Log, ""}};
  }
  // Ranking needs how much stiffer and how large; the centre starts where the force was missing.
  std::vector<size_t> coarseParams() const override { return {4, 3}; }
  // A sphere of a third of the tissue's smallest size, somewhere in the middle half of its box,
  // 1 + 3 x strength times stiffer.
  std::vector<double> plant(const AuditScene& s, double strength, unsigned seed) const override {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.25, 0.75);
    const Eigen::Vector3d lo = s.tissueBox.min(), size = s.tissueBox.sizes();
    return {lo.x() + u(rng) * size.x(), lo.y() + u(rng) * size.y(), lo.z() + u(rng) * size.z(), size.minCoeff() / 3,
            1 + 3 * strength};
  }
  void apply(SceneDesc& desc, const std::vector<double>& v, const AuditScene& s) const override {
    const Eigen::Vector3d c(v.at(0), v.at(1), v.at(2));
    const double r = v.at(3), ratio = v.at(4);
    if (ratio == 1) return;  // as stiff as the rest: no change (and the audit need not replay it)
    const auto fems = elementsOf(desc.root, "TetrahedronFEMForceField");
    for (size_t f = 0; f < fems.size() && f < s.femElements.size(); ++f) {
      const Eigen::Matrix3Xd& X = s.femElements[f];
      const Eigen::Index n = X.cols() / 4;
      const std::vector<double> E = realsOf(*fems[f], "youngModulus", s.units);
      std::string text;
      text.reserve(static_cast<size_t>(n) * 12);
      for (Eigen::Index e = 0; e < n; ++e) {
        const double phi = share(X.middleCols<4>(4 * e), c, r);
        const double base = E.size() == 1 ? E[0] : E.at(static_cast<size_t>(e));
        text += (e ? " " : "") + numberText(base * (1 + (ratio - 1) * phi));
      }
      fems[f]->set("youngModulus", text);
      noteChange(*fems[f], key(),
                 "centre (" + numberText(c.x()) + " " + numberText(c.y()) + " " + numberText(c.z()) + "), radius " +
                     numberText(r) + ", Young's modulus ratio " + numberText(ratio) +
                     " (per element, by the share of the element inside the sphere)");
    }
  }

 private:
  // The share of a tetrahedron (four vertex columns) inside the sphere: the mean of a smooth step
  // over its vertices, edge midpoints, centroid and the midpoints from the centroid to each vertex.
  static double share(const Eigen::Matrix<double, 3, 4>& V, const Eigen::Vector3d& c, double r) {
    const Eigen::Vector3d g = V.rowwise().mean();
    double h = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) h = std::max(h, (V.col(a) - V.col(b)).norm());
    const double w = std::max(0.25 * h, 1e-12);
    double sum = 0;
    int count = 0;
    auto add = [&](const Eigen::Vector3d& p) {
      sum += 1 / (1 + std::exp(-(r - (p - c).norm()) / w));
      ++count;
    };
    add(g);
    for (int a = 0; a < 4; ++a) {
      add(V.col(a));
      add(0.5 * (V.col(a) + g));
      for (int b = a + 1; b < 4; ++b) add(0.5 * (V.col(a) + V.col(b)));
    }
    return sum / count;
  }

  // Where to start looking: below the places the instrument felt more force than the scene gave
  // (their mean, weighted by the excess squared), kept a radius inside the tissue; the tissue's
  // centre when the data hold no such excess.
  static Eigen::Vector3d start(const AuditScene& s, double r) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double weight = 0;
    for (const auto& t : s.touches)
      if (t.excess > 0) {
        sum += t.excess * t.excess * t.at;
        weight += t.excess * t.excess;
      }
    const Eigen::Vector3d lo = s.tissueBox.min(), hi = s.tissueBox.max();
    Eigen::Vector3d c = weight > 0 ? Eigen::Vector3d(sum / weight) : s.tissueBox.center();
    for (int a = 0; a < 3; ++a) c[a] = lo[a] + r < hi[a] - r ? std::clamp(c[a], lo[a] + r, hi[a] - r) : 0.5 * (lo[a] + hi[a]);
    return c;
  }
};

}  // namespace

std::unique_ptr<Effect> makeInclusion() { return std::make_unique<Inclusion>(); }

}  // namespace viscera::study
