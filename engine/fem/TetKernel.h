// Per-element kernels of linear tetrahedra: rest data, the element frames of the corotational
// methods (and their exact derivatives), the linear elastic force and stresses. Fixed-size
// Eigen types only; no knowledge of scenes or assembly.
#pragma once

#include <Eigen/Core>

namespace viscera::fem {

using Mat34 = Eigen::Matrix<double, 3, 4>;  // one column per node
using Mat12 = Eigen::Matrix<double, 12, 12>;

enum class Method { Small, Large, Polar };

// The linear elastic (isotropic Hooke) law, the one place it is written: the kernels, the force
// field's matrix-free product and its assembly all call it.
struct Lame {
  double lambda = 0, mu = 0;
  static Lame fromYoungPoisson(double E, double nu) {
    return {E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))};
  }
  // Stress of a displacement gradient H (3 x 3): sigma = lambda tr(eps) I + 2 mu eps, eps = sym(H).
  Eigen::Matrix3d stress(const Eigen::Matrix3d& H) const {
    return lambda * H.trace() * Eigen::Matrix3d::Identity() + mu * (H + H.transpose());
  }
  // The law's coupling of element nodes i and j, whose rotated shape-function gradients are h_i,
  // h_j (with g_i . g_j = gij at rest): lambda h_i h_j^T + mu h_j h_i^T + mu gij I. The element
  // stiffness block (i, j) is -V times this.
  Eigen::Matrix3d coupling(const Eigen::Vector3d& hi, const Eigen::Vector3d& hj, double gij) const {
    Eigen::Matrix3d B = lambda * hi * hj.transpose() + mu * hj * hi.transpose();
    B.diagonal().array() += mu * gij;
    return B;
  }
};

// Rest data of one element, in its rest frame (world frame for `Small`).
struct ElementRest {
  Mat34 X;        // rest node positions in the element frame
  Mat34 G;        // shape-function gradients in that frame (column k: grad N_k)
  double volume;  // |rest volume|
  double sign;    // sign of the rest volume (orientation), +1 or -1
  Lame lame;
};

// The element frame: a rotation whose rows are the frame's axes (world -> element).
// Large (SOFA's "large"): x along p1 - p0, z = x cross (p2 - p0), y = z cross x.
Eigen::Matrix3d frameLarge(const Mat34& p);
// Polar (SOFA's "polar"): the orthogonal polar factor of the matrix whose rows are the edges
// p1 - p0, p2 - p0, p3 - p0.
Eigen::Matrix3d framePolar(const Mat34& p);
Eigen::Matrix3d frame(Method m, const Mat34& p);
// The orthogonal factor Q of A = Q S (S symmetric positive definite), by Higham's scaled
// Newton iteration.
Eigen::Matrix3d polarFactor(const Eigen::Matrix3d& A);
// Derivative of frame(m, p) with respect to coordinate `dir` of node `node`.
Eigen::Matrix3d frameDerivative(Method m, const Mat34& p, const Eigen::Matrix3d& R, int node, int dir);

// Rest data from rest positions (world) for a method. Throws std::domain_error if degenerate.
ElementRest restElement(Method m, const Mat34& Xworld, const Lame& lame);

// Positions of the nodes in the element frame: small Y = x, large Y = R (x - x0), polar Y = R x.
inline Mat34 localPositions(Method m, const Eigen::Matrix3d& R, const Mat34& x) {
  if (m == Method::Small) return x;
  if (m == Method::Large) return R * (x.colwise() - x.col(0));
  return R * x;
}

// Linear elastic nodal forces in the element frame for local displacements U: f = -V sigma G.
inline Mat34 elasticForce(const ElementRest& e, const Mat34& U) {
  return -e.volume * e.lame.stress(U * e.G.transpose()) * e.G;
}

// SOFA's plasticity of linear tetrahedra (TetrahedronFEMForceField plasticMaxThreshold,
// plasticYieldThreshold, plasticCreep): each element keeps a plastic strain P that the elastic law
// does not see. SOFA measures strains as its strain-displacement product gives them, six times the
// element's volume times the strain (engineering shears), so the thresholds are compared with
// 6 V |strain|: they are volumes, and depend on the element's size as in SOFA.
struct Plasticity {
  double yield = 1e-4, max = 0, creep = 0.9;
  bool on() const { return max > 0; }  // SOFA: plasticity acts only with a positive max threshold
};
using Voigt = Eigen::Matrix<double, 6, 1>;  // xx yy zz, engineering xy yz zx
// Updates P from the local displacements U (each force evaluation, as SOFA's: where the elastic
// strain exceeds the yield threshold, P gains creep times it; P is then capped at the max
// threshold) and returns the local nodal forces of the remaining elastic strain.
Mat34 plasticForce(const ElementRest& e, const Mat34& U, const Plasticity& law, Eigen::Ref<Voigt> P);

// Cauchy stress (linear) for local displacements U.
Eigen::Matrix3d stress(const ElementRest& e, const Mat34& U);
double vonMises(const Eigen::Matrix3d& sigma);

// World-frame element force for current positions x (3 x 4); also returns the frame R.
Mat34 elementForce(Method m, const ElementRest& e, const Mat34& x, Eigen::Matrix3d& R);
// SOFA's "svd" frame: the polar frame, except for an element whose volume ratio J = det F (F the
// deformation gradient) is below 1e-6, inverted or nearly flat, where the polar frame is
// undefined or a reflection: there the frame is the rotation of the SVD of F (the reflection
// moved to the smallest singular value) applied to the rest frame, which turns the element back.
Eigen::Matrix3d frameSvd(const ElementRest& e, const Mat34& x);
// elementForce with a given frame R (method Polar's local positions, Y = R x).
Mat34 elementForceInFrame(const ElementRest& e, const Mat34& x, const Eigen::Matrix3d& R);
// The 12 x 12 stiffness the solver uses (SOFA's: -R^T K0 R, no derivative of R).
Mat12 elementStiffness(Method m, const ElementRest& e, const Eigen::Matrix3d& R);
// The exact derivative of elementForce with respect to x (includes the derivative of R).
Mat12 elementTangent(Method m, const ElementRest& e, const Mat34& x);
// Strain energy 1/2 u^T K0 u of the rotated displacement.
double elementEnergy(Method m, const ElementRest& e, const Mat34& x);

}  // namespace viscera::fem
