#include "learning/force/ForceModel.h"

#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/Error.h"
#include "core/Files.h"

namespace viscera::learning {

namespace fs = std::filesystem;

Eigen::MatrixXf windowed(const Eigen::MatrixXd& features, int window) {
  const Eigen::Index n = features.rows(), f = features.cols();
  Eigen::MatrixXf out(n, window * f);
  for (Eigen::Index i = 0; i < n; ++i)
    for (int w = 0; w < window; ++w) {
      const Eigen::Index src = std::max<Eigen::Index>(0, i - (window - 1) + w);
      out.row(i).segment(w * f, f) = features.row(src).cast<float>();
    }
  return out;
}

Eigen::MatrixXf ForceModel::networkInputs(const robot::JointStateLog& log) const {
  if (log.dof != dof) throw Error(log.series.source + ": the log has " + std::to_string(log.dof) + " joints, the model " + std::to_string(dof));
  Eigen::MatrixXd features;
  if (kind == "direct") {
    features.resize(log.samples(), 2 * dof);
    features << log.qd(), log.effort();
  } else if (base && baseInputs) {
    features.resize(log.samples(), 3 * dof);
    features << log.q(), log.qd(), base->freeSpaceEfforts(log);
  } else {
    features.resize(log.samples(), 2 * dof);
    features << log.q(), log.qd();
  }
  return windowed(features, window);
}

Eigen::MatrixXd ForceModel::freeSpaceEfforts(const robot::JointStateLog& log) const {
  if (kind == "physical") return physical->predict(log);
  if (kind != "network") throw Error("a " + kind + " force model predicts no free-space efforts");
  Eigen::MatrixXd out = network->predict(networkInputs(log)).cast<double>();
  if (base) out += base->freeSpaceEfforts(log);
  return out;
}

Eigen::VectorXd ForceModel::lastFreeSpaceEffort(const robot::JointStateLog& log) const {
  if (log.samples() == 0) throw Error(log.series.source + ": no samples");
  if (kind == "physical") return physical->predict(log).bottomRows(1).transpose();
  if (kind != "network") throw Error("a " + kind + " force model predicts no free-space efforts");
  Eigen::VectorXd out = network->predict(networkInputs(log).bottomRows(1)).cast<double>().transpose();
  if (base) out += base->lastFreeSpaceEffort(log);
  return out;
}

robot::Vector6d ForceModel::lastWrench(const robot::JointStateLog& log, double damping) const {
  robot::Vector6d w = robot::Vector6d::Zero();
  if (kind == "direct") {
    w.head(wrenchOutputs) = network->predict(networkInputs(log).bottomRows(1)).cast<double>().transpose();
    return w;
  }
  const Eigen::VectorXd q = log.q().bottomRows(1).transpose();
  const Eigen::VectorXd external = log.effort().bottomRows(1).transpose() - lastFreeSpaceEffort(log);
  return robot::wrenchFromExternalEfforts(robot::psmLargeNeedleDriver().spatialJacobian(q), external, damping);
}

Eigen::MatrixXd ForceModel::wrenches(const robot::JointStateLog& log, const Eigen::MatrixXd* jacobian, double damping) const {
  const int n = log.samples();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(n, 6);
  if (kind == "direct") {
    out.leftCols(wrenchOutputs) = network->predict(networkInputs(log)).cast<double>();
    return out;
  }
  if (jacobian && (jacobian->rows() != n || jacobian->cols() != 6 * dof))
    throw Error("the Jacobian log needs one row of " + std::to_string(6 * dof) + " values per joint state sample");
  const Eigen::MatrixXd external = log.effort() - freeSpaceEfforts(log);
  const robot::SerialChain psm = robot::psmLargeNeedleDriver();
  for (int i = 0; i < n; ++i) {
    robot::Jacobian J(6, dof);
    if (jacobian) {
      for (int r = 0; r < 6; ++r)
        for (int c = 0; c < dof; ++c) J(r, c) = (*jacobian)(i, r * dof + c);
    } else {
      J = psm.spatialJacobian(log.q().row(i).transpose());
    }
    out.row(i) = robot::wrenchFromExternalEfforts(J, external.row(i).transpose(), damping).transpose();
  }
  return out;
}

void ForceModel::save(const std::string& folder) const {
  fs::create_directories(folder);
  nlohmann::ordered_json j;
  j["format"] = "viscera force model";
  j["version"] = 1;
  j["kind"] = kind;
  j["description"] = description;
  j["rate"] = rate;
  j["dof"] = dof;
  j["window"] = window;
  j["training"] = training.empty() ? nlohmann::ordered_json::object() : nlohmann::ordered_json::parse(training);
  if (kind == "direct") j["wrenchOutputs"] = wrenchOutputs;
  if (kind == "physical") {
    writeFileAtomic((fs::path(folder) / "physical.json").string(), physical->toJson());
    j["physical"] = "physical.json";
  } else {
    network->save((fs::path(folder) / "network").string(), training);
    j["network"] = "network";
  }
  if (base) {
    base->save((fs::path(folder) / "base").string());
    j["base"] = "base";
    j["baseInputs"] = baseInputs;
  }
  writeFileAtomic((fs::path(folder) / "force.json").string(), j.dump(2) + "\n");
}

ForceModel ForceModel::load(const std::string& folder) {
  const std::string path = (fs::path(folder) / "force.json").string();
  if (!fs::is_directory(folder)) throw Error(folder + ": not a force model folder");
  if (!fs::exists(path)) throw Error(folder + ": not a force model (no force.json)");
  try {
    const nlohmann::json j = nlohmann::json::parse(readInputFile(path, "force model"));
    ForceModel m;
    m.kind = j.at("kind").get<std::string>();
    m.description = j.value("description", "");
    if (j.contains("training")) m.training = j.at("training").dump();
    m.rate = j.at("rate").get<double>();
    m.dof = j.at("dof").get<int>();
    m.window = j.at("window").get<int>();
    if (!(m.rate > 0) || m.dof < 1 || m.window < 1) throw Error(path + ": rate, dof and window must be positive");
    if (m.kind == "physical") {
      const std::string p = (fs::path(folder) / j.at("physical").get<std::string>()).string();
      m.physical = robot::PhysicalModel::fromJson(readInputFile(p, "physical model"), p, robot::psmDynamics());
    } else if (m.kind == "network" || m.kind == "direct") {
      m.network = Regressor::load((fs::path(folder) / j.at("network").get<std::string>()).string());
      if (m.kind == "direct") {
        m.wrenchOutputs = j.at("wrenchOutputs").get<int>();
        if (m.wrenchOutputs != 3 && m.wrenchOutputs != 6) throw Error(path + ": wrenchOutputs must be 3 (force) or 6 (wrench)");
      }
    } else {
      throw Error(path + ": unknown kind " + viscera::quoted(m.kind) + " (physical, network or direct)");
    }
    if (j.contains("base")) {
      m.base = std::make_shared<ForceModel>(load((fs::path(folder) / j.at("base").get<std::string>()).string()));
      m.baseInputs = j.value("baseInputs", false);
      if (m.base->rate != m.rate || m.base->dof != m.dof) throw Error(path + ": the base model works at another rate or joint count");
    }
    if (m.network) {
      const RegressorArchitecture& a = m.network->architecture();
      const int features = m.kind == "direct" ? 2 * m.dof : (m.base && m.baseInputs ? 3 * m.dof : 2 * m.dof);
      const int outputs = m.kind == "direct" ? m.wrenchOutputs : m.dof;
      if (a.window != m.window || a.features != features || a.outputs != outputs)
        throw Error(path + ": the network's inputs or outputs do not fit the model (window " + std::to_string(a.window) +
                    ", features " + std::to_string(a.features) + ", outputs " + std::to_string(a.outputs) + ")");
    }
    return m;
  } catch (const nlohmann::json::exception& e) {
    throw Error(path + ": not a force model: " + e.what());
  }
}

}  // namespace viscera::learning
