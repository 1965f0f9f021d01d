// Prescribed motions of chosen nodes. SOFA's patch-test constraints: AffineMovementProjectiveConstraint
// (the nodes follow a rotation and translation) and PatchTestMovementProjectiveConstraint (the
// nodes follow the bilinear or trilinear blend of their region's corner displacements). Both move
// the nodes linearly in time from their initial positions, between beginConstraintTime and
// endConstraintTime, and hold them at the end; the nodes are out of the solve (as fixed nodes)
// and their positions are set before each step. OscillatorProjectiveConstraint moves nodes on
// sines, set after each solve with their velocities, as SOFA projects them.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/Registry.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "engine/mechanics/MechanicalObject.h"

namespace viscera {

namespace {

class MovementConstraint : public Component, public ProjectiveConstraint, public Driver {
 public:
  using Component::Component;
  MechanicalObject& mstate() const override { return *state_; }
  const std::vector<int>& fixedNodes() const override { return nodes_; }
  bool prescribesMotion() const override { return true; }
  void init() override {
    state_ = &contextState(*this);
    nodes_ = linkedInts("indices");
    const int n = state_->size();
    for (const char* list : {"indices", "meshIndices"})
      for (int i : list == std::string("indices") ? nodes_ : linkedInts(list))
        if (i < 0 || i >= n)
          throw error(list, "node " + std::to_string(i) + " is out of range (the MechanicalObject has " +
                                std::to_string(n) + " nodes)");
    begin_ = attrs_.real("beginConstraintTime");
    end_ = attrs_.real("endConstraintTime");
    if (!(end_ > begin_))
      throw error("endConstraintTime", "must be after beginConstraintTime (" + std::to_string(begin_) + ")");
    start_.resize(3, static_cast<Eigen::Index>(nodes_.size()));
    for (size_t k = 0; k < nodes_.size(); ++k) start_.col(static_cast<Eigen::Index>(k)) = state_->xInit.col(nodes_[k]);
    final_ = finalPositions(start_);
  }
  // As SOFA's: the positions at the end of a step are those of the step's start time, moved
  // linearly from the initial ones to the final ones between the begin and end times.
  void drive(State& s, double t, double h) const override {
    const double at = t - h;
    const double a = at <= begin_ ? 0.0 : at >= end_ ? 1.0 : (at - begin_) / (end_ - begin_);
    MechanicalObject::Live& l = state_->live(s);
    for (size_t k = 0; k < nodes_.size(); ++k) {
      const Eigen::Index c = static_cast<Eigen::Index>(k);
      l.x.col(nodes_[k]) = start_.col(c) + a * (final_.col(c) - start_.col(c));
      l.v.col(nodes_[k]).setZero();
    }
  }

 protected:
  // Where the nodes (initially at X, one column each) are at the end time.
  virtual Eigen::Matrix3Xd finalPositions(const Eigen::Matrix3Xd& X) = 0;

  MechanicalObject* state_ = nullptr;

 private:
  std::vector<int> nodes_;
  double begin_ = 0, end_ = 0;
  Eigen::Matrix3Xd start_, final_;
};

// Numbers of a matrix written as SOFA writes it, "[a b c,d e f,g h i]", or plainly.
std::vector<double> matrixNumbers(const std::string& text) {
  std::string plain = text;
  for (char& c : plain)
    if (c == '[' || c == ']' || c == ',') c = ' ';
  std::istringstream in(plain);
  std::vector<double> v;
  for (std::string word; in >> word;) {
    size_t used = 0;
    double d = 0;
    try {
      d = std::stod(word, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != word.size()) throw std::invalid_argument("'" + word + "' is not a number");
    v.push_back(d);
  }
  return v;
}

class AffineMovement : public MovementConstraint {
 public:
  using MovementConstraint::MovementConstraint;

 protected:
  Eigen::Matrix3Xd finalPositions(const Eigen::Matrix3Xd& X) override {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    if (attrs_.isSet("rotation")) {
      std::vector<double> m;
      try {
        m = matrixNumbers(attrs_.str("rotation"));
      } catch (const std::invalid_argument& e) {
        throw error("rotation", e.what());
      }
      if (m.size() != 9) throw error("rotation", "needs 9 numbers (a 3x3 matrix, row by row), got " + std::to_string(m.size()));
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) R(r, c) = m[static_cast<size_t>(3 * r + c)];
    }
    const auto& t = attrs_.reals("translation");
    return (R * X).colwise() + Eigen::Vector3d(t[0], t[1], t[2]);
  }
};

class PatchTestMovement : public MovementConstraint {
 public:
  using MovementConstraint::MovementConstraint;

 protected:
  Eigen::Matrix3Xd finalPositions(const Eigen::Matrix3Xd& X) override {
    // The region's corners: the bounding box of the constrained points (default: the nodes).
    Eigen::Matrix3Xd P = X;
    if (attrs_.isSet("constrainedPoints")) {
      const auto p = linkedReals("constrainedPoints");
      P = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, static_cast<Eigen::Index>(p.size() / 3));
    }
    if (P.cols() == 0) throw error("constrainedPoints", "no points to find the region's corners from");
    const Eigen::Vector3d lo = P.rowwise().minCoeff(), hi = P.rowwise().maxCoeff();
    const bool volume = hi.z() > lo.z();  // SOFA: 3D when the points do not share one z
    const auto& m = attrs_.reals("cornerMovements");
    const size_t corners = volume ? 8 : 4;
    if (m.size() != 3 * corners)
      throw error("cornerMovements", std::string("needs ") + std::to_string(corners) + " displacements (x y z each) for " +
                                         (volume ? "a volume's 8 corners" : "a flat region's 4 corners") + ", got " +
                                         std::to_string(m.size()) + " numbers");
    for (int a = 0; a < (volume ? 3 : 2); ++a)
      if (!(hi[a] > lo[a]))
        throw error("constrainedPoints", "the points span no length along axis " + std::to_string(a));
    auto move = [&](size_t k) -> Eigen::Vector3d { return Eigen::Vector3d(m[3 * k], m[3 * k + 1], m[3 * k + 2]); };
    // Corners 0..3 counter-clockwise from (min x, min y) at min z, 4..7 the same at max z.
    auto bilinear = [&](size_t first, double a, double b) -> Eigen::Vector3d {  // evaluated, not an expression
      return ((1 - a) * (1 - b)) * move(first) + (a * (1 - b)) * move(first + 1) + (a * b) * move(first + 2) +
             ((1 - a) * b) * move(first + 3);
    };
    Eigen::Matrix3Xd out = X;
    for (Eigen::Index i = 0; i < X.cols(); ++i) {
      const double a = (X(0, i) - lo.x()) / (hi.x() - lo.x()), b = (X(1, i) - lo.y()) / (hi.y() - lo.y());
      Eigen::Vector3d d = bilinear(0, a, b);
      if (volume) {
        const double c = (X(2, i) - lo.z()) / (hi.z() - lo.z());
        d = (1 - c) * d + c * bilinear(4, a, b);
      }
      out.col(i) += d;
    }
    return out;
  }
};

// x = mean + A sin(w t + phase), v = A w cos(w t + phase) for each listed node.
class Oscillator : public Component, public ProjectiveConstraint, public Correction {
 public:
  using Component::Component;
  MechanicalObject& mstate() const override { return *state_; }
  const std::vector<int>& fixedNodes() const override { return nodes_; }
  bool prescribesMotion() const override { return true; }
  void init() override {
    state_ = &contextState(*this);
    const auto& o = attrs_.reals("oscillators");
    for (size_t k = 0; k + 9 <= o.size(); k += 9) {
      const double index = o[k];
      if (!(index >= 0 && index < state_->size()) || index != std::floor(index))
        throw error("oscillators", "entry " + std::to_string(k / 9) + ": node " + formatNumber(index) +
                                       " is not a node of the MechanicalObject (it has " + std::to_string(state_->size()) + ")");
      Wave w;
      w.node = static_cast<int>(index);
      w.mean = Eigen::Vector3d(o[k + 1], o[k + 2], o[k + 3]);
      w.amplitude = Eigen::Vector3d(o[k + 4], o[k + 5], o[k + 6]);
      w.pulsation = o[k + 7];
      w.phase = o[k + 8];
      waves_.push_back(w);
      nodes_.push_back(w.node);
    }
  }
  // After the solve, as SOFA's projection: the positions and velocities of the step's start time
  // (the time SOFA's solvers run at).
  void correct(State& s, double t, int) const override {
    const double at = t - scene().dt();
    MechanicalObject::Live& l = state_->live(s);
    for (const Wave& w : waves_) {
      l.x.col(w.node) = w.mean + w.amplitude * std::sin(w.pulsation * at + w.phase);
      l.v.col(w.node) = w.amplitude * (w.pulsation * std::cos(w.pulsation * at + w.phase));
    }
  }

 private:
  struct Wave {
    int node = 0;
    Eigen::Vector3d mean, amplitude;
    double pulsation = 0, phase = 0;
  };
  MechanicalObject* state_ = nullptr;
  std::vector<Wave> waves_;
  std::vector<int> nodes_;
};

void addMovementAttributes(ComponentSpec& s) {
  s.add(AttrSpec::ints("indices").req().atLeast(0).linked().help("the moved nodes (or a link such as @box.indices)"));
  s.add(AttrSpec::ints("meshIndices").def("").atLeast(0).linked().help(
      "SOFA's list of the mesh's nodes, whose final positions it reports; checked, not used by the motion"));
  s.add(AttrSpec::real("beginConstraintTime").def("0").atLeast(0).unit(Dimension::time()).help("when the motion starts"));
  s.add(AttrSpec::real("endConstraintTime").def("20").unit(Dimension::time()).help("when the nodes reach their final positions (held after)"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
}

}  // namespace

void registerMovementConstraints(Registry& r) {
  {
    ComponentSpec s;
    s.name = "AffineMovementProjectiveConstraint";
    s.aliases = {"AffineMovementConstraint"};
    s.category = "constraint";
    s.doc = "Moves nodes to R x0 + t (x0: their initial positions; the rotation about the origin), linearly in time "
            "between beginConstraintTime and endConstraintTime, and holds them there after; before, they stay. The "
            "nodes are out of the solve, as fixed nodes, with zero velocity. As SOFA's, the positions at the end of a "
            "step are those of the step's start time. SOFA's default rotation is the zero matrix, which sends every "
            "node to t; here it is the identity.";
    addMovementAttributes(s);
    s.add(AttrSpec::string("rotation").help("3x3 rotation matrix, row by row, as SOFA writes it (\"[1 0 0,0 1 0,0 0 1]\") or plain numbers"));
    s.add(AttrSpec::reals("translation", 3).def("0 0 0").unit(Dimension::length()).help("translation t"));
    s.factory = [](BuildContext& c) { return std::make_unique<AffineMovement>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "PatchTestMovementProjectiveConstraint";
    s.aliases = {"PatchTestMovementConstraint"};
    s.category = "constraint";
    s.doc = "The patch test's boundary motion: each node moves by the bilinear blend of the displacements of the "
            "four corners of the region (its bounding box; trilinear with eight corners when the points do not share "
            "one z), linearly in time between beginConstraintTime and endConstraintTime, and is held there after. "
            "Corners 0-3 go counter-clockwise from (min x, min y) at min z; 4-7 are the same at max z. The nodes are "
            "out of the solve, as fixed nodes. SOFA finds the corners by a scan that can depend on the points' order; "
            "here they are the bounding box's.";
    addMovementAttributes(s);
    s.add(AttrSpec::reals("constrainedPoints").multipleOf(3).unit(Dimension::length()).linked().help(
        "the points whose bounding box gives the corners (default: the moved nodes), e.g. @box.pointsInROI"));
    s.add(AttrSpec::reals("cornerMovements").req().multipleOf(3).unit(Dimension::length()).help(
        "the corners' displacements, x y z each: 4 for a flat region, 8 for a volume"));
    s.factory = [](BuildContext& c) { return std::make_unique<PatchTestMovement>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "OscillatorProjectiveConstraint";
    s.aliases = {"OscillatorConstraint"};
    s.category = "constraint";
    s.doc = "Moves nodes on sines: x = mean + amplitude sin(pulsation t + phase), with velocity amplitude pulsation "
            "cos(pulsation t + phase), per listed node. The nodes are out of the solve, as fixed nodes; after each "
            "solve they are put at the values of the step's start time, as SOFA projects them.";
    s.add(AttrSpec::reals("oscillators").req().multipleOf(9).help(
        "per node: index, mean (x y z), amplitude (x y z), pulsation (rad/s), phase (rad)"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.factory = [](BuildContext& c) { return std::make_unique<Oscillator>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
