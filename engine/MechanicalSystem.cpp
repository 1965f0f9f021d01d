#include <Eigen/Dense>
#include "engine/MechanicalSystem.h"

#include <cstdlib>
#include <string>

#include <Eigen/Eigenvalues>
#include <map>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"

namespace viscera {

std::string Diverged::str() const {
  std::ostringstream s;
  s << "diverged at step " << step << " (t = " << time << "): " << reason;
  if (!object.empty()) s << " [" << object << "]";
  auto list = [&s](const char* what, const std::vector<int>& ids) {
    if (ids.empty()) return;
    s << "; " << what << " ";
    for (size_t i = 0; i < ids.size() && i < 20; ++i) s << (i ? "," : "") << ids[i];
    if (ids.size() > 20) s << ",... (" << ids.size() << " in all)";
  };
  list("elements", elements);
  list("nodes", nodes);
  return s.str();
}

namespace {
MechanicalObject& nodeState(Component& owner) {
  MechanicalObject* m = owner.node().find<MechanicalObject>();
  if (!m) throw owner.error("needs a MechanicalObject in its node");
  return *m;
}
}  // namespace

MechanicalSystem::MechanicalSystem(Component& owner) : MechanicalSystem(owner, nodeState(owner)) {}

MechanicalSystem::MechanicalSystem(Component& owner, MechanicalObject& body) {
  Node& node = body.node();
  state_ = &body;
  owner.scene().initComponent(*state_);
  const int n = state_->size();
  mass_ = Eigen::VectorXd::Zero(n);
  diagonalMass_ = Eigen::VectorXd::Zero(n);
  bool hasMass = false;
  std::map<int, std::vector<Eigen::Vector3d>> held;
  std::map<int, std::pair<const Component*, bool>> constrainedBy;  // node -> first constraint, whether it prescribes motion
  std::vector<Component*> comps;
  node.collect(comps);
  for (Component* c : comps) {
    if (c == &owner || dynamic_cast<OdeSolver*>(c) || dynamic_cast<Observer*>(c)) continue;
    if (!dynamic_cast<Mass*>(c) && !dynamic_cast<ForceField*>(c) && !dynamic_cast<ProjectiveConstraint*>(c)) continue;
    owner.scene().initComponent(*c);
    if (auto* m = dynamic_cast<Mass*>(c); m && &m->mstate() == state_) {
      mass_ += m->nodeMass();
      if (m->consistent()) consistent_.push_back(m);
      else diagonalMass_ += m->nodeMass();
      hasMass = true;
    }
    if (auto* f = dynamic_cast<ForceField*>(c); f && &f->mstate() == state_) forces_.push_back(f);
    if (auto* p = dynamic_cast<ProjectiveConstraint*>(c); p && &p->mstate() == state_) {
      fixed_.insert(fixed_.end(), p->fixedNodes().begin(), p->fixedNodes().end());
      for (const auto& [node, dir] : p->heldDirections()) held[node].push_back(dir);
      // A prescribed motion must be alone on its nodes: another constraint would hold them
      // against it, or move them off its path.
      const bool sets = p->prescribesMotion();
      std::vector<int> nodes = p->fixedNodes();
      for (const auto& hd : p->heldDirections()) nodes.push_back(hd.first);
      std::sort(nodes.begin(), nodes.end());
      nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
      for (int i : nodes) {
        auto [it, first] = constrainedBy.insert({i, {c, sets}});
        if (!first && it->second.first != c && (sets || it->second.second))
          throw c->error("node " + std::to_string(i) + " of '" + state_->name() + "' is also held by " +
                         it->second.first->typeName() + " '" + it->second.first->name() +
                         "'; a node on a prescribed motion takes no other constraint");
      }
    }
  }
  for (InteractionForceField* ff : owner.scene().all<InteractionForceField>()) {
    owner.scene().initComponent(dynamic_cast<Component&>(*ff));
    if (&ff->object(0) == state_ && &ff->object(1) == state_) internal_.push_back(ff);
  }
  // Partly held nodes: the span of their held directions is removed from their motion; three
  // independent directions fix the node.
  for (const auto& [node, dirs] : held) {
    Eigen::Matrix3d N = Eigen::Matrix3d::Zero();
    for (const auto& d : dirs) N += d * d.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(N);
    Eigen::Matrix3d P = Eigen::Matrix3d::Identity();
    int rank = 0;
    for (int k = 0; k < 3; ++k)
      if (eig.eigenvalues()[k] > 1e-9) {
        P -= eig.eigenvectors().col(k) * eig.eigenvectors().col(k).transpose();
        ++rank;
      }
    if (rank == 3) fixed_.push_back(node);
    else partial_.push_back({node, P});
  }
  if (!hasMass) {
    if (!forces_.empty() || !internal_.empty())
      throw owner.error("no mass acts on MechanicalObject '" + state_->name() + "' (add UniformMass, DiagonalMass or MeshMatrixMass)");
    // Neither mass nor force: SOFA's solve leaves such a state where it is. Its nodes are held
    // (a unit mass keeps the system regular; gravity on it is held too).
    owner.scene().addNote(state_->loc().str() + ": note: nothing acts on MechanicalObject '" + state_->name() +
                          "' (no mass, no force field): it stays where it is");
    mass_.setOnes();
    diagonalMass_.setOnes();
    fixed_.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) fixed_[static_cast<size_t>(i)] = i;
  }
  std::sort(fixed_.begin(), fixed_.end());
  fixed_.erase(std::unique(fixed_.begin(), fixed_.end()), fixed_.end());
  // A fixed node needs no projector.
  partial_.erase(std::remove_if(partial_.begin(), partial_.end(),
                                [&](const auto& p) { return std::binary_search(fixed_.begin(), fixed_.end(), p.first); }),
                 partial_.end());
}

int MechanicalSystem::nodes() const { return state_->size(); }

void MechanicalSystem::computeForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v,
                                    Eigen::Matrix3Xd& f) const {
  f.setZero(3, x.cols());
  for (ForceField* ff : forces_) ff->addForce(s, x, v, f);
  for (const InteractionForceField* ff : internal_) ff->addForce(s, {&x, &x}, {&v, &v}, {&f, &f});
}

void MechanicalSystem::addKdx(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double factor,
                              double undampedScale) const {
  for (ForceField* ff : forces_) ff->addDForce(s, dx, df, ff->rayleighDamped() ? factor : factor * undampedScale);
  for (const InteractionForceField* ff : internal_) ff->addDForce(s, {&dx, &dx}, {&df, &df}, factor);
}

void MechanicalSystem::prepareAssembly() {
  if (patternReady_) return;
  std::vector<std::pair<int, int>> pairs;
  for (ForceField* ff : forces_) ff->stiffnessPattern(pairs);
  for (const InteractionForceField* ff : internal_) {
    std::vector<std::array<int, 4>> blocks;
    ff->stiffnessPattern(blocks);
    for (const auto& b : blocks) pairs.push_back({b[1], b[3]});
  }
  for (Mass* m : consistent_) m->massPattern(pairs);
  pattern_.setPattern(nodes(), pairs);
  for (ForceField* ff : forces_) ff->prepareAssembly(pattern_);
  patternReady_ = true;
}

bool MechanicalSystem::prepareUpperAssembly() {
  if (!patternReady_) throw std::logic_error("MechanicalSystem::prepareUpperAssembly before prepareAssembly");
  if (upperPattern_.upper()) return true;
  // VISCERA_MATRIX=full keeps the full storage (to compare, or to rule the upper storage out).
  static const bool fullOnly = [] {
    const char* e = std::getenv("VISCERA_MATRIX");
    return e && std::string(e) == "full";
  }();
  if (fullOnly || !internal_.empty() || !consistent_.empty()) return false;
  for (const ForceField* ff : forces_)
    if (!ff->assemblesUpper()) return false;
  std::vector<std::pair<int, int>> pairs;
  for (ForceField* ff : forces_) ff->stiffnessPattern(pairs);
  upperPattern_.setPattern(nodes(), pairs, BlockSparseMatrix::Storage::Upper);
  for (ForceField* ff : forces_) ff->prepareAssembly(upperPattern_);
  return true;
}

void MechanicalSystem::assembleStiffness(const State& s, BlockSparseMatrix& K, double undampedScale, double factor) const {
  if (!patternReady_) throw std::logic_error("MechanicalSystem::assembleStiffness before prepareAssembly");
  if (K.blockRows() != nodes()) K = pattern_;
  const auto scaled = [&](const ForceField* ff) { return factor * (ff->rayleighDamped() ? 1.0 : undampedScale); };
  // The first field that can set the matrix does (no zeroing first); the others add in their order.
  size_t setter = 0;
  while (setter < forces_.size() && !forces_[setter]->setStiffness(s, K, scaled(forces_[setter]))) ++setter;
  if (setter == forces_.size()) K.setZero();
  for (size_t k = 0; k < forces_.size(); ++k)
    if (k != setter) forces_[k]->addStiffness(s, K, scaled(forces_[k]));
  for (const InteractionForceField* ff : internal_)
    ff->forEachStiffnessBlock(s, [&](int, int i, int, int j, const Eigen::Matrix3d& Kij) { K.block(K.slot(i, j)) += factor * Kij; });
}

void MechanicalSystem::addMdx(const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& out, double factor) const {
  for (int i = 0; i < dx.cols(); ++i) out.col(i) += (dx.col(i) * diagonalMass_[i]) * factor;
  for (Mass* m : consistent_) m->addMdx(dx, out, factor);
}

void MechanicalSystem::addMass(BlockSparseMatrix& A, double factor) const {
  for (int i = 0; i < nodes(); ++i) A.block(A.diagonalSlot(i)).diagonal().array() += factor * diagonalMass_[i];
  for (Mass* m : consistent_) m->addMassMatrix(A, factor);
}

void MechanicalSystem::project(Eigen::Matrix3Xd& v) const {
  for (int i : fixed_) v.col(i).setZero();
  for (const auto& [i, P] : partial_) v.col(i) = P * v.col(i);
}

Eigen::Matrix3d MechanicalSystem::projector(int i) const {
  if (std::binary_search(fixed_.begin(), fixed_.end(), i)) return Eigen::Matrix3d::Zero();
  for (const auto& [n, P] : partial_)
    if (n == i) return P;
  return Eigen::Matrix3d::Identity();
}

void MechanicalSystem::constrain(BlockSparseMatrix& A) const {
  A.constrainNodes(fixed_);
  A.projectNodes(partial_);
}

std::optional<Diverged> MechanicalSystem::check(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, int step,
                                                double time) const {
  Diverged d;
  d.step = step;
  d.time = time;
  d.object = state_->name();
  for (int i = 0; i < x.cols(); ++i)
    if (!x.col(i).allFinite() || !v.col(i).allFinite()) d.nodes.push_back(i);
  if (!d.nodes.empty()) {
    d.reason = "non-finite position or velocity";
    return d;
  }
  for (ForceField* ff : forces_) {
    auto bad = ff->invertedElements(x);
    d.elements.insert(d.elements.end(), bad.begin(), bad.end());
  }
  if (!d.elements.empty()) {
    d.reason = "inverted elements";
    return d;
  }
  return std::nullopt;
}

double MechanicalSystem::potentialEnergy(const Eigen::Matrix3Xd& x) const {
  double e = 0;
  for (ForceField* ff : forces_) e += ff->potentialEnergy(x);
  return e;
}

}  // namespace viscera
