// Scene drivers fed by robot data: the instrument follows the tool tip of a dVRK PSM, computed by
// forward kinematics from a joint log (PsmJointDriver) or from an ESPM packet capture (EspmDriver),
// then placed in the scene by a registration transform.
#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <sstream>
#include <vector>

#include "engine/Roles.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/rigid/Placement.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/InputCache.h"
#include "robot/espm/Capture.h"
#include "robot/kinematics/JointTrajectory.h"
#include "robot/kinematics/PsmKinematics.h"

namespace viscera {

namespace {

// Replays a joint trajectory: joint values are interpolated linearly between samples (the robot
// moves along the kinematic path, not along a straight Cartesian line between sampled tip poses),
// the tool-tip pose is the forward kinematics of the interpolated joints, converted from m to the
// scene's length unit and placed by the transform / rotation / translation attributes.
class JointReplayDriver : public Component, public Driver {
 public:
  using Component::Component;

  void drive(State& s, double t, double h) const override { motionAt(t, h, body_->live(s)); }

  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "duration") out.values = {joints_.end() - offset_};
    else if (name == "joints") out.values.assign(qStart_.data(), qStart_.data() + qStart_.size());
    else return false;
    return true;
  }

 private:
  // The pose at t and the mean velocity over the step (t - h, t].
  void motionAt(double t, double h, RigidObject::Live& b) const {
    const double tt = t + offset_;
    Eigen::VectorXd q(chain_.dof());
    std::vector<Eigen::Isometry3d> frames(chain_.dof());
    joints_.sample(tt - h, q);
    const Eigen::Isometry3d before = chain_.forwardKinematics(q, frames);
    joints_.sample(tt, q);
    const Eigen::Isometry3d now = chain_.forwardKinematics(q, frames);
    const Eigen::Vector3d p0 = before.translation() * metresToScene_, p1 = now.translation() * metresToScene_;
    const Eigen::Quaterniond r0(before.linear()), r1(now.linear());
    // Velocity: the mean over the step ending at t (the step's displacement / dt), as the other
    // drivers report it for the friction constraints.
    b.setMotion(place_.point(p1), place_.rotation(r1), place_.vector((p1 - p0) / h),
                place_.vector(rotationVector(r0, r1) / h));
  }

 protected:
  // Where sample i of the log came from, for limit messages: a location and a prefix for the
  // message (the CSV line and ""; or the capture and "packet at byte N (t = T s): ").
  using SampleSource = std::function<std::pair<SourceLoc, std::string>(const robot::JointTrajectory&, int)>;

  // Takes the joint samples (read by the subclass) and starts the replay.
  void start(robot::JointTrajectory joints, const SampleSource& where) {
    body_ = &contextRigid(*this);
    if (body_->driven) throw error("object", "'" + body_->name() + "' already has a driver");
    body_->driven = true;
    if (attrs_.boolean("checkLimits"))
      for (int i = 0; i < joints.size(); ++i)
        if (!chain_.limitViolations(joints.joints(i)).empty()) {
          const auto [loc, prefix] = where(joints, i);
          try {
            chain_.requireWithinLimits(joints.joints(i));
          } catch (const Error& e) {
            throw fileErrorFor(Error(loc, prefix + e.what()), *this, "filename");
          }
        }
    joints_ = std::move(joints);
    offset_ = attrs_.real("timeOffset");
    place_ = readPlacement(*this);
    metresToScene_ = 1.0 / scene().units().siOf(Dimension::length());
    qStart_.resize(chain_.dof());
    joints_.sample(scene().startTime() + offset_, qStart_);
    motionAt(scene().startTime(), scene().dt(), body_->start);
    body_->p0 = body_->start.p;
    body_->q0 = body_->start.q;
  }

  const robot::SerialChain chain_ = robot::psmLargeNeedleDriver();

 private:
  RigidObject* body_ = nullptr;
  robot::JointTrajectory joints_;
  double offset_ = 0, metresToScene_ = 1;
  Placement place_;
  Eigen::VectorXd qStart_;  // the joints at the start
};

class PsmJointDriver : public JointReplayDriver {
 public:
  using JointReplayDriver::JointReplayDriver;
  void init() override {
    const std::string path = scene().resolvePath(attrs_.str("filename"));
    robot::JointTrajectory joints;
    try {
      const int dof = chain_.dof();
      joints = *io::cachedRead<robot::JointTrajectory>(path, [dof](const std::string& p) { return robot::readJointCsv(p, dof); });
    } catch (const Error& e) {
      throw fileErrorFor(e, *this, "filename");
    }
    start(std::move(joints), [&](const robot::JointTrajectory& j, int i) {
      return std::pair{SourceLoc{path, j.line(i)}, std::string()};
    });
  }
};

class EspmDriver : public JointReplayDriver {
 public:
  using JointReplayDriver::JointReplayDriver;
  void init() override {
    const std::string path = scene().resolvePath(attrs_.str("filename"));
    robot::espm::CaptureOptions options;
    robot::espm::parseFraming(attrs_.str("framing"), options.framing);  // the attribute's choices are the names
    options.lineRate = attrs_.real("lineRate");
    if (!(options.lineRate > 0)) throw error("lineRate", "must be positive");
    robot::espm::JointScale scale;
    const auto& counts = attrs_.reals("countsPerUnit");
    const auto& offsets = attrs_.reals("jointOffset");
    for (int j = 0; j < chain_.dof(); ++j) {
      if (!(counts[j] != 0)) throw error("countsPerUnit", "entry " + std::to_string(j + 1) + " is zero");
      scale.countsPerUnit[j] = counts[j];
      scale.offset[j] = offsets[j];
    }
    robot::espm::Capture capture;
    robot::JointTrajectory joints;
    try {
      capture = robot::espm::readCapture(path, options);
      joints = robot::espm::jointsFromCapture(capture, scale);
    } catch (const Error& e) {
      throw fileErrorFor(e, *this, "filename");
    }
    stats_ = capture.stats;
    start(std::move(joints), [&](const robot::JointTrajectory&, int i) {
      std::ostringstream m;
      m << "packet at byte " << capture.samples[i].offset << " (t = " << capture.samples[i].time << " s): ";
      return std::pair{SourceLoc{path}, m.str()};
    });
  }
  bool field(const std::string& name, FieldValue& out) const override {
    if (name == "packets") out.values = {static_cast<double>(stats_.packets)};
    else if (name == "crcErrors") out.values = {static_cast<double>(stats_.crcFailures)};
    else return JointReplayDriver::field(name, out);
    return true;
  }

 private:
  robot::espm::DecoderStats stats_;
};

// Attributes common to the joint-driven drivers.
void addReplayAttributes(ComponentSpec& s) {
  s.add(AttrSpec::link("object").help("the Rigid3d MechanicalObject (default: the one in the node)"));
  s.add(AttrSpec::real("timeOffset").def("0").unit(Dimension::time()).help("log time = scene time + timeOffset"));
  s.add(AttrSpec::boolean("checkLimits").def("true").help("reject a log with joint values outside the PSM's joint limits "
                                                          "(the message names the sample)"));
  addPlacementAttributes(s, "the tool-tip poses (robot base frame, converted to the scene's length unit)");
}

}  // namespace

void registerRobotDrivers(Registry& r) {
  {
    ComponentSpec s;
    s.name = "PsmJointDriver";
    s.category = "driver";
    s.doc = "Moves a rigid body (the instrument) with the tool tip of a dVRK PSM (large needle driver, modified DH "
            "table in docs/user-guide.md) replaying a joint log: a CSV of t,q1,...,q6 rows (s; rad, and m for the "
            "insertion q3; header optional). Joint values are interpolated linearly between samples and the pose is "
            "the forward kinematics of the interpolated joints, so the instrument follows the robot's kinematic path. "
            "Positions are converted from m to the scene's length unit, then placed by `transform` (robot -> scene), "
            "`rotation` and `translation`. Held at the first / last sample outside the log. The velocity is the mean "
            "over each time step. Field `joints`: the joint values at the current time.";
    s.add(AttrSpec::file("filename").req().help("joint log CSV (t,q1,...,q6; rad and m)"));
    addReplayAttributes(s);
    s.factory = [](BuildContext& c) { return std::make_unique<PsmJointDriver>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "EspmDriver";
    s.category = "driver";
    s.doc = "Moves a rigid body (the instrument) with the tool tip of a dVRK PSM whose joints are read from an ESPM "
            "capture: the raw bytes of the arm's 20 Mbit/s link (written by `viscera espm synth` or recorded). The "
            "capture is decoded (framing, CRC, resynchronisation after corrupt data), each packet's encoder counts 1-6 "
            "become joint values q = count / countsPerUnit + jointOffset, timed by the packet's position on the line "
            "(t = byte offset x 8 / lineRate), and the tool tip follows as in PsmJointDriver. A packet with an encoder "
            "overflow is an error naming its byte offset. Fields: `joints`, `packets` (decoded), `crcErrors`.";
    s.add(AttrSpec::file("filename").req().help("ESPM capture (raw link bytes)"));
    s.add(AttrSpec::choice("framing", {"auto", "dissertation", "public"}).def("auto")
              .help("packet framing: the dissertation's (magic, 32 quadlets, CRC-16) or the controller's (magic, header "
                    "with page and length, payload, CRC quadlet); auto decides from the first packets"));
    s.add(AttrSpec::real("lineRate").def("20e6").help("bit rate of the link (bit/s): packet time = byte offset x 8 / lineRate"));
    s.add(AttrSpec::reals("countsPerUnit", 6).def("1e5 1e5 1e6 1e5 1e5 1e5")
              .help("encoder counts per rad (per m for the insertion, joint 3) of joints 1-6"));
    s.add(AttrSpec::reals("jointOffset", 6).def("0 0 0 0 0 0").help("joint value at count 0 (rad; m for joint 3)"));
    addReplayAttributes(s);
    s.factory = [](BuildContext& c) { return std::make_unique<EspmDriver>(c); };
    r.add(std::move(s));
  }
}

}  // namespace viscera
