// Registers every built-in component and the SOFA elements accepted without effect.
#include "builtin/Builtins.h"

namespace viscera {

void registerMechanicalObject(Registry&);
void registerMasses(Registry&);
void registerConstraints(Registry&);
void registerRestShapeSprings(Registry&);
void registerSprings(Registry&);
void registerRegionEngines(Registry&);
void registerTopologies(Registry&);
void registerTetrahedronFEM(Registry&);
void registerHexahedronFEM(Registry&);
void registerVTKExporter(Registry&);
void registerLinearSolvers(Registry&);
void registerEulerImplicit(Registry&);
void registerExplicitSolvers(Registry&);
void registerStaticSolver(Registry&);
void registerDrivers(Registry&);
void registerCollision(Registry&);
void registerConstraintContact(Registry&);
void registerMappings(Registry&);
void registerRigidMapping(Registry&);
void registerObservation(Registry&);
void registerRobotDrivers(Registry&);
void registerForceDrivers(Registry&);
void registerLearnedComponents(Registry&);

void registerBuiltins(Registry& r) {
  registerMechanicalObject(r);
  registerMasses(r);
  registerConstraints(r);
  registerRestShapeSprings(r);
  registerSprings(r);
  registerRegionEngines(r);
  registerTopologies(r);
  registerTetrahedronFEM(r);
  registerHexahedronFEM(r);
  registerVTKExporter(r);
  registerLinearSolvers(r);
  registerEulerImplicit(r);
  registerExplicitSolvers(r);
  registerStaticSolver(r);
  registerDrivers(r);
  registerCollision(r);
  registerConstraintContact(r);
  registerMappings(r);
  registerRigidMapping(r);
  registerObservation(r);
  registerRobotDrivers(r);
  registerForceDrivers(r);
  registerLearnedComponents(r);

  const char* drawing = "drawing only";
  for (const char* t : {"VisualStyle", "OglSceneFrame", "LightManager", "DirectionalLight",
                        "SpotLight", "InteractiveCamera", "Camera", "BackgroundSetting", "DefaultVisualManagerLoop",
                        "VisualGrid", "LineAxis", "PositionalLight", "OglShader", "OglShadowShader", "OglTexture",
                        "OglShaderDefineMacro", "OglFloatVariable", "OglLabel", "OglViewport", "OglGrid",
                        "RecordedCamera", "ViewerSetting", "Visual3DText", "ConstraintAttachButtonSetting",
                        "AttachBodyButtonSetting", "MouseButtonSetting"})
    r.addIgnored(t, drawing);
  r.addIgnored("RequiredPlugin", "plugins are built in");
  r.addIgnored("DefaultAnimationLoop", "the step loop is built in");
  r.addIgnored("TetrahedronSetTopologyModifier", "topology changes are not needed");
  r.addIgnored("TetrahedronSetGeometryAlgorithms", "geometry helpers are built in");
  r.addIgnored("TriangleSetTopologyModifier", "topology changes are not needed");
  r.addIgnored("TriangleSetGeometryAlgorithms", "geometry helpers are built in");
  r.addIgnored("InfoComponent", "no effect");
  r.addIgnored("TaskSchedulerSettings", "threads are set by the run (--threads)");
  for (const char* t : {"EdgeSetTopologyModifier", "QuadSetTopologyModifier", "HexahedronSetTopologyModifier",
                        "PointSetTopologyModifier"})
    r.addIgnored(t, "topology changes are not needed");
  for (const char* t : {"ConstantSparsityPatternSystem", "PreconditionedMatrixFreeSystem", "MatrixLinearSystem",
                        "NaturalOrderingMethod", "AMDOrderingMethod",
                        "COLAMDOrderingMethod", "MetisOrderingMethod"})
    r.addIgnored(t, "the linear solver chooses its own matrix storage and ordering (round-off differs, not the physics)");
  for (const char* t : {"EdgeSetGeometryAlgorithms", "QuadSetGeometryAlgorithms", "HexahedronSetGeometryAlgorithms",
                        "PointSetGeometryAlgorithms"})
    r.addIgnored(t, "geometry helpers are built in");
}

const Registry& builtinRegistry() {
  static const Registry r = [] {
    Registry reg;
    registerBuiltins(reg);
    return reg;
  }();
  return r;
}

std::unique_ptr<Scene> buildScene(const SceneDesc& desc) { return Scene::build(desc, builtinRegistry()); }

}  // namespace viscera
