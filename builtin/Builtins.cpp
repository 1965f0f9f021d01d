// Registers every built-in component and the SOFA elements accepted without effect.
#include "builtin/Builtins.h"

namespace viscera {

void registerMechanicalObject(Registry&);
void registerMasses(Registry&);
void registerConstraints(Registry&);
void registerRestShapeSprings(Registry&);
void registerSprings(Registry&);
void registerRegionEngines(Registry&);
void registerMovementConstraints(Registry&);
void registerGeometryEngines(Registry&);
void registerTopologies(Registry&);
void registerTetrahedronFEM(Registry&);
void registerHexahedronFEM(Registry&);
void registerHyperelasticFEM(Registry&);
void registerVTKExporter(Registry&);
void registerExodusExporter(Registry&);
void registerSurfaceExporters(Registry&);
void registerWriteState(Registry&);
void registerLinearSolvers(Registry&);
void registerEulerImplicit(Registry&);
void registerExplicitSolvers(Registry&);
void registerStaticSolver(Registry&);
void registerBDFOdeSolver(Registry&);
void registerNewmarkImplicitSolver(Registry&);
void registerDrivers(Registry&);
void registerCollision(Registry&);
void registerConstraintContact(Registry&);
void registerMappings(Registry&);
void registerRigidMapping(Registry&);
void registerRigidForces(Registry&);
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
  registerMovementConstraints(r);
  registerGeometryEngines(r);
  registerTopologies(r);
  registerTetrahedronFEM(r);
  registerHexahedronFEM(r);
  registerHyperelasticFEM(r);
  registerVTKExporter(r);
  registerExodusExporter(r);
  registerSurfaceExporters(r);
  registerWriteState(r);
  registerLinearSolvers(r);
  registerEulerImplicit(r);
  registerExplicitSolvers(r);
  registerStaticSolver(r);
  registerBDFOdeSolver(r);
  registerNewmarkImplicitSolver(r);
  registerDrivers(r);
  registerCollision(r);
  registerConstraintContact(r);
  registerMappings(r);
  registerRigidMapping(r);
  registerRigidForces(r);
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
                        "AttachBodyButtonSetting", "MouseButtonSetting", "ClipPlane", "OrderIndependentTransparencyManager",
                        "VisualBoundingBox", "TrailRenderer", "VisualVectorField", "CylinderVisualModel", "PointSplatModel",
                        "OglIntVariable", "PostProcessManager"})
    r.addIgnored(t, drawing);
  r.addIgnored("RequiredPlugin", "plugins are built in");
  {
    // SOFA's AddDataRepository: a folder where the scene's files are looked for first.
    ComponentSpec s;
    s.name = "AddDataRepository";
    s.category = "scene";
    s.doc = "Puts a folder first on the search path of the files the scene names (SOFA's data repository); a relative "
            "path is taken from the scene's folder. The scene's own folder is still looked in before it.";
    s.add(AttrSpec::string("path").req().help("the folder"));
    s.factory = [](BuildContext& c) {
      c.scene().addDataFolder(c.attrs().str("path"));
      return std::make_unique<Component>(c);
    };
    r.add(std::move(s));
  }
  {
    // SOFA's Gravity component: the scene's gravity, from the root node.
    ComponentSpec s;
    s.name = "Gravity";
    s.category = "scene";
    s.doc = "The scene's gravity (SOFA's Gravity component), replacing the root node's `gravity`. In the root node only: "
            "gravity is one for the whole scene here, as a sub-node's `gravity` attribute is.";
    s.add(AttrSpec::reals("gravity", 3).req().unit(Dimension::acceleration()).help("gravity vector"));
    s.factory = [](BuildContext& c) {
      if (c.node().parent())
        throw Error(c.attrs().get("gravity").loc, "Gravity.gravity: gravity is set for the whole scene, in the root node");
      const auto& g = c.attrs().reals("gravity");
      c.scene().setGravity(Eigen::Vector3d(g[0], g[1], g[2]));
      return std::make_unique<Component>(c);
    };
    r.add(std::move(s));
  }
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
