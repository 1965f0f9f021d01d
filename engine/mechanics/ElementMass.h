// Mass matrices assembled from element matrices, shared by the masses and by force fields that
// carry their own mass (HexahedronFEMForceFieldAndMass).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace viscera {

class BlockSparseMatrix;
struct FieldValue;

// A mass matrix assembled from element matrices: M_e (k x k scalars, times the 3 x 3 identity)
// over each element's k nodes. Its rows summed are the lumped masses.
class ElementMassMatrix {
 public:
  // Elements as columns of node indices (4 for tetrahedra, 8 for hexahedra), one k x k matrix each.
  void set(Eigen::MatrixXi elements, std::vector<Eigen::MatrixXd> matrices) {
    elements_ = std::move(elements);
    matrices_ = std::move(matrices);
  }
  Eigen::VectorXd rowSums(int nodes) const {
    Eigen::VectorXd m = Eigen::VectorXd::Zero(nodes);
    for (int e = 0; e < elements_.cols(); ++e)
      for (int i = 0; i < elements_.rows(); ++i) m[elements_(i, e)] += matrices_[e].row(i).sum();
    return m;
  }
  void pattern(std::vector<std::pair<int, int>>& pairs) const {
    for (int e = 0; e < elements_.cols(); ++e)
      for (int i = 0; i < elements_.rows(); ++i)
        for (int j = i + 1; j < elements_.rows(); ++j) pairs.push_back({elements_(i, e), elements_(j, e)});
  }
  void addMdx(const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& out, double factor) const {
    for (int e = 0; e < elements_.cols(); ++e)
      for (int i = 0; i < elements_.rows(); ++i) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int j = 0; j < elements_.rows(); ++j) sum += matrices_[e](i, j) * dx.col(elements_(j, e));
        out.col(elements_(i, e)) += factor * sum;
      }
  }
  void addTo(BlockSparseMatrix& A, double factor) const;

 private:
  Eigen::MatrixXi elements_;
  std::vector<Eigen::MatrixXd> matrices_;
};

// Gravity through lumped masses m (one per node): f += m_i g, its potential energy -sum m_i g.x_i,
// and the fields every mass offers (vertexMass, totalMass).
void addGravity(const Eigen::VectorXd& m, const Eigen::Vector3d& g, Eigen::Matrix3Xd& f);
double gravityEnergy(const Eigen::VectorXd& m, const Eigen::Vector3d& g, const Eigen::Matrix3Xd& x);
bool massField(const Eigen::VectorXd& m, const std::string& name, FieldValue& out);

// The consistent mass matrix int rho N_i N_j dV of a trilinear hexahedron with corners in SOFA's
// (and RegularGridTopology's) node order, by 2 x 2 x 2 Gauss points: exact for a uniform density
// on a parallelepiped. `density` is given the eight shape-function values at each point.
Eigen::MatrixXd hexahedronMassMatrix(const Eigen::Matrix<double, 3, 8>& corners,
                                     const std::function<double(const Eigen::VectorXd& N)>& density);

}  // namespace viscera
