// TetrahedronHyperelasticityFEMForceField (and SOFA's StandardTetrahedralFEMForceField, the same
// elements): linear tetrahedra with a hyperelastic law. Per element, F = sum_j (x_j - x_0) (x) s_j
// with s_j the rest gradients of the barycentric coordinates, C = F^T F, J the volume ratio; the
// force on vertex a is -V0 F S s_a and the stiffness the consistent tangent
// df_a/dx_b = -V0 [(s_b . S s_a) I + F dS(H) s_a], H = s_b (x) F^T e + F^T e (x) s_b for each
// direction e of x_b, as SOFA computes them. The tangent is assembled at each force evaluation.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/fem/HyperelasticMaterials.h"
#include "solvers/linear/BlockSparseMatrix.h"
#include "engine/mechanics/MechanicalObject.h"

namespace viscera {

namespace {

class HyperelasticFEMForceField : public Component, public ForceField, public Stateful {
 public:
  using Component::Component;
  MechanicalObject& mstate() const override { return *state_; }
  // The tangent blocks at the last addForce: 16 per element, df_a/dx_b at 4 a + b.
  struct Live : ComponentStateOf<Live> {
    std::vector<Eigen::Matrix3d> K;
    void save(StateWriter& out) const override { out.put(K); }
    void load(StateReader& in) override { in.getSameSize(K, "tangent blocks"); }
  };
  std::unique_ptr<ComponentState> initialState() const override {
    auto l = std::make_unique<Live>();
    l->K.assign(16 * static_cast<size_t>(tets_.cols()), Eigen::Matrix3d::Zero());
    return l;
  }

  void init() override {
    state_ = &contextState(*this);
    tets_ = contextTopology(*this, "topology", false).tetrahedra();
    if (tets_.cols() == 0) throw error("the topology has no tetrahedra");
    const std::string law = attrs_.str("materialName");
    const auto& laws = fem::hyperelasticMaterials();
    const auto info = std::find_if(laws.begin(), laws.end(), [&](const fem::MaterialInfo& m) { return law == m.name; });
    if (info == laws.end()) throw error("materialName", "'" + law + "' is not a supported law");
    const auto& p = attrs_.reals("ParameterSet");
    if (static_cast<int>(p.size()) != info->count)
      throw error("ParameterSet", law + " takes " + std::to_string(info->count) + " parameters (" + info->parameters +
                                      "), got " + std::to_string(p.size()));
    material_ = fem::makeHyperelasticMaterial(law, p);
    const Eigen::Matrix3Xd& X = state_->x0;
    const Eigen::Index n = tets_.cols();
    grad_.resize(static_cast<size_t>(n));
    volume_.resize(static_cast<size_t>(n));
    vol6_.resize(static_cast<size_t>(n));
    for (Eigen::Index e = 0; e < n; ++e) {
      for (int k = 0; k < 4; ++k)
        if (tets_(k, e) < 0 || tets_(k, e) >= X.cols())
          throw error("tetrahedron " + std::to_string(e) + " refers to node " + std::to_string(tets_(k, e)) +
                      ", but MechanicalObject '" + state_->name() + "' has " + std::to_string(X.cols()));
      Eigen::Vector3d p4[4];
      for (int k = 0; k < 4; ++k) p4[k] = X.col(tets_(k, e));
      const double vol6 = ((p4[2] - p4[0]).cross(p4[3] - p4[0])).dot(p4[1] - p4[0]);
      if (vol6 == 0) throw error("tetrahedron " + std::to_string(e) + " is flat at rest");
      auto& s = grad_[static_cast<size_t>(e)];
      for (int j = 0; j < 4; ++j) {
        const Eigen::Vector3d c = (p4[(j + 2) % 4] - p4[(j + 1) % 4]).cross(p4[(j + 3) % 4] - p4[(j + 1) % 4]) / vol6;
        s[j] = j % 2 == 0 ? Eigen::Vector3d(-c) : c;
      }
      vol6_[static_cast<size_t>(e)] = vol6;
      volume_[static_cast<size_t>(e)] = std::abs(vol6 / 6);
    }
  }

  void addForce(State& st, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd&, Eigen::Matrix3Xd& f) const override {
    std::vector<Eigen::Matrix3d>& K = stateIn<Live>(st).K;
    for (Eigen::Index e = 0; e < tets_.cols(); ++e) {
      const size_t ue = static_cast<size_t>(e);
      const auto& s = grad_[ue];
      Eigen::Matrix3d F;
      double J;
      deformation(x, e, F, J);
      const Eigen::Matrix3d C = F.transpose() * F;
      const Eigen::Matrix3d S = material_->stress(C, J);
      const double V = volume_[ue];
      for (int a = 0; a < 4; ++a) f.col(tets_(a, e)) -= V * (F * (S * s[a]));
      // The consistent tangent, column by column (vertex b, direction m).
      for (int b = 0; b < 4; ++b)
        for (int m = 0; m < 3; ++m) {
          const Eigen::Vector3d Fe = F.row(m).transpose();  // F^T e_m
          const Eigen::Matrix3d H = s[b] * Fe.transpose() + Fe * s[b].transpose();
          const Eigen::Matrix3d dS = material_->stressDerivative(C, J, H);
          for (int a = 0; a < 4; ++a) {
            Eigen::Vector3d col = -V * (F * (dS * s[a]));
            col[m] -= V * s[b].dot(S * s[a]);
            K[16 * ue + 4 * a + b].col(m) = col;
          }
        }
    }
  }
  void addDForce(const State& st, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const override {
    const std::vector<Eigen::Matrix3d>& K = stateIn<Live>(st).K;
    for (Eigen::Index e = 0; e < tets_.cols(); ++e)
      for (int a = 0; a < 4; ++a) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int b = 0; b < 4; ++b) sum += K[16 * static_cast<size_t>(e) + 4 * a + b] * dx.col(tets_(b, e));
        df.col(tets_(a, e)) += kFactor * sum;
      }
  }
  void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const override {
    for (Eigen::Index e = 0; e < tets_.cols(); ++e)
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) pairs.push_back({tets_(a, e), tets_(b, e)});
  }
  void addStiffness(const State& st, BlockSparseMatrix& M, double kFactor) const override {
    const std::vector<Eigen::Matrix3d>& K = stateIn<Live>(st).K;
    for (Eigen::Index e = 0; e < tets_.cols(); ++e)
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const int i = tets_(a, e), j = tets_(b, e);
          M.block(i == j ? M.diagonalSlot(i) : M.slot(i, j)) += kFactor * K[16 * static_cast<size_t>(e) + 4 * a + b];
        }
  }
  double potentialEnergy(const Eigen::Matrix3Xd& x) const override {
    double w = 0;
    for (Eigen::Index e = 0; e < tets_.cols(); ++e) {
      Eigen::Matrix3d F;
      double J;
      deformation(x, e, F, J);
      w += volume_[static_cast<size_t>(e)] * material_->energy(F.transpose() * F, J);
    }
    return w;
  }
  std::vector<int> invertedElements(const Eigen::Matrix3Xd& x) const override {
    std::vector<int> bad;
    if (material_->definedWhenInverted()) return bad;
    for (Eigen::Index e = 0; e < tets_.cols(); ++e) {
      Eigen::Matrix3d F;
      double J;
      deformation(x, e, F, J);
      if (!(J > 0)) bad.push_back(static_cast<int>(e));
    }
    return bad;
  }

 private:
  // F and the signed volume ratio J of element e at x (J from the volumes, as SOFA).
  void deformation(const Eigen::Matrix3Xd& x, Eigen::Index e, Eigen::Matrix3d& F, double& J) const {
    const auto& s = grad_[static_cast<size_t>(e)];
    const Eigen::Vector3d x0 = x.col(tets_(0, e));
    const Eigen::Vector3d d0 = x.col(tets_(1, e)) - x0, d1 = x.col(tets_(2, e)) - x0, d2 = x.col(tets_(3, e)) - x0;
    F = d0 * s[1].transpose() + d1 * s[2].transpose() + d2 * s[3].transpose();
    J = d1.cross(d2).dot(d0) / vol6_[static_cast<size_t>(e)];
  }

  MechanicalObject* state_ = nullptr;
  TetList tets_;
  std::unique_ptr<fem::HyperelasticMaterial> material_;
  std::vector<std::array<Eigen::Vector3d, 4>> grad_;  // rest gradients of the barycentric coordinates
  std::vector<double> volume_, vol6_;                 // rest volume, and six times its signed value
};

}  // namespace

void registerHyperelasticFEM(Registry& r) {
  std::string laws;
  for (const auto& m : fem::hyperelasticMaterials())
    laws += std::string(laws.empty() ? "" : "; ") + m.name + ": " + m.parameters;
  ComponentSpec s;
  s.name = "TetrahedronHyperelasticityFEMForceField";
  s.aliases = {"StandardTetrahedralFEMForceField"};
  s.category = "fem";
  s.doc = "Linear tetrahedra with a hyperelastic law, as SOFA's: the force -V0 F S s_a on each vertex (S the second "
          "Piola-Kirchhoff stress of C = F^T F, s_a the rest gradient of its barycentric coordinate) and the consistent "
          "tangent (geometric and material parts). Laws and their ParameterSet: " + laws +
          ". The volume ratio J is from the signed volumes; an element with J <= 0 stops the run, except under the laws "
          "defined there (StVenantKirchhoff, StableNeoHookean).";
  std::vector<std::string> names;
  for (const auto& m : fem::hyperelasticMaterials()) names.push_back(m.name);
  s.add(AttrSpec::choice("materialName", names).def("ArrudaBoyce").help("the law (SOFA's default: ArrudaBoyce)"));
  s.add(AttrSpec::reals("ParameterSet").req().help("the law's parameters, in its order (above), as plain numbers"));
  s.add(AttrSpec::link("topology").help("tetrahedral topology (default: the last one in the node or above)"));
  s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node or above)"));
  s.factory = [](BuildContext& c) { return std::make_unique<HyperelasticFEMForceField>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
