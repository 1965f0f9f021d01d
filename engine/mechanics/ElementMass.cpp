#include "engine/mechanics/ElementMass.h"

#include <Eigen/Dense>
#include <cmath>
#include <stdexcept>

#include "core/Component.h"
#include "solvers/linear/BlockSparseMatrix.h"

namespace viscera {

void ElementMassMatrix::addTo(BlockSparseMatrix& A, double factor) const {
  for (int e = 0; e < elements_.cols(); ++e)
    for (int i = 0; i < elements_.rows(); ++i)
      for (int j = 0; j < elements_.rows(); ++j) {
        const int slot = A.slot(elements_(i, e), elements_(j, e));
        if (slot < 0) throw std::logic_error("mass matrix: the matrix pattern lacks the mass's node pairs");
        A.block(slot).diagonal().array() += factor * matrices_[e](i, j);
      }
}

void addGravity(const Eigen::VectorXd& m, const Eigen::Vector3d& g, Eigen::Matrix3Xd& f) {
  if (g.isZero()) return;
  for (int i = 0; i < f.cols(); ++i) f.col(i) += m[i] * g;
}

double gravityEnergy(const Eigen::VectorXd& m, const Eigen::Vector3d& g, const Eigen::Matrix3Xd& x) {
  double e = 0;
  for (int i = 0; i < x.cols(); ++i) e -= m[i] * g.dot(x.col(i));
  return e;
}

bool massField(const Eigen::VectorXd& m, const std::string& name, FieldValue& out) {
  if (name == "vertexMass") out.values.assign(m.data(), m.data() + m.size());
  else if (name == "totalMass") out.values = {m.sum()};
  else return false;
  return true;
}

Eigen::MatrixXd hexahedronMassMatrix(const Eigen::Matrix<double, 3, 8>& corners,
                                     const std::function<double(const Eigen::VectorXd& N)>& density) {
  // Corner signs of the reference cube.
  static const int sign[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                 {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
  const double g = 1.0 / std::sqrt(3.0);
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(8, 8);
  for (int q = 0; q < 8; ++q) {
    const Eigen::Vector3d xi(sign[q][0] * g, sign[q][1] * g, sign[q][2] * g);
    Eigen::VectorXd N(8);
    Eigen::Matrix<double, 8, 3> dN;
    for (int k = 0; k < 8; ++k) {
      const double a = 1 + sign[k][0] * xi[0], b = 1 + sign[k][1] * xi[1], c = 1 + sign[k][2] * xi[2];
      N[k] = a * b * c / 8;
      dN.row(k) << sign[k][0] * b * c / 8, sign[k][1] * a * c / 8, sign[k][2] * a * b / 8;
    }
    const Eigen::Matrix3d J = corners * dN;
    M += std::abs(J.determinant()) * density(N) * N * N.transpose();  // Gauss weights are 1
  }
  return M;
}

}  // namespace viscera
