// Isotropic hyperelastic laws as SOFA's TetrahedronHyperelasticityFEMForceField defines them, in
// terms of the right Cauchy-Green tensor C = F^T F and the volume ratio J: the strain energy W per
// unit rest volume, the second Piola-Kirchhoff stress S = 2 dW/dC and its directional derivative
// dS = dS/dC : H (the material part of the consistent tangent).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

namespace viscera::fem {

class HyperelasticMaterial {
 public:
  virtual ~HyperelasticMaterial() = default;
  virtual double energy(const Eigen::Matrix3d& C, double J) const = 0;
  virtual Eigen::Matrix3d stress(const Eigen::Matrix3d& C, double J) const = 0;
  // dS/dC : H for a symmetric H.
  virtual Eigen::Matrix3d stressDerivative(const Eigen::Matrix3d& C, double J, const Eigen::Matrix3d& H) const = 0;
  // Whether the law is defined for J <= 0 (no ln J or fractional power of J): an inverted element
  // is then a state like any other, not a failure.
  virtual bool definedWhenInverted() const { return false; }
};

// SOFA's names, in its order, and the parameters each takes (ParameterSet).
struct MaterialInfo {
  const char* name;
  const char* parameters;  // their meaning, in order
  int count;
};
const std::vector<MaterialInfo>& hyperelasticMaterials();

// The law `name` with `parameters` (their number checked by the caller against MaterialInfo).
std::unique_ptr<HyperelasticMaterial> makeHyperelasticMaterial(const std::string& name, const std::vector<double>& parameters);

}  // namespace viscera::fem
