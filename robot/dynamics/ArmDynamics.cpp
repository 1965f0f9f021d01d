#include "robot/dynamics/ArmDynamics.h"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <string>

#include "core/Error.h"

namespace viscera::robot {

double JointFriction::effort(double v) const {
  const double breakaway = coulomb + stribeck * std::exp(-(v / stribeckVelocity) * (v / stribeckVelocity));
  return breakaway * std::tanh(v / smoothing) + viscous * v;
}

double JointFriction::slope(double v) const {
  const double r = v / stribeckVelocity;
  const double e = std::exp(-r * r);
  const double breakaway = coulomb + stribeck * e;
  const double dBreakaway = stribeck * e * (-2 * r / stribeckVelocity);
  const double th = std::tanh(v / smoothing);
  return dBreakaway * th + breakaway * (1 - th * th) / smoothing + viscous;
}

namespace {

// Inertia about the link frame's origin from the one about the centre of mass (parallel axes).
Eigen::Matrix3d inertiaAtOrigin(const LinkInertia& l) {
  return l.inertia + l.mass * (l.com.squaredNorm() * Eigen::Matrix3d::Identity() - l.com * l.com.transpose());
}

}  // namespace

ArmDynamics::ArmDynamics(SerialChain chain, std::vector<LinkInertia> links, Eigen::Vector3d gravity,
                         std::vector<double> armature, std::vector<JointFriction> friction,
                         std::vector<JointSpring> springs)
    : chain_(std::move(chain)),
      links_(std::move(links)),
      gravity_(gravity),
      armature_(std::move(armature)),
      friction_(std::move(friction)),
      springs_(std::move(springs)) {
  const size_t n = static_cast<size_t>(chain_.dof());
  if (links_.size() != n || armature_.size() != n || friction_.size() != n || springs_.size() != n)
    throw Error("ArmDynamics: links, armature, friction and springs need one entry per joint (" +
                std::to_string(n) + ")");
  for (size_t i = 0; i < n; ++i) {
    const LinkInertia& l = links_[i];
    const JointFriction& f = friction_[i];
    if (!(l.mass >= 0) || !l.com.allFinite() || !l.inertia.allFinite() || !(armature_[i] >= 0) ||
        !(f.coulomb >= 0) || !(f.stribeck >= 0) || !(f.viscous >= 0) || !(f.stribeckVelocity > 0) ||
        !(f.smoothing > 0) || !std::isfinite(springs_[i].stiffness + springs_[i].rest + springs_[i].offset))
      throw Error("ArmDynamics: joint " + std::to_string(i + 1) +
                  " needs mass, armature and friction >= 0, positive velocity scales and finite values");
  }
  if (!gravity_.allFinite()) throw Error("ArmDynamics: gravity is not finite");
  parameters_.resize(static_cast<Eigen::Index>(n) * kLinkParameters);
  for (size_t i = 0; i < n; ++i) {
    const LinkInertia& l = links_[i];
    const Eigen::Matrix3d I = inertiaAtOrigin(l);
    parameters_.segment<kLinkParameters>(static_cast<Eigen::Index>(i) * kLinkParameters)
        << l.mass, l.mass * l.com, I(0, 0), I(0, 1), I(0, 2), I(1, 1), I(1, 2), I(2, 2);
  }
}

Eigen::VectorXd ArmDynamics::linkParameters() const { return parameters_; }

Eigen::VectorXd ArmDynamics::rigidBody(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                       const Eigen::VectorXd& qdd, const Eigen::VectorXd& parameters,
                                       bool withGravity) const {
  const int n = dof();
  if (q.size() != n || qd.size() != n || qdd.size() != n || parameters.size() != n * kLinkParameters)
    throw Error("ArmDynamics: joint vectors need " + std::to_string(n) + " entries and parameters " +
                std::to_string(n * kLinkParameters));
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  std::vector<Eigen::Matrix3d> R(n);
  std::vector<Eigen::Vector3d> p(n), F(n), N(n);
  // Outward: velocities and accelerations of each link frame, in its own coordinates. Gravity
  // enters as an upward acceleration of the base.
  Eigen::Vector3d w = Eigen::Vector3d::Zero(), wd = Eigen::Vector3d::Zero();
  Eigen::Vector3d a = withGravity ? Eigen::Vector3d(-gravity_) : Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    const Eigen::Isometry3d T = chain_.linkTransform(i, q[i]);
    R[i] = T.linear();
    p[i] = T.translation();
    const Eigen::Matrix3d Rt = R[i].transpose();
    const Eigen::Vector3d aNew = Rt * (wd.cross(p[i]) + w.cross(w.cross(p[i])) + a);
    Eigen::Vector3d wNew = Rt * w, wdNew = Rt * wd;
    if (chain_.joints()[i].type == JointType::Revolute) {
      wdNew += wNew.cross(qd[i] * z) + qdd[i] * z;
      wNew += qd[i] * z;
      a = aNew;
    } else {
      a = aNew + 2 * wNew.cross(qd[i] * z) + qdd[i] * z;
    }
    w = wNew;
    wd = wdNew;
    // Force and moment (about the frame's origin) that accelerate link i, linear in its parameters.
    const auto pi = parameters.segment<kLinkParameters>(static_cast<Eigen::Index>(i) * kLinkParameters);
    const double m = pi[0];
    const Eigen::Vector3d h = pi.segment<3>(1);
    Eigen::Matrix3d I;
    I << pi[4], pi[5], pi[6], pi[5], pi[7], pi[8], pi[6], pi[8], pi[9];
    F[i] = m * a + wd.cross(h) + w.cross(w.cross(h));
    N[i] = I * wd + w.cross(I * w) + h.cross(a);
  }
  // Inward: what each joint transmits to the links beyond it.
  Eigen::VectorXd tau(n);
  Eigen::Vector3d f = Eigen::Vector3d::Zero(), m = Eigen::Vector3d::Zero();
  for (int i = n - 1; i >= 0; --i) {
    Eigen::Vector3d fi = F[i], mi = N[i];
    if (i + 1 < n) {
      const Eigen::Vector3d fOut = R[i + 1] * f;
      fi += fOut;
      mi += R[i + 1] * m + p[i + 1].cross(fOut);
    }
    f = fi;
    m = mi;
    tau[i] = chain_.joints()[i].type == JointType::Revolute ? m.dot(z) : f.dot(z);
  }
  return tau;
}

Eigen::VectorXd ArmDynamics::rigidBody(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                       const Eigen::VectorXd& qdd) const {
  return rigidBody(q, qd, qdd, parameters_);
}

Eigen::VectorXd ArmDynamics::frictionEfforts(const Eigen::VectorXd& qd) const {
  Eigen::VectorXd f(dof());
  for (int i = 0; i < dof(); ++i) f[i] = friction_[i].effort(qd[i]);
  return f;
}

Eigen::VectorXd ArmDynamics::bias(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const {
  Eigen::VectorXd b = rigidBody(q, qd, Eigen::VectorXd::Zero(dof()));
  for (int i = 0; i < dof(); ++i) b[i] += springs_[i].effort(q[i]);
  return b;
}

Eigen::VectorXd ArmDynamics::inverseDynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                             const Eigen::VectorXd& qdd) const {
  Eigen::VectorXd tau = rigidBody(q, qd, qdd) + frictionEfforts(qd);
  for (int i = 0; i < dof(); ++i) tau[i] += armature_[i] * qdd[i] + springs_[i].effort(q[i]);
  return tau;
}

Eigen::MatrixXd ArmDynamics::massMatrix(const Eigen::VectorXd& q) const {
  const int n = dof();
  Eigen::MatrixXd M(n, n);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd e = zero;
  for (int j = 0; j < n; ++j) {
    e[j] = 1;
    M.col(j) = rigidBody(q, zero, e, parameters_, false);
    M(j, j) += armature_[j];
    e[j] = 0;
  }
  return 0.5 * (M + M.transpose());  // symmetric to rounding
}

double ArmDynamics::kineticEnergy(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const {
  return 0.5 * qd.dot(massMatrix(q) * qd);
}

double ArmDynamics::potentialEnergy(const Eigen::VectorXd& q) const {
  const ChainPose pose = chain_.forwardKinematics(q);
  double u = 0;
  for (int i = 0; i < dof(); ++i) {
    u -= links_[i].mass * gravity_.dot(pose.frames[i] * links_[i].com);
    const JointSpring& s = springs_[i];
    u += 0.5 * s.stiffness * (q[i] - s.rest) * (q[i] - s.rest) + s.offset * q[i];
  }
  return u;
}

ArmDynamics psmDynamics() {
  auto link = [](double mass, Eigen::Vector3d com, Eigen::Vector3d principal) {
    return LinkInertia{mass, com, principal.asDiagonal()};
  };
  // Frames as in psmLargeNeedleDriver: link 1 turns about the yaw axis, link 2 is the pitch
  // parallelogram, link 3 the insertion stage with the instrument's back end (its frame's origin
  // sits on the shaft axis 0.43 m behind the tip at q3 = 0), link 4 the instrument shaft (frame at
  // the shaft's far end), links 5 and 6 the wrist and the jaw.
  std::vector<LinkInertia> links = {
      link(2.5, {0.04, 0.0, 0.02}, {0.05, 0.05, 0.03}),
      link(1.8, {-0.10, 0.06, 0.0}, {0.02, 0.03, 0.03}),
      link(0.8, {0.0, 0.0, 0.12}, {0.006, 0.006, 2e-4}),
      link(0.1, {0.0, 0.0, -0.2}, {4e-4, 4e-4, 2e-6}),
      link(0.01, {0.005, 0.0, 0.0}, {1e-7, 1e-7, 1e-7}),
      link(0.005, {0.006, 0.0, 0.0}, {5e-8, 5e-8, 5e-8}),
  };
  constexpr double tilt = 40 * std::numbers::pi / 180;
  const Eigen::Vector3d gravity = 9.81 * Eigen::Vector3d(0, std::cos(tilt), -std::sin(tilt));
  std::vector<double> armature = {0.03, 0.03, 0.4, 2e-4, 2e-4, 2e-4};
  std::vector<JointFriction> friction = {
      {0.05, 0.02, 0.02, 0.05, 1e-3},  {0.08, 0.03, 0.02, 0.05, 1e-3},  {0.6, 0.3, 0.005, 1.5, 1e-4},
      {0.004, 0.002, 0.05, 0.002, 1e-3}, {0.006, 0.002, 0.05, 0.002, 1e-3}, {0.006, 0.002, 0.05, 0.002, 1e-3},
  };
  // Spring counterbalance of the pitch parallelogram; the instrument's cables pull its roll and wrist
  // back towards their neutral positions, like springs.
  std::vector<JointSpring> springs(6);
  springs[1] = {0.6, 0.0, -0.8};
  springs[3] = {0.004, 0.0, 0.0};
  springs[4] = {0.02, 0.0, 0.0};
  springs[5] = {0.02, 0.0, 0.0};
  return ArmDynamics(psmLargeNeedleDriver(), std::move(links), gravity, std::move(armature), std::move(friction),
                     std::move(springs));
}

}  // namespace viscera::robot
