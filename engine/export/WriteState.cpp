// WriteState (SOFA's): the state of the node's MechanicalObject (Vec3d or Rigid3d) at chosen times, in SOFA's dump
// format (io/scene/StateDump.h), which its regression references use and `viscera sofa-suite`
// reads. Frames are written as the run goes into a temporary file that takes the dump's name at
// the end of the run (also after a divergence, with the good frames).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/StateDump.h"

namespace viscera {

namespace {

class WriteState : public Component, public Observer {
 public:
  using Component::Component;
  void init() override {
    findState();
    period_ = attrs_.real("period");
    times_ = attrs_.reals("time");
    if (times_.empty()) throw error("time", "needs at least one time to write at");
    for (size_t k = 1; k < times_.size(); ++k)
      if (!(times_[k] > times_[k - 1])) throw error("time", "must increase");
    if (period_ > 0 && times_.size() > 1) throw error("period", "goes with one start `time`, not a list");
    if (!attrs_.boolean("writeX") && !attrs_.boolean("writeX0") && !attrs_.boolean("writeV") && !attrs_.boolean("writeF"))
      throw error("writeX", "nothing to write: set writeX, writeX0, writeV or writeF");
  }
  void begin(const State& s, double t) override {
    const std::string name = attrs_.str("filename");
    if (scene().escapesOutputFolder(name))
      throw error("filename", "'" + name + "' would be written outside the output folder (--out); give a name inside it");
    path_ = scene().outputPath(name);
    std::error_code ec;
    const std::filesystem::path dir = std::filesystem::path(path_).parent_path();
    if (!dir.empty()) std::filesystem::create_directories(dir, ec);
    writer_ = std::make_unique<io::StateDumpWriter>(path_);
    next_ = 0;
    maybeWrite(s, t);
  }
  void observe(const State& s, double t, int) override { maybeWrite(s, t); }
  void end(const State&, double, int) override { flush(); }
  void diverged(const State&, double, int) override { flush(); }

 private:
  // The k-th time to write at: the listed times, or the first one and then every period.
  double timeAt(size_t k) const {
    if (period_ > 0) return times_.front() + static_cast<double>(k) * period_;
    return k < times_.size() ? times_[k] : INFINITY;
  }
  void maybeWrite(const State& s, double t) {
    // Half a step's tolerance: a time falls on the step whose end is nearest.
    const double slack = 0.5 * scene().dt();
    if (!(t + slack >= timeAt(next_))) return;
    while (t + slack >= timeAt(next_)) ++next_;
    char head[64];
    std::snprintf(head, sizeof head, "T= %.17g\n", t);
    std::string text = head;
    auto line = [&](const char* key, const auto& m) {
      std::ostringstream out;
      out.precision(17);
      out << "  " << key << "=";
      for (Eigen::Index i = 0; i < m.size(); ++i) out << ' ' << m.data()[i];
      text += out.str() + "\n";
    };
    if (rigid_) {
      // SOFA's Rigid3 coordinates: position then quaternion (x y z w); velocities: linear then angular.
      const RigidObject::Live& b = rigid_->live(s);
      if (attrs_.boolean("writeX")) line("X", pose(b.p, b.q));
      if (attrs_.boolean("writeX0")) line("X0", pose(rigid_->p0, rigid_->q0));
      if (attrs_.boolean("writeV")) line("V", (Eigen::Matrix<double, 3, 2>() << b.v, b.w).finished());
    } else {
      if (attrs_.boolean("writeX")) line("X", state_->x(s));
      if (attrs_.boolean("writeX0")) line("X0", state_->x0);
      if (attrs_.boolean("writeV")) line("V", state_->v(s));
      if (attrs_.boolean("writeF")) line("F", state_->live(s).f);
    }
    writer_->append(text);
  }
  static Eigen::Matrix<double, 7, 1> pose(const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
    return (Eigen::Matrix<double, 7, 1>() << p, q.x(), q.y(), q.z(), q.w()).finished();
  }
  // The object to write: `mstate` if set, else the nearest MechanicalObject or rigid body in the
  // node or above.
  void findState() {
    Component* c = nullptr;
    if (attrs_.isSet("mstate")) {
      c = linkedComponent("mstate");
    } else {
      // SOFA's context rule: the last one of the node, else of the nearest node above.
      for (const Node* n = &node(); n && !c; n = n->parent())
        for (auto it = n->components().rbegin(); it != n->components().rend() && !c; ++it)
          if (dynamic_cast<MechanicalObject*>(it->get()) || dynamic_cast<RigidObject*>(it->get())) c = it->get();
      if (!c) throw error("no MechanicalObject in its node or above");
    }
    state_ = dynamic_cast<MechanicalObject*>(c);
    rigid_ = dynamic_cast<RigidObject*>(c);
    if (!state_ && !rigid_) throw error("mstate", "does not link to a MechanicalObject");
    scene().initComponent(*c);
    if (rigid_ && attrs_.boolean("writeF"))
      throw error("writeF", "a rigid body keeps no force vector to write; write its positions and velocities");
  }
  void flush() {
    if (writer_) writer_->finish();
    writer_.reset();
  }

  MechanicalObject* state_ = nullptr;  // one of these two
  RigidObject* rigid_ = nullptr;
  double period_ = 0;
  std::vector<double> times_;
  size_t next_ = 0;
  std::string path_;
  std::unique_ptr<io::StateDumpWriter> writer_;  // open from begin to the end of the run
};

}  // namespace

void registerWriteState(Registry& r) {
  ComponentSpec s;
  s.name = "WriteState";
  s.category = "output";
  s.doc = "Writes the node's MechanicalObject (Vec3d, or Rigid3d: position and quaternion x y z w, linear and "
          "angular velocity) at chosen times in SOFA's state dump format (T=, X=, V=, F= lines; "
          "gzip-compressed when the name ends in .gz), in the output folder, as SOFA's WriteState: from the first "
          "`time` every `period`, or at each listed time. The dump takes its name at the end of the run (a temporary "
          "file beside it meanwhile).";
  s.add(AttrSpec::string("filename").req().help("the file, in the output folder (.gz: compressed)"));
  s.add(AttrSpec::real("period").def("0").atLeast(0).unit(Dimension::time()).help("time between writes (0: the listed times only)"));
  s.add(AttrSpec::reals("time").def("0").unit(Dimension::time()).help("the first time to write at, or (period 0) every time to write at"));
  s.add(AttrSpec::boolean("writeX").def("true").help("write the positions"));
  s.add(AttrSpec::boolean("writeX0").def("false").help("write the rest positions"));
  s.add(AttrSpec::boolean("writeV").def("false").help("write the velocities"));
  s.add(AttrSpec::boolean("writeF").def("false").help("write the forces"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
  s.factory = [](BuildContext& c) { return std::make_unique<WriteState>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
