#include "robot/dynamics/ArmSimulator.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "core/Error.h"

namespace viscera::robot {

ArmSimulationOptions psmSimulationDefaults() {
  ArmSimulationOptions o;
  o.gains.kp = {40, 40, 2000, 0.3, 0.3, 0.3};
  o.gains.kd = {2.5, 2.5, 60, 0.012, 0.012, 0.012};
  o.gains.ki = {8, 8, 400, 0.06, 0.06, 0.06};
  // Cable transmissions: a little play in the outer joints' readings; dVRK-like noise levels.
  o.measurement.backlash = {2e-4, 2e-4, 2e-5, 1e-3, 1e-3, 1e-3};
  o.measurement.positionNoise = {2e-5, 2e-5, 2e-6, 1e-4, 1e-4, 1e-4};
  o.measurement.velocityNoise = {1e-3, 1e-3, 1e-4, 3e-3, 3e-3, 3e-3};
  o.measurement.effortNoise = {0.01, 0.01, 0.03, 2e-4, 2e-4, 2e-4};
  o.excitation.lower = {-0.9, -0.6, 0.08, -2.0, -1.0, -1.0};
  o.excitation.upper = {0.9, 0.6, 0.22, 2.0, 1.0, 1.0};
  return o;
}

void MeasurementModel::makePerfect() {
  for (std::vector<double>* v : {&backlash, &positionNoise, &velocityNoise, &effortNoise}) std::fill(v->begin(), v->end(), 0.0);
}

namespace {

// A segment of the reference: quintic Hermite from `from` to `to` with end velocities v0, v1 and
// zero end accelerations (the minimum-jerk move when both velocities are zero).
struct Segment {
  double start = 0, duration = 1;
  Eigen::VectorXd from, to, v0, v1;
  bool free = true;  // a free move (palpations stop at each of their waypoints)

  void at(double x, Eigen::VectorXd& q, Eigen::VectorXd& qd) const {
    const double x2 = x * x, x3 = x2 * x, x4 = x3 * x, x5 = x4 * x;
    const double h0 = 1 - 10 * x3 + 15 * x4 - 6 * x5, h1 = x - 6 * x3 + 8 * x4 - 3 * x5;
    const double h2 = -4 * x3 + 7 * x4 - 3 * x5, h3 = 10 * x3 - 15 * x4 + 6 * x5;
    const double d0 = -30 * x2 + 60 * x3 - 30 * x4, d1 = 1 - 18 * x2 + 32 * x3 - 15 * x4;
    const double d2 = -12 * x2 + 28 * x3 - 15 * x4, d3 = 30 * x2 - 60 * x3 + 30 * x4;
    q = h0 * from + h3 * to + duration * (h1 * v0 + h2 * v1);
    qd = (d0 * from + d3 * to) / duration + d1 * v0 + d2 * v1;
  }
};

// The reference: segments between waypoints, plus a slow wander.
class Reference {
 public:
  Reference(const ArmDynamics& arm, const ArmSimulationOptions& o, std::mt19937_64& rng) : n_(arm.dof()) {
    const Excitation& e = o.excitation;
    std::uniform_real_distribution<double> u01(0, 1);
    // A waypoint at most `step` of each range away from `from` (anywhere when from is empty).
    auto draw = [&](const Eigen::VectorXd* from) {
      Eigen::VectorXd q(n_);
      for (int i = 0; i < n_; ++i) {
        const double range = e.upper[i] - e.lower[i];
        const double x = from ? (*from)[i] + e.step * range * (2 * u01(rng) - 1) : e.lower[i] + range * u01(rng);
        q[i] = std::clamp(x, e.lower[i], e.upper[i]);
      }
      return q;
    };
    auto duration = [&] { return e.minSegment + (e.maxSegment - e.minSegment) * u01(rng); };
    const Phantom& ph = o.phantom;
    // Insertion at which the tip touches the phantom, for the other joints of q (joint 3 moves the
    // tip along the shaft, so the height above the surface is linear in it); `along` is the height
    // change per metre of insertion (< 0 when the shaft points into the surface).
    auto surfaceInsertion = [&](const Eigen::VectorXd& q, double& along) {
      const Eigen::Vector3d tip = arm.chain().tipPose(q).translation();
      Eigen::VectorXd q2 = q;
      q2[2] += 0.01;
      const Eigen::Vector3d shaft = (arm.chain().tipPose(q2).translation() - tip) / 0.01;
      along = shaft.dot(ph.normal);
      const double height = (tip - ph.point).dot(ph.normal);
      return q[2] - height / along;
    };
    constexpr double clearance = 0.008;  // m above the surface for free motion
    // The deepest insertion that keeps the tip above the surface along a joint-space move a -> b
    // with insertion x at both ends (checked at points along the move).
    auto freeInsertion = [&](const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
      double limit = arm.chain().joints()[2].upper, along = 0;
      for (double s = 0; s <= 1.0001; s += 0.125) {
        const Eigen::VectorXd q = a + s * (b - a);
        const double touch = surfaceInsertion(q, along);
        if (along < 0) limit = std::min(limit, touch - clearance / -along);
      }
      return std::max(limit, e.lower[2]);
    };
    Eigen::VectorXd q = draw(nullptr);
    if (ph.enabled) q[2] = std::min(q[2], freeInsertion(q, q));
    double t = 0;
    const double end = o.duration + 1;
    const Eigen::VectorXd rest = Eigen::VectorXd::Zero(n_);
    auto add = [&](const Eigen::VectorXd& to, double d, bool free = false) {
      segments_.push_back({t, d, q, to, rest, rest, free});
      t += d;
      q = to;
    };
    // A free move to `to`, retracting first when the insertion now would dip into the phantom.
    auto moveTo = [&](Eigen::VectorXd to) {
      if (ph.enabled) {
        const double x = freeInsertion(q, to);
        to[2] = std::min(to[2], x);
        if (q[2] > x + 1e-6) {
          Eigen::VectorXd up = q;
          up[2] = x;
          add(up, 0.5 + 0.5 * u01(rng));
        }
      }
      add(to, duration(), true);
    };
    double along = 0;
    int misses = 0;  // palpation spots drawn in a row that the shaft cannot press
    while (t < end) {
      if (ph.enabled && u01(rng) < e.palpationShare) {
        // Palpation: above a point, down into the surface along the shaft, hold, up again. The spot
        // is near the current pose; after many misses there, anywhere in the ranges.
        if (misses > 100000) throw Error("arm simulation: no palpation fits the excitation's ranges and the phantom");
        Eigen::VectorXd above = draw(misses < 20 ? &q : nullptr);
        const double touch = surfaceInsertion(above, along);
        Eigen::VectorXd pressed = above;
        above[2] = touch - clearance / -along;
        pressed[2] = touch + (e.minDepth + (e.maxDepth - e.minDepth) * u01(rng)) / -along;
        // Too grazing, the surface out of the insertion's reach, or off the phantom: draw again.
        bool off = false;
        if (ph.radius > 0 && along < 0) {
          Eigen::VectorXd touching = above;
          touching[2] = touch;
          const Eigen::Vector3d d = arm.chain().tipPose(touching).translation() - ph.point;
          off = (d - d.dot(ph.normal) * ph.normal).norm() > ph.radius;
        }
        if (off || !(along < -0.3) || above[2] < e.lower[2] || pressed[2] > e.upper[2]) {
          ++misses;
          continue;
        }
        misses = 0;
        moveTo(above);
        add(pressed, 0.8 + 1.2 * u01(rng));
        add(pressed, 0.3 + 1.0 * u01(rng));
        add(above, 0.8 + 1.2 * u01(rng));
      } else {
        moveTo(draw(&q));
      }
    }
    // A surgeon's hand does not stop at every waypoint: between two free moves the reference passes
    // with half the mean velocity of the two (Catmull-Rom-like); the insertion stops when there is
    // a phantom, whose clearance was checked along straight moves.
    for (size_t k = 0; k + 1 < segments_.size(); ++k) {
      Segment& a = segments_[k];
      Segment& b = segments_[k + 1];
      if (!a.free || !b.free) continue;
      Eigen::VectorXd v = 0.5 * (b.to - a.from) / (a.duration + b.duration);
      if (ph.enabled) v[2] = 0;
      a.v1 = b.v0 = v;
    }
    // Wander: three sines per joint, 0.1 to 1 Hz.
    wander_.resize(n_);
    for (int i = 0; i < n_; ++i)
      for (int k = 0; k < 3; ++k)
        wander_[i].push_back({e.wander * (e.upper[i] - e.lower[i]), 2 * std::numbers::pi * (0.1 + 0.9 * u01(rng)),
                              2 * std::numbers::pi * u01(rng)});
  }

  // Reference position and velocity at time t.
  void at(double t, Eigen::VectorXd& q, Eigen::VectorXd& qd) {
    while (current_ + 1 < segments_.size() && t >= segments_[current_ + 1].start) ++current_;
    const Segment& s = segments_[current_];
    s.at(std::clamp((t - s.start) / s.duration, 0.0, 1.0), q, qd);
    for (int i = 0; i < n_; ++i)
      for (const Sine& w : wander_[i]) {
        q[i] += w.amplitude * std::sin(w.omega * t + w.phase);
        qd[i] += w.amplitude * w.omega * std::cos(w.omega * t + w.phase);
      }
  }

 private:
  struct Sine {
    double amplitude, omega, phase;
  };
  int n_;
  std::vector<Segment> segments_;
  size_t current_ = 0;
  std::vector<std::vector<Sine>> wander_;
};

void requireSize(const std::vector<double>& v, int n, const char* what) {
  if (static_cast<int>(v.size()) != n)
    throw Error(std::string("arm simulation: ") + what + " needs one value per joint (" + std::to_string(n) + ")");
  for (double x : v)
    if (!std::isfinite(x)) throw Error(std::string("arm simulation: ") + what + " is not finite");
}

// Environment efforts at a state: the body wall's and seal's share (trocar) and J^T F_ext with the
// phantom's wrench, plus the derivatives the implicit step needs (diagonal, per joint velocity).
struct Environment {
  Eigen::VectorXd trocar, external;             // efforts
  Eigen::VectorXd trocarSlope, externalSlope;  // d effort_i / d qd_i
  Vector6d wrench = Vector6d::Zero();
};

Environment environment(const ArmDynamics& arm, const ArmSimulationOptions& o, const Eigen::VectorXd& q,
                        const Eigen::VectorXd& qd, const Vector6d& held) {
  const int n = arm.dof();
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
  Environment env{zero, zero, zero, zero};
  const bool analyticPhantom = o.phantom.enabled && !o.environment;
  if (!o.trocar.enabled && !analyticPhantom && !o.seal.enabled && !o.environment) return env;
  const ChainPose pose = arm.chain().forwardKinematics(q);
  Jacobian J(6, n);
  arm.chain().spatialJacobian(pose.frames, pose.tip, J);
  if (o.trocar.enabled) {
    // The shaft is the z axis of joint 3's frame; the wall acts at its point nearest the anchor.
    const Eigen::Vector3d axis = pose.frames[2].linear().col(2);
    const Eigen::Vector3d origin = pose.frames[2].translation();
    const Eigen::Vector3d point = origin + axis * axis.dot(o.trocar.anchor - origin);
    // Velocity of that point from joints 1-3 (the roll and wrist do not move the shaft's axis).
    Eigen::Matrix<double, 3, Eigen::Dynamic> Jp = Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, n);
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d z = pose.frames[i].linear().col(2);
      Jp.col(i) = arm.chain().joints()[i].type == JointType::Revolute ? z.cross(point - pose.frames[i].translation()) : z;
    }
    const Eigen::Matrix3d lateral = Eigen::Matrix3d::Identity() - axis * axis.transpose();
    const Eigen::Vector3d d = point - o.trocar.anchor;  // already lateral
    const Eigen::Vector3d v = lateral * (Jp * qd);
    const double r = d.norm();
    const Eigen::Vector3d onShaft = -(o.trocar.stiffness + o.trocar.cubic * r * r) * d - o.trocar.damping * v;
    env.trocar -= Jp.transpose() * onShaft;  // the motor supplies the opposite
    env.trocarSlope += (o.trocar.damping * (Jp.transpose() * lateral * Jp)).diagonal();
  }
  if (o.seal.enabled) {
    env.trocar[2] += o.seal.axial.effort(qd[2]);
    env.trocar[3] += o.seal.roll.effort(qd[3]);
    env.trocarSlope[2] += o.seal.axial.slope(qd[2]);
    env.trocarSlope[3] += o.seal.roll.slope(qd[3]);
  }
  if (o.environment) {
    env.wrench = held;
    env.external = J.transpose() * held;
  } else if (analyticPhantom) {
    const Phantom& ph = o.phantom;
    const double depth = -(pose.tip.translation() - ph.point).dot(ph.normal);
    if (depth > 0) {
      const Eigen::Vector3d v = (J * qd).head<3>();
      const double vn = v.dot(ph.normal);
      const double normal = std::max(0.0, ph.stiffness * depth - ph.damping * vn);
      const Eigen::Vector3d vt = v - vn * ph.normal;
      const double speed = vt.norm();
      constexpr double slip = 1e-3;  // m/s, regularisation of Coulomb friction
      Eigen::Vector3d onTool = normal * ph.normal;
      if (speed > 0) onTool -= ph.friction * normal * std::tanh(speed / slip) * vt / speed;
      env.wrench.head<3>() = -onTool;  // the tool's wrench on the phantom, about the tip
      env.external = J.transpose() * env.wrench;
      const Eigen::Matrix<double, 3, Eigen::Dynamic> Jv = J.topRows<3>();
      env.externalSlope += (ph.damping * (Jv.transpose() * ph.normal * ph.normal.transpose() * Jv)).diagonal();
    }
  }
  return env;
}

}  // namespace

ArmRecording simulateArm(const ArmDynamics& arm, const ArmSimulationOptions& o,
                         const std::function<void(double)>& progress) {
  const int n = arm.dof();
  if (!(o.duration > 0) || !(o.rate > 0) || o.substeps < 1 || !std::isfinite(o.duration * o.rate))
    throw Error("arm simulation: duration, rate and substeps must be positive");
  requireSize(o.gains.kp, n, "gains.kp");
  requireSize(o.gains.kd, n, "gains.kd");
  requireSize(o.gains.ki, n, "gains.ki");
  requireSize(o.measurement.backlash, n, "measurement.backlash");
  requireSize(o.measurement.positionNoise, n, "measurement.positionNoise");
  requireSize(o.measurement.velocityNoise, n, "measurement.velocityNoise");
  requireSize(o.measurement.effortNoise, n, "measurement.effortNoise");
  requireSize(o.excitation.lower, n, "excitation.lower");
  requireSize(o.excitation.upper, n, "excitation.upper");
  for (int i = 0; i < n; ++i) {
    const DhJoint& j = arm.chain().joints()[i];
    if (!(o.excitation.lower[i] <= o.excitation.upper[i]) || o.excitation.lower[i] < j.lower || o.excitation.upper[i] > j.upper)
      throw Error("arm simulation: the excitation range of joint " + std::to_string(i + 1) + " is not within its limits [" +
                  std::to_string(j.lower) + ", " + std::to_string(j.upper) + "]");
  }
  if (!(o.excitation.step > 0 && o.excitation.step <= 1))
    throw Error("arm simulation: the excitation's step must be in (0, 1] (a share of each joint's range)");
  if (o.phantom.enabled && std::abs(o.phantom.normal.norm() - 1) > 1e-6)
    throw Error("arm simulation: the phantom's normal is not a unit vector");

  std::mt19937_64 rng(o.seed);
  Reference reference(arm, o, rng);
  std::normal_distribution<double> gauss(0, 1);

  constexpr double maxSamples = 1e8;  // 28 hours at 1 kHz; the recording is held in memory
  if (o.duration * o.rate >= maxSamples)
    throw Error("arm simulation: " + std::to_string(o.duration * o.rate) + " samples; at most 1e8 in one recording");
  const int samples = static_cast<int>(std::floor(o.duration * o.rate)) + 1;
  ArmRecording rec;
  rec.dof = n;
  rec.t.resize(samples);
  for (Eigen::MatrixXd* m : {&rec.q, &rec.qd, &rec.effort, &rec.qTrue, &rec.qdTrue, &rec.freeEffort, &rec.trocarEffort,
                             &rec.externalEffort})
    m->resize(samples, n);
  rec.wrench.resize(samples, 6);
  rec.jacobian.resize(samples, 6 * n);
  rec.tip.resize(samples, 3);

  const Eigen::Map<const Eigen::VectorXd> kp(o.gains.kp.data(), n), kd(o.gains.kd.data(), n), ki(o.gains.ki.data(), n);
  Eigen::VectorXd q(n), qd = Eigen::VectorXd::Zero(n), integral = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd qRef(n), qdRef(n);
  reference.at(0, qRef, qdRef);
  q = qRef;
  Eigen::VectorXd reading = q;  // the play operator's output
  // Start at rest with the integral term already holding the arm against gravity.
  const Eigen::VectorXd hold = arm.bias(q, qd);
  for (int i = 0; i < n; ++i) integral[i] = ki[i] > 0 ? hold[i] / ki[i] : 0;
  // The efforts of the last step, split as in Eq. 2.4; at t = 0 the arm is at rest.
  Eigen::VectorXd free = arm.inverseDynamics(q, qd, Eigen::VectorXd::Zero(n));
  Vector6d held = Vector6d::Zero();  // the external environment's wrench over the current sample
  auto tipMotion = [&](Eigen::Isometry3d& tip, Vector6d& twist) {
    tip = arm.chain().tipPose(q);
    twist = arm.chain().spatialJacobian(q) * qd;
  };
  if (o.environment) {
    Eigen::Isometry3d tip;
    Vector6d twist;
    tipMotion(tip, twist);
    held = o.environment(0, tip, twist);
  }
  Environment env = environment(arm, o, q, qd, held);
  Eigen::VectorXd trocar = env.trocar, external = env.external;
  const double h = 1 / (o.rate * o.substeps);

  for (int s = 0; s < samples; ++s) {
    const double t = s / o.rate;
    if (s > 0 && o.environment) {
      Eigen::Isometry3d tip;
      Vector6d twist;
      tipMotion(tip, twist);
      held = o.environment((s - 1) / o.rate, tip, twist);  // the state is still the previous sample's
      if (!held.allFinite()) throw Error("arm simulation: the environment's wrench is not finite at t = " + std::to_string(t) + " s");
    }
    for (int k = 0; s > 0 && k < o.substeps; ++k) {
      const double tk = t - (o.substeps - 1 - k) * h;
      reference.at(tk, qRef, qdRef);
      const Eigen::MatrixXd M = arm.massMatrix(q);
      const Eigen::VectorXd bias = arm.bias(q, qd);
      env = environment(arm, o, q, qd, held);
      Eigen::VectorXd friction(n), slope(n);
      for (int i = 0; i < n; ++i) {
        friction[i] = arm.friction()[i].effort(qd[i]);
        slope[i] = arm.friction()[i].slope(qd[i]);
      }
      // Linearly implicit Euler: the controller, friction and the environment's damping at the new
      // velocity (through their derivatives at the old one), the controller at q + h qd_new.
      const Eigen::VectorXd e = qRef - q;
      integral += h * e;
      const Eigen::VectorXd pid = kp.cwiseProduct(e - h * qd) + kd.cwiseProduct(qdRef - qd) + ki.cwiseProduct(integral);
      Eigen::MatrixXd A = M;
      A.diagonal() += h * (kd + slope + env.trocarSlope + env.externalSlope) + h * h * kp;
      const Eigen::VectorXd dqd = A.llt().solve(h * (pid - bias - friction - env.trocar - env.external));
      qd += dqd;
      q += h * qd;
      // What each part took of the motor effort over this step; they sum to it to rounding.
      free = M * (dqd / h) + bias + friction + slope.cwiseProduct(dqd);
      trocar = env.trocar + env.trocarSlope.cwiseProduct(dqd);
      external = env.external + env.externalSlope.cwiseProduct(dqd);
    }
    if (!q.allFinite() || !qd.allFinite())
      throw Error("arm simulation: the state diverged at t = " + std::to_string(t) + " s");
    const Eigen::VectorXd motor = free + trocar + external;
    env = environment(arm, o, q, qd, held);
    rec.t[s] = t;
    rec.qTrue.row(s) = q;
    rec.qdTrue.row(s) = qd;
    rec.freeEffort.row(s) = free;
    rec.trocarEffort.row(s) = trocar;
    rec.externalEffort.row(s) = external;
    rec.wrench.row(s) = env.wrench;
    for (int i = 0; i < n; ++i) {
      const MeasurementModel& m = o.measurement;
      const double half = m.backlash[i] / 2;
      reading[i] = std::clamp(reading[i], q[i] - half, q[i] + half);
      rec.q(s, i) = reading[i] + m.positionNoise[i] * gauss(rng);
      rec.qd(s, i) = qd[i] + m.velocityNoise[i] * gauss(rng);
      rec.effort(s, i) = motor[i] + m.effortNoise[i] * gauss(rng);
    }
    const Eigen::VectorXd qMeasured = rec.q.row(s).transpose();
    const Jacobian J = arm.chain().spatialJacobian(qMeasured);
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < n; ++c) rec.jacobian(s, r * n + c) = J(r, c);
    rec.tip.row(s) = arm.chain().tipPose(q).translation().transpose();
    if (progress && (s % 1000 == 0 || s + 1 == samples)) progress(double(s + 1) / samples);
  }
  return rec;
}

}  // namespace viscera::robot
