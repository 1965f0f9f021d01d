#include "robot/force/Identification.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/Error.h"

namespace viscera::robot {
namespace {

constexpr int kJointParameters = 5;  // armature, viscous, Coulomb, spring, offset

}  // namespace

PhysicalModel::PhysicalModel(const ArmDynamics& structure, IdentificationOptions options, Eigen::VectorXd parameters)
    : structure_(structure), options_(options), parameters_(std::move(parameters)) {
  if (parameters_.size() != parameterCount(dof()))
    throw Error("physical model: " + std::to_string(parameterCount(dof())) + " parameters expected, not " +
                std::to_string(parameters_.size()));
  if (!(options_.coulombVelocity > 0) || !(options_.accelerationWindow > 0))
    throw Error("physical model: the Coulomb velocity and the acceleration window must be positive");
}

std::vector<std::string> PhysicalModel::parameterNames(int dof) {
  static const char* link[] = {"m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz"};
  static const char* joint[] = {"armature", "viscous", "coulomb", "spring", "offset"};
  std::vector<std::string> names;
  for (int i = 1; i <= dof; ++i)
    for (const char* n : link) names.push_back("link" + std::to_string(i) + "." + n);
  for (int i = 1; i <= dof; ++i)
    for (const char* n : joint) names.push_back("joint" + std::to_string(i) + "." + n);
  return names;
}

Eigen::MatrixXd PhysicalModel::regressor(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                         const Eigen::VectorXd& qdd) const {
  const int n = dof();
  const int rigid = n * ArmDynamics::kLinkParameters;
  Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(n, parameterCount(n));
  Eigen::VectorXd unit = Eigen::VectorXd::Zero(rigid);
  for (int k = 0; k < rigid; ++k) {
    unit[k] = 1;
    Y.col(k) = structure_.rigidBody(q, qd, qdd, unit);
    unit[k] = 0;
  }
  for (int j = 0; j < n; ++j) {
    const int c = rigid + j * kJointParameters;
    Y(j, c) = qdd[j];
    Y(j, c + 1) = qd[j];
    Y(j, c + 2) = std::tanh(qd[j] / options_.coulombVelocity);
    Y(j, c + 3) = q[j];
    Y(j, c + 4) = 1;
  }
  return Y;
}

Eigen::VectorXd PhysicalModel::predict(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                       const Eigen::VectorXd& qdd) const {
  return regressor(q, qd, qdd) * parameters_;
}

Eigen::MatrixXd jointAccelerations(const JointStateLog& log, double window) {
  const int s = log.samples();
  Eigen::MatrixXd qdd = Eigen::MatrixXd::Zero(s, log.dof);
  if (s < 2) return qdd;
  const auto& t = log.series.t;
  const Eigen::MatrixXd qd = log.qd();
  int lo = 0, hi = 0;
  for (int i = 0; i < s; ++i) {
    while (lo < i && t[i] - t[lo] > window / 2) ++lo;
    while (hi + 1 < s && t[hi + 1] - t[i] <= window / 2) ++hi;
    int a = lo, b = std::max(hi, i);
    if (a == b) (b + 1 < s) ? ++b : --a;  // at least one interval
    qdd.row(i) = (qd.row(b) - qd.row(a)) / (t[b] - t[a]);
  }
  return qdd;
}

Eigen::MatrixXd PhysicalModel::predict(const JointStateLog& log) const {
  if (log.dof != dof()) throw Error(log.series.source + ": the log has " + std::to_string(log.dof) + " joints, the model " + std::to_string(dof()));
  const Eigen::MatrixXd qdd = jointAccelerations(log, options_.accelerationWindow);
  Eigen::MatrixXd out(log.samples(), dof());
  for (int i = 0; i < log.samples(); ++i)
    out.row(i) = predict(log.q().row(i).transpose(), log.qd().row(i).transpose(), qdd.row(i).transpose()).transpose();
  return out;
}

PhysicalModel PhysicalModel::identify(const ArmDynamics& structure, const std::vector<JointStateLog>& logs,
                                      const IdentificationOptions& options) {
  const int n = structure.dof();
  const int p = parameterCount(n);
  PhysicalModel model(structure, options, Eigen::VectorXd::Zero(p));
  // Each joint's rows weighted by 1 / (its effort's standard deviation), so that the wrist's small
  // efforts count as much as the outer joints' large ones.
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(n), sumSq = Eigen::VectorXd::Zero(n);
  long long count = 0;
  for (const JointStateLog& log : logs) {
    if (log.dof != n) throw Error(log.series.source + ": the log has " + std::to_string(log.dof) + " joints, the arm " + std::to_string(n));
    sum += log.effort().colwise().sum().transpose();
    sumSq += log.effort().colwise().squaredNorm().transpose();
    count += log.samples();
  }
  if (count < p) throw Error("identification needs at least " + std::to_string(p) + " samples, the logs hold " + std::to_string(count));
  const Eigen::VectorXd mean = sum / static_cast<double>(count);
  Eigen::VectorXd weight(n);
  for (int j = 0; j < n; ++j) {
    const double var = sumSq[j] / static_cast<double>(count) - mean[j] * mean[j];
    weight[j] = var > 0 ? 1 / std::sqrt(var) : 1;
  }
  // Normal equations accumulated sample by sample: the stacked regressor would not fit in memory.
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(p);
  for (const JointStateLog& log : logs) {
    const Eigen::MatrixXd qdd = jointAccelerations(log, options.accelerationWindow);
    for (int i = 0; i < log.samples(); ++i) {
      const Eigen::MatrixXd Y =
          weight.asDiagonal() * model.regressor(log.q().row(i).transpose(), log.qd().row(i).transpose(), qdd.row(i).transpose());
      A.selfadjointView<Eigen::Lower>().rankUpdate(Y.transpose());
      b += Y.transpose() * weight.cwiseProduct(log.effort().row(i).transpose());
    }
  }
  A.triangularView<Eigen::StrictlyUpper>() = A.transpose();
  // Columns scaled to unit diagonal, then the pseudo-inverse through the eigen-decomposition:
  // parameter combinations the data do not excite get no value rather than a huge one.
  Eigen::VectorXd scale = A.diagonal().cwiseSqrt();
  for (int k = 0; k < p; ++k)
    if (!(scale[k] > 0)) scale[k] = 1;
  const Eigen::MatrixXd As = scale.cwiseInverse().asDiagonal() * A * scale.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(As);
  const Eigen::VectorXd& values = eig.eigenvalues();
  const double cutoff = options.relativeCutoff * values.maxCoeff();
  Eigen::VectorXd inverse = Eigen::VectorXd::Zero(p);
  for (int k = 0; k < p; ++k)
    if (values[k] > cutoff) inverse[k] = 1 / values[k];
  const Eigen::VectorXd y = eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose() *
                            scale.cwiseInverse().asDiagonal() * b;
  model.parameters_ = scale.cwiseInverse().asDiagonal() * y;
  return model;
}

std::string PhysicalModel::toJson() const {
  nlohmann::ordered_json j;
  j["kind"] = "physical";
  j["dof"] = dof();
  j["gravity"] = {structure_.gravity().x(), structure_.gravity().y(), structure_.gravity().z()};
  j["coulombVelocity"] = options_.coulombVelocity;
  j["accelerationWindow"] = options_.accelerationWindow;
  nlohmann::ordered_json params;
  const std::vector<std::string> names = parameterNames(dof());
  for (int k = 0; k < parameters_.size(); ++k) params[names[k]] = parameters_[k];
  j["parameters"] = params;
  return j.dump(2) + "\n";
}

PhysicalModel PhysicalModel::fromJson(const std::string& text, const std::string& source, const ArmDynamics& structure) {
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    if (j.at("kind").get<std::string>() != "physical") throw Error(source + ": not a physical model (kind " + viscera::quoted(j.at("kind").dump()) + ")");
    if (j.at("dof").get<int>() != structure.dof())
      throw Error(source + ": a model of " + std::to_string(j.at("dof").get<int>()) + " joints, the arm has " + std::to_string(structure.dof()));
    IdentificationOptions o;
    o.coulombVelocity = j.at("coulombVelocity").get<double>();
    o.accelerationWindow = j.at("accelerationWindow").get<double>();
    const std::vector<std::string> names = parameterNames(structure.dof());
    Eigen::VectorXd p(static_cast<Eigen::Index>(names.size()));
    for (size_t k = 0; k < names.size(); ++k) {
      const auto& v = j.at("parameters").at(names[k]);
      if (!v.is_number()) throw Error(source + ": parameters." + names[k] + " is not a number");
      p[static_cast<Eigen::Index>(k)] = v.get<double>();
    }
    return PhysicalModel(structure, o, p);
  } catch (const nlohmann::json::exception& e) {
    throw Error(source + ": not a physical model: " + e.what());
  }
}

Vector6d wrenchFromExternalEfforts(const Jacobian& J, const Eigen::VectorXd& tau, double damping) {
  if (tau.size() != J.cols()) throw Error("wrench from efforts: the Jacobian has " + std::to_string(J.cols()) + " columns, the efforts " + std::to_string(tau.size()));
  const Eigen::Matrix<double, 6, 6> A = J * J.transpose() + damping * damping * Eigen::Matrix<double, 6, 6>::Identity();
  return A.ldlt().solve(J * tau);
}

}  // namespace viscera::robot
