// Visual surfaces through the `viscera` command line and the shipped example scene: the
// components' listing, exit code 2 with the scene location for a missing surface file (nothing
// written), and the example's surface lying inside the phantom.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/mapping/VisualModel.h"
#include "io/scene/SceneReader.h"
#include "tests/apps/cli_helpers.h"

using namespace viscera_test;

namespace {

TEST(VisualCli, ComponentsListTheVisualModelAndMappings) {
  for (const char* name : {"OglModel", "VisualModel"}) {
    const RunResult r = runViscera({"components", name});
    ASSERT_EQ(r.rc, 0) << r;
    EXPECT_NE(r.out.find(" [visual]\n"), std::string::npos) << r;
  }
  const RunResult bary = runViscera({"components", "BarycentricMapping"});
  EXPECT_NE(bary.out.find("BarycentricMapping [mapping]"), std::string::npos) << bary;
  EXPECT_NE(bary.out.find("maxDistance (real, unit L"), std::string::npos) << bary;
  EXPECT_NE(bary.out.find("input (link) alias object1"), std::string::npos) << bary;
  const RunResult identity = runViscera({"components", "IdentityMapping"});
  EXPECT_NE(identity.out.find("IdentityMapping [mapping]"), std::string::npos) << identity;
  const RunResult ogl = runViscera({"components", "OglModel"});
  EXPECT_NE(ogl.out.find("OglModel (also VisualModel) [visual]"), std::string::npos) << ogl;
  EXPECT_NE(ogl.out.find("scale3d (real list, default \"1 1 1\"): scale factors of the vertices, applied first (SOFA's scale"), std::string::npos) << ogl;
  // No longer in the accepted-and-ignored list.
  const RunResult all = runViscera({"components"});
  const std::string ignored = all.out.substr(all.out.find("Accepted and ignored:")) + " ";
  EXPECT_EQ(ignored.find(" OglModel "), std::string::npos) << ignored;
  EXPECT_EQ(ignored.find(" VisualModel "), std::string::npos) << ignored;
}

TEST(VisualCli, MissingSurfaceFileExitsWithTwoAndWritesNothing) {
  TempDir dir;
  const std::string scene = dir / "scene.xml";
  std::ofstream(scene) << R"(<Node name="root" dt="0.01">
  <Node name="body">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="25" tolerance="1e-9" threshold="1e-20"/>
    <RegularGridTopology name="grid" n="3 3 3" min="0 0 0" max="1 1 1"/>
    <MechanicalObject name="dofs"/>
    <TetrahedronSetTopologyContainer name="tetra"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tetra"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3"/>
    <VTKExporter filename="body"/>
    <Node name="Visual">
      <OglModel name="skin" filename="skin.stl"/>
      <BarycentricMapping input="@.." output="@skin"/>
      <VTKExporter filename="skin"/>
    </Node>
  </Node>
</Node>
)";
  const RunResult r = runViscera({"run", scene, "--steps", "3", "--out", dir / "out"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("scene.xml:13:"), std::string::npos) << r;
  EXPECT_NE(r.err.find("OglModel.filename: surface file"), std::string::npos) << r;
  EXPECT_NE(r.err.find("skin.stl' does not exist"), std::string::npos) << r;
  EXPECT_TRUE(absentOrEmpty(dir / "out")) << r;
}

TEST(VisualCli, ExampleSceneSurfaceLiesInsideThePhantom) {
  auto scene = viscera::buildScene(viscera::io::readScene(sourcePath("scenes/gel_phantom_visual.xml")));
  scene->init();
  // The rounded block of the example: 2218 vertices, 4432 triangles, none outside the
  // tetrahedra (so no extrapolation note).
  const auto models = scene->all<viscera::VisualModel>();
  ASSERT_EQ(models.size(), 1u);
  EXPECT_EQ(models[0]->size(), 2218);
  EXPECT_EQ(models[0]->triangles.cols(), 4432);
  for (const auto& n : scene->notes()) EXPECT_EQ(n.find("lie outside"), std::string::npos) << n;
}

}  // namespace
