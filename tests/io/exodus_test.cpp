// Exodus II series (.exo): round trips through the writer and reader (Float64 bit-exact, Float32
// rounded), the file taking its name only when finished, ExodusExporter in a scene against the
// state it exports, and (where python3-vtk is installed) VTK's own Exodus reader.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/topology/GridSplit.h"
#include "io/mesh/Exodus.h"
#include "io/scene/SceneReader.h"
#include "tests/support/ErrorOf.h"
#include "tests/support/FileText.h"
#include "tests/support/TempDir.h"

namespace fs = std::filesystem;
using viscera::io::ExodusLayout;
using viscera::io::ExodusReader;
using viscera::io::ExodusWriter;
using viscera::test_support::errorOf;
using viscera::test_support::slurp;
using viscera::test_support::spit;
using viscera::test_support::TempDir;

namespace {

#define EXPECT_CONTAINS(haystack, needle) EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

// A 4 x 3 x 3 grid split into tetrahedra, with fields that vary by node, cell and frame.
ExodusLayout gridLayout(bool float32) {
  ExodusLayout l;
  l.rest = viscera::gridPoints({4, 3, 3}, Eigen::Vector3d(0, 0.001, 0), Eigen::Vector3d(0.3, 0.141, 0.1));
  l.tets = viscera::splitHexahedra(viscera::gridHexahedra({4, 3, 3}), 3, 2, true);
  l.nodeVectors = {"displacement", "velocity"};
  l.cellScalars = {"vonMises"};
  l.float32 = float32;
  return l;
}

Eigen::Matrix3Xd displacementAt(const ExodusLayout& l, int frame) {
  Eigen::Matrix3Xd d(3, l.rest.cols());
  for (Eigen::Index n = 0; n < d.cols(); ++n)
    for (int c = 0; c < 3; ++c) d(c, n) = 1e-3 * std::sin(0.3 * n + c + 0.7 * frame) * (frame + 1) / 3.0;
  return d;
}
Eigen::VectorXd stressAt(const ExodusLayout& l, int frame) {
  Eigen::VectorXd s(l.tets.cols());
  for (Eigen::Index e = 0; e < s.size(); ++e) s[e] = 1e3 * std::abs(std::cos(0.37 * e + frame)) + 1.0 / 3.0;
  return s;
}

void writeSeries(const std::string& path, const ExodusLayout& l, int frames) {
  ExodusWriter w(path, l);
  for (int f = 0; f < frames; ++f) {
    const Eigen::Matrix3Xd d = displacementAt(l, f);
    w.append(0.1 * f / 3.0, {d, Eigen::Matrix3Xd(-2.0 * d)}, {stressAt(l, f)});
  }
  w.finish();
}

// A cube of n^3 nodes clamped at its base and sagging under gravity, with `exporters` in its node.
std::string sagScene(int n, const std::string& exporters) {
  const std::string nodes = std::to_string(n) + " " + std::to_string(n) + " " + std::to_string(n);
  return R"(<Node name="root" dt="0.01" gravity="0 -9 0">
    <Node name="cube">
        <EulerImplicitSolver/>
        <CGLinearSolver iterations="25" tolerance="1e-9" threshold="1e-20"/>
        <RegularGridTopology name="grid" n=")" + nodes + R"(" min="0 0 0" max="1 1 1"/>
        <MechanicalObject name="dofs"/>
        <TetrahedronSetTopologyContainer name="tetra"/>
        <Hexa2TetraTopologicalMapping input="@grid" output="@tetra"/>
        <DiagonalMass massDensity="1"/>
        <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3" method="large"/>
        <BoxROI name="clamp" box="-1 -1 -1 2 2 0.1"/>
        <FixedConstraint indices="@clamp.indices"/>
        )" + exporters + R"(
    </Node>
</Node>
)";
}

bool noTemporaries(const TempDir& dir) {
  for (const auto& e : fs::directory_iterator(dir.path()))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) return false;
  return true;
}

}  // namespace

TEST(Exodus, Float64SeriesReadsBackBitExact) {
  const TempDir dir("viscera_exo");
  const ExodusLayout l = gridLayout(false);
  writeSeries(dir / "s.exo", l, 4);
  EXPECT_TRUE(noTemporaries(dir));
  const ExodusReader r(dir / "s.exo");
  EXPECT_TRUE(r.mesh().points == l.rest);
  EXPECT_TRUE(r.mesh().tets == l.tets);
  ASSERT_EQ(r.times().size(), 4u);
  for (int f = 0; f < 4; ++f) EXPECT_EQ(r.times()[f], 0.1 * f / 3.0);
  EXPECT_EQ(r.nodeVariables(), (std::vector<std::string>{"displacement_x", "displacement_y", "displacement_z", "velocity_x",
                                                         "velocity_y", "velocity_z"}));
  EXPECT_EQ(r.cellVariables(), std::vector<std::string>{"vonMises"});
  for (int f = 0; f < 4; ++f) {
    const Eigen::Matrix3Xd d = displacementAt(l, f);
    EXPECT_TRUE(r.positions(f) == Eigen::Matrix3Xd(l.rest + d)) << "frame " << f;
    EXPECT_TRUE(r.nodeVariable(f, "velocity_y") == Eigen::VectorXd(-2.0 * d.row(1).transpose()));
    EXPECT_TRUE(r.cellVariable(f, "vonMises") == stressAt(l, f));
  }
  EXPECT_CONTAINS(errorOf([&] { r.nodeVariable(0, "pressure"); }), "no node field 'pressure'");
  EXPECT_CONTAINS(errorOf([&] { r.positions(4); }), "no frame 4");
}

TEST(Exodus, Float32SeriesHoldsTheRoundedValuesAndIsSmaller) {
  const TempDir dir("viscera_exo");
  const ExodusLayout single = gridLayout(true), full = gridLayout(false);
  writeSeries(dir / "single.exo", single, 6);
  writeSeries(dir / "double.exo", full, 6);
  const ExodusReader r(dir / "single.exo");
  for (Eigen::Index i = 0; i < r.mesh().points.size(); ++i)
    ASSERT_EQ(r.mesh().points.data()[i], static_cast<double>(static_cast<float>(single.rest.data()[i]))) << "coordinate " << i;
  const Eigen::Matrix3Xd d = displacementAt(single, 5);
  const Eigen::VectorXd dx = r.nodeVariable(5, "displacement_x");
  for (Eigen::Index n = 0; n < d.cols(); ++n) ASSERT_EQ(dx[n], static_cast<double>(static_cast<float>(d(0, n)))) << "node " << n;
  EXPECT_LT(fs::file_size(dir / "single.exo"), fs::file_size(dir / "double.exo"));
}

TEST(Exodus, TrianglesAndBarePointsAreCellsToo) {
  const TempDir dir("viscera_exo");
  ExodusLayout l;
  l.rest = Eigen::Matrix3Xd::Random(3, 5);
  l.triangles.resize(3, 2);
  l.triangles << 0, 1, 1, 2, 3, 4;
  l.nodeVectors = {"displacement"};
  {
    ExodusWriter w(dir / "tri.exo", l);
    w.append(0.5, {Eigen::Matrix3Xd::Constant(3, 5, 0.25)}, {});
    w.finish();
  }
  const ExodusReader tri(dir / "tri.exo");
  EXPECT_TRUE(tri.mesh().triangles == l.triangles);
  EXPECT_EQ(tri.mesh().tets.cols(), 0);
  l.triangles.resize(3, 0);
  {
    ExodusWriter w(dir / "points.exo", l);
    w.append(0.5, {Eigen::Matrix3Xd::Zero(3, 5)}, {});
    w.finish();
  }
  const ExodusReader points(dir / "points.exo");
  EXPECT_EQ(points.mesh().points.cols(), 5);
  EXPECT_EQ(points.mesh().triangles.cols() + points.mesh().tets.cols(), 0);
}

TEST(Exodus, TheFileTakesItsNameOnlyWhenFinished) {
  const TempDir dir("viscera_exo");
  const ExodusLayout l = gridLayout(true);
  spit(dir.path() / "s.exo", "an earlier result");
  {
    ExodusWriter w(dir / "s.exo", l);
    w.append(0, {displacementAt(l, 0), displacementAt(l, 1)}, {stressAt(l, 0)});
    EXPECT_EQ(slurp(dir.path() / "s.exo"), "an earlier result");  // still there while the series grows
    EXPECT_FALSE(noTemporaries(dir));
  }  // destroyed unfinished: the temporary goes, the earlier file stays
  EXPECT_EQ(slurp(dir.path() / "s.exo"), "an earlier result");
  EXPECT_TRUE(noTemporaries(dir));

  ExodusWriter w(dir / "s.exo", l);
  EXPECT_CONTAINS(errorOf([&] { w.append(0, {displacementAt(l, 0)}, {stressAt(l, 0)}); }), "other fields than the series");
  EXPECT_CONTAINS(errorOf([&] { w.append(0, {displacementAt(l, 0), Eigen::Matrix3Xd::Zero(3, 2)}, {stressAt(l, 0)}); }),
                  "node field has the wrong size");
  w.append(0, {displacementAt(l, 0), displacementAt(l, 1)}, {stressAt(l, 0)});
  w.finish();
  EXPECT_EQ(ExodusReader(dir / "s.exo").times().size(), 1u);
  EXPECT_CONTAINS(errorOf([&] { w.append(1, {displacementAt(l, 0), displacementAt(l, 1)}, {stressAt(l, 0)}); }),
                  "already finished");

  // Outputs never follow a link; bad settings are refused before anything is written.
  fs::create_symlink(dir / "elsewhere.exo", dir.path() / "link.exo");
  EXPECT_CONTAINS(errorOf([&] { ExodusWriter(dir / "link.exo", l); }), "not a regular file");
  ExodusLayout bad = l;
  bad.compressionLevel = 0;
  EXPECT_CONTAINS(errorOf([&] { ExodusWriter(dir / "bad.exo", bad); }), "zlib level must be 1..9");
  bad = l;
  bad.tets(0, 0) = 99;
  EXPECT_CONTAINS(errorOf([&] { ExodusWriter(dir / "bad.exo", bad); }), "names node 99");
  EXPECT_FALSE(fs::exists(dir.path() / "bad.exo"));
  EXPECT_TRUE(noTemporaries(dir));
}

TEST(Exodus, ReaderRefusesWhatIsNotAnExodusSeries) {
  const TempDir dir("viscera_exo");
  spit(dir.path() / "text.exo", "not netCDF at all\n");
  EXPECT_CONTAINS(errorOf([&] { ExodusReader(dir / "text.exo"); }), "text.exo: cannot read the Exodus file");
  EXPECT_CONTAINS(errorOf([&] { ExodusReader(dir / "missing.exo"); }), "cannot open the Exodus file");
  EXPECT_CONTAINS(errorOf([&] { ExodusReader(dir.str()); }), "not a regular file");
}

// The exporter in a scene: every exported frame is the state of the step it names (Float64), the
// displacement always written, frames every N steps plus the start, and a second run replaces
// the first run's file.
TEST(Exodus, ExporterWritesTheStateOfEachExportedStep) {
  const TempDir dir("viscera_exo");
  spit(dir.path() / "scene.xml", sagScene(4, R"(<ExodusExporter filename="cube.exo" exportEveryNumberOfSteps="2" precision="float64"/>
        <ExodusExporter name="motion" fields="velocity"/>)"));
  auto scene = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
  scene->setOutputDirectory(dir / "out");
  const auto* dofs = scene->all<viscera::MechanicalObject>().front();
  for (int run = 0; run < 2; ++run) {
    viscera::Simulation sim(*scene);
    std::vector<Eigen::Matrix3Xd> states;
    sim.begin();
    states.push_back(dofs->x(sim.state()));
    for (int i = 0; i < 5 + run; ++i) {
      ASSERT_FALSE(sim.step());
      states.push_back(dofs->x(sim.state()));
    }
    sim.end();
    const ExodusReader r(dir / "out/cube.exo");
    const size_t frames = run == 0 ? 3 : 4;  // steps 0, 2, 4 (and 6)
    ASSERT_EQ(r.times().size(), frames) << "run " << run;
    for (size_t f = 0; f < frames; ++f) {
      EXPECT_NEAR(r.times()[f], 0.02 * f, 1e-15);
      EXPECT_TRUE(r.positions(static_cast<int>(f)).isApprox(states[2 * f], 1e-15)) << "frame " << f;
    }
    EXPECT_EQ(r.cellVariables(), std::vector<std::string>{"vonMises"});
    const ExodusReader m(dir / "out/motion.exo");
    EXPECT_EQ(m.times().size(), states.size());
    EXPECT_EQ(m.nodeVariables().front(), "displacement_x");  // written though not asked for: it carries the motion
    EXPECT_TRUE(m.cellVariables().empty());
    EXPECT_LT((m.positions(static_cast<int>(states.size()) - 1) - states.back()).cwiseAbs().maxCoeff(), 1e-6);
  }
}

// With SOFA's plasticity on, the cell field plasticStrain is each element's plastic strain norm,
// as the state holds it at the exported step (Float64: bit for bit); asked for without plasticity
// it is refused, naming the field.
TEST(Exodus, PlasticStrainIsACellField) {
  const TempDir dir("viscera_exo");
  std::string text = sagScene(3, R"(<ExodusExporter filename="plastic.exo" fields="vonMises plasticStrain" precision="float64"/>)");
  const std::string elastic = R"(method="large"/>)";
  text.replace(text.find(elastic), elastic.size(), R"(method="large" plasticMaxThreshold="1" plasticYieldThreshold="0" plasticCreep="0.2"/>)");
  spit(dir.path() / "scene.xml", text);
  auto scene = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
  scene->setOutputDirectory(dir / "out");
  viscera::Simulation sim(*scene);
  sim.begin();
  for (int i = 0; i < 4; ++i) ASSERT_FALSE(sim.step());
  const auto* fem = scene->all<viscera::TetrahedronFEMForceField>().front();
  const Eigen::VectorXd expected = fem->plasticStrains(sim.state()).colwise().norm().transpose();
  sim.end();
  const ExodusReader r(dir / "out/plastic.exo");
  EXPECT_EQ(r.cellVariables(), (std::vector<std::string>{"vonMises", "plasticStrain"}));
  const Eigen::VectorXd written = r.cellVariable(static_cast<int>(r.times().size()) - 1, "plasticStrain");
  EXPECT_TRUE(written == expected);
  EXPECT_GT(written.maxCoeff(), 0.0);
  spit(dir.path() / "elastic.xml", sagScene(3, R"(<ExodusExporter fields="plasticStrain"/>)"));
  EXPECT_CONTAINS(errorOf([&] {
                    auto s = viscera::buildScene(viscera::io::readScene(dir / "elastic.xml"));
                    viscera::Simulation b(*s);
                  }),
                  "plasticStrain needs a TetrahedronFEMForceField with plasticity");
}

// Exporters end one after another: one whose series cannot be put in place (its name is now a
// folder) reports that, and the others still finish theirs.
TEST(Exodus, OneExportersFailureDoesNotCostAnotherItsSeries) {
  const TempDir dir("viscera_exo");
  spit(dir.path() / "scene.xml", sagScene(3, R"(<ExodusExporter filename="a"/> <ExodusExporter filename="b"/>)"));
  auto scene = viscera::buildScene(viscera::io::readScene(dir / "scene.xml"));
  scene->setOutputDirectory(dir / "out");
  viscera::Simulation sim(*scene);
  sim.begin();
  for (int i = 0; i < 2; ++i) ASSERT_FALSE(sim.step());
  fs::create_directory(dir.path() / "out" / "a.exo");
  EXPECT_CONTAINS(errorOf([&] { sim.end(); }), "a.exo");
  EXPECT_EQ(ExodusReader(dir / "out/b.exo").times().size(), 3u);
  for (const auto& e : fs::directory_iterator(dir.path() / "out"))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

// A file whose frames go back in time is refused.
TEST(Exodus, FramesGoingBackInTimeAreRefused) {
  const TempDir dir("viscera_exo");
  const ExodusLayout l = gridLayout(false);
  {
    ExodusWriter w(dir / "s.exo", l);
    for (double t : {0.0, 0.2, 0.1}) w.append(t, {displacementAt(l, 0), displacementAt(l, 1)}, {stressAt(l, 0)});
    w.finish();
  }
  EXPECT_CONTAINS(errorOf([&] { ExodusReader(dir / "s.exo"); }), "frame 2's time");
  // Equal times are not out of order (Float32 times of a long run with a fine step round together).
  {
    ExodusWriter w(dir / "t.exo", l);
    for (double t : {0.0, 0.1, 0.1}) w.append(t, {displacementAt(l, 0), displacementAt(l, 1)}, {stressAt(l, 0)});
    w.finish();
  }
  EXPECT_EQ(ExodusReader(dir / "t.exo").times().size(), 3u);
}

// VTK's own Exodus reader (python3-vtk9) opens the series, finds the frames and fields, and moves
// the nodes by the displacement.
TEST(Exodus, VtkReaderOpensTheSeries) {
  if (std::system("/usr/bin/python3 -c 'import vtk' >/dev/null 2>&1") != 0) GTEST_SKIP() << "no python3 with VTK bindings";
  const TempDir dir("viscera_exo");
  const ExodusLayout l = gridLayout(true);
  writeSeries(dir / "s.exo", l, 3);
  spit(dir.path() / "check.py", R"(import sys, vtk
r = vtk.vtkExodusIIReader()
r.SetFileName(sys.argv[1])
r.UpdateInformation()
r.SetAllArrayStatus(vtk.vtkExodusIIReader.NODAL, 1)
r.SetAllArrayStatus(vtk.vtkExodusIIReader.ELEM_BLOCK, 1)
r.SetGenerateGlobalNodeIdArray(1)
r.SetTimeStep(2)
r.Update()
g = r.GetOutput().GetBlock(0).GetBlock(0)
ids = g.GetPointData().GetArray('PedigreeNodeId')
print(r.GetNumberOfTimeSteps(), g.GetNumberOfPoints(), g.GetNumberOfCells(), g.GetCellType(0))
vm = g.GetCellData().GetArray('vonMises')
print(vm.GetNumberOfTuples())
print(' '.join(repr(vm.GetValue(i)) for i in range(vm.GetNumberOfTuples())))
for i in range(g.GetNumberOfPoints()):
    p = g.GetPoint(i)
    print(int(ids.GetValue(i)) - 1, repr(p[0]), repr(p[1]), repr(p[2]))
)");
  const std::string cmd = "/usr/bin/python3 " + (dir / "check.py") + " " + (dir / "s.exo") + " > " + (dir / "out.txt") +
                          " 2> " + (dir / "err.txt");
  ASSERT_EQ(std::system(cmd.c_str()), 0) << slurp(dir.path() / "err.txt");
  std::istringstream out(slurp(dir.path() / "out.txt"));
  int steps = 0, points = 0, cells = 0, type = 0, stresses = 0;
  out >> steps >> points >> cells >> type >> stresses;
  EXPECT_EQ(steps, 3);
  EXPECT_EQ(points, l.rest.cols());
  EXPECT_EQ(cells, l.tets.cols());
  EXPECT_EQ(type, 10);  // VTK_TETRA
  ASSERT_EQ(stresses, l.tets.cols());
  const Eigen::VectorXd s = stressAt(l, 2);
  for (int e = 0; e < stresses; ++e) {
    double v = 0;
    out >> v;
    EXPECT_EQ(v, static_cast<double>(static_cast<float>(s[e]))) << "cell " << e;
  }
  const Eigen::Matrix3Xd d = displacementAt(l, 2);
  int seen = 0;
  for (int node; out >> node;) {
    ASSERT_GE(node, 0);
    ASSERT_LT(node, l.rest.cols());
    for (int c = 0; c < 3; ++c) {
      double x = 0;
      out >> x;
      // The reader adds the Float32 displacement to the Float32 coordinates.
      EXPECT_NEAR(x, static_cast<float>(l.rest(c, node)) + static_cast<float>(d(c, node)), 1e-6) << "node " << node;
    }
    ++seen;
  }
  EXPECT_EQ(seen, points);
}
