// Linear elastic trilinear hexahedra (SOFA's HexahedronFEMForceField and its element force fields on
// hexahedra); the class is internal to HexahedronFEMForceField.cpp.
#pragma once

#include <memory>

namespace viscera {

class BuildContext;
class Component;
class Registry;

void registerHexahedronFEM(Registry& r);
// The hexahedral element force field for SOFA's LinearSmallStrainFEMForceField (no rotation) and
// CorotationalFEMForceField (rotation from the centroid polar decomposition) on hexahedra.
std::unique_ptr<Component> makeHexahedronElementFEM(BuildContext& c);

}  // namespace viscera
