// The `viscera` command line: check, components, run with --summary / --state-out / --time, option
// errors and a diverging run (exit codes 0 ok, 2 invalid input, 3 diverged).
#include <gtest/gtest.h>

#include <fstream>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "builtin/Builtins.h"
#include "cli_helpers.h"
#include "core/Registry.h"
#include "io/mesh/Mesh.h"

using namespace viscera_test;

namespace {

const std::string kBeam = sourcePath("scenes/beam.xml");  // 5 x 5 x 20 grid: 500 nodes, dt 0.01

// The number after "key": in a JSON text (NaN if absent).
double jsonNumber(const std::string& json, const std::string& key) {
  size_t p = json.find("\"" + key + "\":");
  if (p == std::string::npos) return std::nan("");
  p += key.size() + 3;
  const char* start = json.c_str() + p;
  char* end = nullptr;
  double d = std::strtod(start, &end);
  return end == start ? std::nan("") : d;
}

// The string after "key": in a JSON text (empty if absent).
std::string jsonString(const std::string& json, const std::string& key) {
  size_t p = json.find("\"" + key + "\": \"");
  if (p == std::string::npos) return "";
  p += key.size() + 5;
  return json.substr(p, json.find('"', p) - p);
}

struct Row {
  std::string object;
  int node;
  double x, y, z;
};

// Parses --state-out CSV; checks the header.
std::vector<Row> readState(const std::string& path) {
  auto ls = lines(slurp(path));
  EXPECT_FALSE(ls.empty());
  if (ls.empty()) return {};
  EXPECT_EQ(ls[0], "object,node,x,y,z");
  std::vector<Row> rows;
  for (size_t i = 1; i < ls.size(); ++i) {
    std::vector<std::string> f;
    std::string cur;
    for (char c : ls[i]) {
      if (c == ',') f.push_back(cur), cur.clear();
      else cur += c;
    }
    f.push_back(cur);
    EXPECT_EQ(f.size(), 5u) << "line " << i + 1 << ": " << ls[i];
    if (f.size() != 5) continue;
    rows.push_back({f[0], std::stoi(f[1]), std::stod(f[2]), std::stod(f[3]), std::stod(f[4])});
  }
  return rows;
}

TEST(Cli, CheckGoodSceneExitsZero) {
  RunResult r = runViscera({"check", kBeam});
  EXPECT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.out.find("ok"), std::string::npos) << r;
  EXPECT_NE(r.out.find("1 mechanical object"), std::string::npos) << r;
}

TEST(Cli, CheckWritesNothing) {
  // check initialises but does not run: no exporter output next to the scene.
  TempDir tmp;
  fs::copy_file(kBeam, tmp / "beam.xml");
  RunResult r = runViscera({"check", tmp / "beam.xml"});
  EXPECT_EQ(r.rc, 0) << r;
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(tmp.path())) files.push_back(e.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"beam.xml"});
}

// A scene with more notes than a terminal wants: the first 20 and a count, or every one with
// --all-notes (check and run alike).
TEST(Cli, NotesAreCutAt20UnlessAllAreAskedFor) {
  TempDir tmp;
  std::string scene = "<Node name=\"root\">\n";
  for (int i = 0; i < 25; ++i) scene += "  <VisualStyle/>\n";
  scene += "</Node>\n";
  std::ofstream(tmp / "notes.xml") << scene;
  auto lines = [](const std::string& text, const std::string& what) {
    int n = 0;
    for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
    return n;
  };
  RunResult cut = runViscera({"check", tmp / "notes.xml"});
  ASSERT_EQ(cut.rc, 0) << cut;
  EXPECT_EQ(lines(cut.err, "VisualStyle ignored"), 20) << cut;
  EXPECT_NE(cut.err.find("... and 5 more notes"), std::string::npos) << cut;
  for (const char* command : {"check", "run"}) {
    std::vector<std::string> args = {command, tmp / "notes.xml", "--all-notes"};
    if (std::string(command) == "run") args.insert(args.end(), {"--steps", "1", "--out", tmp / "out"});
    RunResult all = runViscera(args);
    ASSERT_EQ(all.rc, 0) << all;
    EXPECT_EQ(lines(all.err, "VisualStyle ignored"), 25) << all;
    EXPECT_EQ(all.err.find("more notes"), std::string::npos) << all;
  }
}

TEST(Cli, ComponentsListsEveryComponentAndAlias) {
  RunResult r = runViscera({"components"});
  ASSERT_EQ(r.rc, 0) << r;
  for (const char* n : {"TetrahedronFEMForceField", "FixedConstraint", "FixedProjectiveConstraint", "MechanicalObject",
                        "EulerImplicitSolver", "CGLinearSolver", "MeshGmshLoader", "VTKExporter", "BoxROI"})
    EXPECT_NE(r.out.find(n), std::string::npos) << n;
  // Every registered component, each alias, and the ignored SOFA elements.
  const viscera::Registry& reg = viscera::builtinRegistry();
  ASSERT_FALSE(reg.specs().empty());
  for (const auto& [name, spec] : reg.specs()) {
    EXPECT_NE(r.out.find("\n" + name + " "), std::string::npos) << "component " << name << " is not listed";
    for (const auto& a : spec.aliases) EXPECT_NE(r.out.find(" " + a), std::string::npos) << "alias " << a << " of " << name;
    for (const auto& a : spec.attrs) EXPECT_NE(r.out.find("- " + a.name + " ("), std::string::npos) << name << "." << a.name;
  }
  for (const auto& [name, why] : reg.ignored()) EXPECT_NE(r.out.find(" " + name), std::string::npos) << name;
  // The alias is shown next to its component.
  EXPECT_NE(r.out.find("FixedConstraint (also FixedProjectiveConstraint)"), std::string::npos) << r.out;
}

TEST(Cli, ComponentsOneByNameOrAlias) {
  RunResult r = runViscera({"components", "TetrahedronFEMForceField"});
  EXPECT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.out.find("poissonRatio"), std::string::npos) << r;
  EXPECT_NE(r.out.find("(-1, 0.5)"), std::string::npos) << r;

  RunResult a = runViscera({"components", "FixedProjectiveConstraint"});
  EXPECT_EQ(a.rc, 0) << a;
  EXPECT_EQ(a.out.rfind("FixedConstraint", 0), 0u) << a;

  RunResult node = runViscera({"components", "Node"});
  EXPECT_EQ(node.rc, 0) << node;
  EXPECT_NE(node.out.find("units"), std::string::npos) << node;

  RunResult ig = runViscera({"components", "RequiredPlugin"});
  EXPECT_EQ(ig.rc, 0) << ig;
  EXPECT_NE(ig.out.find("ignored"), std::string::npos) << ig;
}

TEST(Cli, ComponentsUnknownExitsTwo) {
  RunResult r = runViscera({"components", "NoSuch"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("NoSuch"), std::string::npos) << r;
}

TEST(Cli, RunWritesSummaryJson) {
  TempDir tmp;
  RunResult r = runViscera({"run", kBeam, "--out", tmp / "out", "--steps", "10", "--summary", tmp / "summary.json", "--quiet"});
  ASSERT_EQ(r.rc, 0) << r;
  const std::string j = slurp(tmp / "summary.json");
  EXPECT_EQ(jsonString(j, "status"), "ok") << j;
  EXPECT_EQ(jsonNumber(j, "steps"), 10) << j;
  EXPECT_NEAR(jsonNumber(j, "simulated_time"), 0.1, 1e-12) << j;
  EXPECT_NEAR(jsonNumber(j, "dt"), 0.01, 1e-15) << j;
  EXPECT_GE(jsonNumber(j, "wall_time_s"), 0.0) << j;
  EXPECT_GE(jsonNumber(j, "ms_per_step"), 0.0) << j;
  EXPECT_NEAR(jsonNumber(j, "ms_per_step"), 1000 * jsonNumber(j, "wall_time_s") / 10, 1e-6) << j;
  EXPECT_NE(j.find("\"objects\": ["), std::string::npos) << j;
  EXPECT_EQ(jsonString(j, "name"), "dofs") << j;
  EXPECT_EQ(jsonNumber(j, "nodes"), 500) << j;
  EXPECT_GT(jsonNumber(j, "max_displacement"), 0.0) << j;  // the beam sags under gravity
  // Well-formed enough: balanced braces and brackets, no NaN/inf.
  EXPECT_EQ(std::count(j.begin(), j.end(), '{'), std::count(j.begin(), j.end(), '}')) << j;
  EXPECT_EQ(std::count(j.begin(), j.end(), '['), std::count(j.begin(), j.end(), ']')) << j;
  EXPECT_EQ(j.find("nan"), std::string::npos) << j;
  EXPECT_EQ(j.find("inf"), std::string::npos) << j;
}

TEST(Cli, RunWritesStateCsv) {
  TempDir tmp;
  RunResult r0 = runViscera({"run", kBeam, "--out", tmp / "out0", "--steps", "0", "--state-out", tmp / "rest.csv", "--quiet"});
  ASSERT_EQ(r0.rc, 0) << r0;
  RunResult r = runViscera({"run", kBeam, "--out", tmp / "out", "--steps", "10", "--state-out", tmp / "state.csv", "--summary",
                         tmp / "summary.json", "--quiet"});
  ASSERT_EQ(r.rc, 0) << r;
  auto rest = readState(tmp / "rest.csv");
  auto state = readState(tmp / "state.csv");
  ASSERT_EQ(state.size(), 500u);  // one row per node
  ASSERT_EQ(rest.size(), 500u);
  double maxDisp = 0;
  for (size_t i = 0; i < state.size(); ++i) {
    EXPECT_EQ(state[i].object, "dofs");
    EXPECT_EQ(state[i].node, static_cast<int>(i));
    EXPECT_TRUE(std::isfinite(state[i].x) && std::isfinite(state[i].y) && std::isfinite(state[i].z));
    maxDisp = std::max(maxDisp, std::hypot(state[i].x - rest[i].x, state[i].y - rest[i].y, state[i].z - rest[i].z));
  }
  // With zero steps the state is the grid itself: node 0 at the min corner, x fastest.
  EXPECT_EQ(rest[0].x, -5);
  EXPECT_EQ(rest[0].y, -5);
  EXPECT_EQ(rest[0].z, 0);
  EXPECT_EQ(rest[1].x, -2.5);
  EXPECT_EQ(rest[499].z, 40);
  // The summary's largest displacement is that of the CSV (written with 17 digits).
  const double fromSummary = jsonNumber(slurp(tmp / "summary.json"), "max_displacement");
  EXPECT_NEAR(fromSummary, maxDisp, 1e-8 * std::max(1.0, maxDisp));
  EXPECT_GT(maxDisp, 0.0);
}

TEST(Cli, TimeOptionRunsThatManySteps) {
  TempDir tmp;
  RunResult r = runViscera({"run", kBeam, "--out", tmp / "out", "--time", "0.05", "--summary", tmp / "s.json", "--quiet"});
  ASSERT_EQ(r.rc, 0) << r;
  const std::string j = slurp(tmp / "s.json");
  EXPECT_EQ(jsonNumber(j, "steps"), 5) << j;
  EXPECT_NEAR(jsonNumber(j, "simulated_time"), 0.05, 1e-12) << j;
}

TEST(Cli, StepsAndTimeTogetherIsAnError) {
  TempDir tmp;
  RunResult r = runViscera({"run", kBeam, "--out", tmp / "out", "--steps", "5", "--time", "0.05"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_FALSE(r.err.empty()) << r;
  EXPECT_TRUE(absentOrEmpty(tmp.path() / "out"));
}

TEST(Cli, OptionErrorsExitTwo) {
  TempDir tmp;
  EXPECT_EQ(runViscera({}).rc, 2);                                                  // no subcommand
  EXPECT_EQ(runViscera({"frobnicate"}).rc, 2);                                      // unknown subcommand
  EXPECT_EQ(runViscera({"run"}).rc, 2);                                             // no scene
  EXPECT_EQ(runViscera({"run", kBeam, "--steps", "-3", "--out", tmp / "o"}).rc, 2);  // negative steps
  EXPECT_EQ(runViscera({"run", kBeam, "--steps", "many", "--out", tmp / "o"}).rc, 2);
  EXPECT_EQ(runViscera({"run", kBeam, "--threads", "0", "--out", tmp / "o"}).rc, 2);
  EXPECT_TRUE(absentOrEmpty(tmp.path() / "o"));
  // The constraint-order spread is for the regression list, not the examples check.
  EXPECT_EQ(runViscera({"sofa-suite", tmp.path().string(), "--examples", "--order-spread", "2"}).rc, 2);
  EXPECT_EQ(runViscera({"sofa-suite", tmp.path().string(), "--order-spread", "-1"}).rc, 2);
  EXPECT_EQ(runViscera({"--help"}).rc, 0);
}

// Runs a diverging fixture (dt = 0.01) and checks exit code 3, the message, the summary, the
// final state and the exported files; returns the step that failed.
int checkDivergingRun(const std::string& fixture) {
  TempDir tmp;
  RunResult r = runViscera({"run", badPath(fixture), "--out", tmp / "out", "--steps", "50", "--summary", tmp / "s.json",
                         "--state-out", tmp / "state.csv"});
  EXPECT_EQ(r.rc, 3) << r;
  if (r.rc != 3) return 0;
  // "diverged at step N (t = T)" with T = N dt (dt = 0.01 in the fixture).
  const size_t p = r.err.find("diverged at step ");
  EXPECT_NE(p, std::string::npos) << r;
  if (p == std::string::npos) return 0;
  const int step = std::atoi(r.err.c_str() + p + 17);
  const size_t tp = r.err.find("(t = ", p);
  EXPECT_NE(tp, std::string::npos) << r;
  if (tp == std::string::npos) return 0;
  const double t = std::atof(r.err.c_str() + tp + 5);
  EXPECT_GE(step, 1) << r;
  EXPECT_NEAR(t, 0.01 * step, 1e-12) << r;
  EXPECT_NE(r.err.find(badPath(fixture) + ": diverged"), std::string::npos) << r;
  // The summary records the failure; steps counts the good ones.
  const std::string j = slurp(tmp / "s.json");
  EXPECT_EQ(jsonString(j, "status"), "diverged") << j;
  EXPECT_NE(jsonString(j, "failure").find("diverged at step " + std::to_string(step)), std::string::npos) << j;
  EXPECT_EQ(jsonNumber(j, "steps"), step - 1) << j;
  // The final state is the last good one: finite.
  for (const auto& row : readState(tmp / "state.csv"))
    EXPECT_TRUE(std::isfinite(row.x) && std::isfinite(row.y) && std::isfinite(row.z)) << "node " << row.node;
  // Nothing from the failed step reaches the exporter: one file per good step (every step, from 0).
  int vtu = 0;
  for (const auto& e : fs::directory_iterator(tmp.path() / "out")) vtu += e.path().extension() == ".vtu";
  EXPECT_EQ(vtu, step) << "steps 0.." << step - 1 << " expected";
  return step;
}

TEST(Cli, DivergingRunExitsThreeAndNamesStepAndTime) {
  // A huge force on a soft beam: elements invert in the first step.
  EXPECT_GE(checkDivergingRun("diverging.xml"), 1);
}

TEST(Cli, DivergingAfterSeveralGoodSteps) {
  // A smaller force: a few good steps first, so step numbering and outputs are checked past step 1.
  EXPECT_GT(checkDivergingRun("diverging_later.xml"), 1);
}

// Exporting every other step, a run that diverges still exports its last good step, from the copy
// the exporter kept of it: the series ends where the run did.
TEST(Cli, DivergingExportsTheLastGoodStepBetweenExportSteps) {
  TempDir tmp;
  std::string xml = slurp(badPath("diverging_later.xml"));
  const std::string from = "<VTKExporter filename=\"beam\"/>";
  ASSERT_NE(xml.find(from), std::string::npos);
  xml.replace(xml.find(from), from.size(), "<VTKExporter filename=\"beam\" exportEveryNumberOfSteps=\"2\"/>");
  std::ofstream(tmp.path() / "scene.xml") << xml;
  const RunResult r = runViscera({"run", tmp / "scene.xml", "--out", tmp / "out", "--steps", "50"});
  ASSERT_EQ(r.rc, 3) << r;
  const int step = std::atoi(r.err.c_str() + r.err.find("diverged at step ") + 17);
  ASSERT_GT(step, 2) << r;
  ASSERT_EQ((step - 1) % 2, 1) << "the fixture's last good step is to fall between export steps";
  const auto frames = viscera::io::readPvd(tmp / "out/beam.pvd");
  ASSERT_FALSE(frames.empty());
  char last[32];
  std::snprintf(last, sizeof last, "beam_%06d.vtu", step - 1);
  EXPECT_EQ(fs::path(frames.back().path).filename().string(), last);
  EXPECT_NEAR(frames.back().time, 0.01 * (step - 1), 1e-12);
  EXPECT_TRUE(viscera::io::readVtu(frames.back().path).points.allFinite());
}

}  // namespace

TEST(Cli, SetChangesAnAttributeWithUnits) {
  TempDir tmp;
  const std::string coarse = sourcePath("scenes/gel_phantom_coarse.xml");
  RunResult soft = runViscera({"run", coarse, "--out", tmp / "a", "--steps", "800", "--summary", tmp / "soft.json", "--quiet"});
  ASSERT_EQ(soft.rc, 0) << soft;
  RunResult stiff = runViscera({"run", coarse, "--out", tmp / "b", "--steps", "800", "--summary", tmp / "stiff.json", "--quiet",
                                "--set", "phantom/fem.youngModulus=50 kPa", "--set", "phantom/ode.rayleighMass=0.2"});
  ASSERT_EQ(stiff.rc, 0) << stiff;
  // The same imposed instrument motion moves the ten times stiffer block differently.
  EXPECT_NE(jsonNumber(slurp(tmp / "soft.json"), "max_displacement"), jsonNumber(slurp(tmp / "stiff.json"), "max_displacement"));
  RunResult check = runViscera({"check", coarse, "--set", "phantom/fem.youngModulus=3.2 kPa"});
  EXPECT_EQ(check.rc, 0) << check;
}

TEST(Cli, SetErrorsExitTwoNamingTheAddressAndCandidates) {
  TempDir tmp;
  const std::string coarse = sourcePath("scenes/gel_phantom_coarse.xml");
  struct Case {
    std::string set, expect1, expect2;
  };
  for (const Case& c : {Case{"dofs.rayleighMass=1", "--set dofs.rayleighMass", "unknown attribute"},
                        Case{"phantom/fem.youngModulus=3 kPaa", "--set phantom/fem.youngModulus", "kPaa"},
                        Case{"phantom/fem.youngModulous=3 kPa", "--set phantom/fem.youngModulous", "youngModulus"},
                        Case{"UniformMass.totalMass=1", "'UniformMass' is ambiguous", "/instrument/UniformMass (UniformMass)"},
                        Case{"phantom/nope.x=1", "no element 'phantom/nope'", "candidates"},
                        Case{"phantom/fem.youngModulus", "ADDRESS=VALUE", ""}}) {
    for (const char* cmd : {"run", "check"}) {
      std::vector<std::string> args = {cmd, coarse, "--set", c.set};
      if (std::string(cmd) == "run") args.insert(args.end(), {"--out", tmp / "out", "--steps", "2", "--summary", tmp / "s.json"});
      RunResult r = runViscera(args);
      EXPECT_EQ(r.rc, 2) << c.set << "\n" << r;
      EXPECT_NE(r.err.find(c.expect1), std::string::npos) << r;
      EXPECT_NE(r.err.find(c.expect2), std::string::npos) << r;
      EXPECT_FALSE(fs::exists(tmp / "s.json"));
    }
  }
}

TEST(Cli, SaveStateAndContinueFromIt) {
  TempDir tmp;
  const std::string coarse = sourcePath("scenes/gel_phantom_coarse.xml");
  RunResult whole = runViscera({"run", coarse, "--out", tmp / "w", "--steps", "80", "--state-out", tmp / "whole.csv", "--quiet"});
  ASSERT_EQ(whole.rc, 0) << whole;
  RunResult first = runViscera({"run", coarse, "--out", tmp / "f", "--steps", "50", "--save-state", tmp / "s50.state", "--quiet"});
  ASSERT_EQ(first.rc, 0) << first;
  RunResult rest = runViscera({"run", coarse, "--out", tmp / "r", "--steps", "30", "--from-state", tmp / "s50.state",
                               "--state-out", tmp / "resumed.csv", "--quiet"});
  ASSERT_EQ(rest.rc, 0) << rest;
  EXPECT_EQ(slurp(tmp / "whole.csv"), slurp(tmp / "resumed.csv"));
  // A state of another scene is refused.
  RunResult other = runViscera({"run", kBeam, "--out", tmp / "o", "--steps", "1", "--from-state", tmp / "s50.state"});
  EXPECT_EQ(other.rc, 2) << other;
  EXPECT_NE(other.err.find("s50.state"), std::string::npos) << other;
}

TEST(Cli, RunOutputsNeverOverwriteItsInputs) {
  TempDir tmp;
  // Copies, so that a failure of the check cannot touch the shipped files.
  fs::copy_file(sourcePath("scenes/gel_phantom_coarse.xml"), tmp / "scene.xml");
  fs::copy_file(sourcePath("scenes/palpation_80s.csv"), tmp / "palpation_80s.csv");
  const std::string scene = slurp(tmp / "scene.xml"), trajectory = slurp(tmp / "palpation_80s.csv");
  struct Case {
    const char* option;
    std::string path;
  };
  for (const Case& c : {Case{"--summary", tmp / "scene.xml"}, Case{"--wrench", tmp / "palpation_80s.csv"},
                        Case{"--state-out", tmp.str() + "/./scene.xml"}, Case{"--save-state", tmp / "palpation_80s.csv"}}) {
    RunResult r = runViscera({"run", tmp / "scene.xml", "--out", tmp / "out", "--steps", "3", c.option, c.path});
    EXPECT_EQ(r.rc, 2) << c.option << "\n" << r;
    EXPECT_NE(r.err.find("is an input of the command"), std::string::npos) << r;
    EXPECT_EQ(slurp(tmp / "scene.xml"), scene);
    EXPECT_EQ(slurp(tmp / "palpation_80s.csv"), trajectory);
  }
  // A missing output folder is found before the run, not after it.
  RunResult r = runViscera({"run", tmp / "scene.xml", "--out", tmp / "out", "--steps", "100000", "--wrench", tmp / "no/w.csv"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r;
}

// SIGINT and SIGTERM stop a run at a step boundary: the summary says "interrupted", the wrench
// table and the VTK series hold the steps run (the .pvd lists exactly the frames on disk), and the
// exit code is the shell's for the signal.
TEST(Cli, InterruptedRunsWriteTheirOutputsAndExitWithTheSignalsCode) {
  for (const auto& [name, code] : {std::pair{"INT", 130}, std::pair{"TERM", 143}}) {
    TempDir tmp;
    std::string cmd = shellQuote(VISCERA_BINARY) + " run " + shellQuote(sourcePath("scenes/gel_phantom_coarse.xml")) +
                      " --time 80 --quiet --out " + shellQuote(tmp / "out") + " --summary " + shellQuote(tmp / "s.json") +
                      " --wrench " + shellQuote(tmp / "w.csv");
    const std::string script = "(" + cmd + " 2>" + shellQuote(tmp / "err") + " & p=$!; sleep 1.5; kill -" + name +
                               " $p; wait $p; echo $? > " + shellQuote(tmp / "rc") + ")";
    ASSERT_EQ(std::system(script.c_str()), 0);
    EXPECT_EQ(std::stoi(slurp(tmp / "rc")), code) << name << ": " << slurp(tmp / "err");
    const std::string summary = slurp(tmp / "s.json");
    EXPECT_NE(summary.find("\"status\": \"interrupted\""), std::string::npos) << summary;
    EXPECT_NE(summary.find(std::string("SIG") + name), std::string::npos) << summary;
    EXPECT_GT(lines(slurp(tmp / "w.csv")).size(), 2u);
    const auto frames = viscera::io::readPvd(tmp / "out/gel_phantom_coarse.pvd");
    EXPECT_GT(frames.size(), 1u);
    for (const auto& f : frames) EXPECT_TRUE(fs::exists(f.path)) << f.path;
    size_t onDisk = 0;
    for (const auto& e : fs::directory_iterator(tmp.path() / "out")) onDisk += e.path().extension() == ".vtu";
    EXPECT_EQ(onDisk, frames.size());
  }
}

// kill -9 gives a run no chance to write anything more: the wrench rows streamed to WRENCH.partial
// are whole rows, the .pvd lists only complete frames, and the folder is free for the next run.
TEST(Cli, AKilledRunLeavesItsStreamedWrenchAndCompleteFrames) {
  TempDir tmp;
  const std::string cmd = shellQuote(VISCERA_BINARY) + " run " + shellQuote(sourcePath("scenes/gel_phantom_coarse.xml")) +
                          " --time 80 --quiet --out " + shellQuote(tmp / "out") + " --wrench " + shellQuote(tmp / "w.csv");
  // Killed once a dozen rows are out (waiting at most a minute), so that there is something to check.
  const std::string partial = shellQuote(tmp / "w.csv.partial");
  const std::string script = "(" + cmd + " 2>/dev/null & p=$!; i=0; while [ $i -lt 1200 ] && [ \"$(cat " + partial +
                             " 2>/dev/null | wc -l)\" -lt 12 ]; do sleep 0.05; i=$((i+1)); done; kill -KILL $p; wait $p; true)";
  ASSERT_EQ(std::system(script.c_str()), 0);
  EXPECT_FALSE(fs::exists(tmp.path() / "w.csv"));
  const auto rows = lines(slurp(tmp / "w.csv.partial"));
  ASSERT_GT(rows.size(), 10u);
  EXPECT_EQ(rows.front(), "t,fx,fy,fz,tx,ty,tz,contacts");
  for (const auto& row : rows) EXPECT_EQ(std::count(row.begin(), row.end(), ','), 7) << row;
  for (const auto& f : viscera::io::readPvd(tmp / "out/gel_phantom_coarse.pvd")) {
    EXPECT_TRUE(fs::exists(f.path)) << f.path;
    EXPECT_NE(slurp(f.path).find("</VTKFile>"), std::string::npos) << f.path;
  }
  const RunResult next = runViscera({"run", sourcePath("scenes/gel_phantom_coarse.xml"), "--steps", "20", "--quiet", "--out",
                                     tmp / "out", "--wrench", tmp / "w.csv"});
  EXPECT_EQ(next.rc, 0) << next;
  EXPECT_EQ(lines(slurp(tmp / "w.csv")).size(), 21u);
  EXPECT_FALSE(fs::exists(tmp.path() / "w.csv.partial"));
}

// Two runs into one --out: the second is refused, naming the process that holds the folder, and
// leaves the first's frames alone; once the first has ended, the folder is free again.
TEST(Cli, ASecondRunIntoTheSameOutputFolderIsRefused) {
  TempDir tmp;
  const std::string first = shellQuote(VISCERA_BINARY) + " run " + shellQuote(sourcePath("scenes/gel_phantom_coarse.xml")) +
                            " --time 80 --quiet --out " + shellQuote(tmp / "out");
  // The second starts once the first holds the folder (its lock file is there) and is given
  // time to finish before the first is stopped.
  const std::string second = shellQuote(VISCERA_BINARY) + " run " + shellQuote(sourcePath("scenes/beam.xml")) +
                             " --steps 2 --quiet --out " + shellQuote(tmp / "out");
  const std::string script = "(" + first + " 2>/dev/null & p=$!; while [ ! -e " + shellQuote(tmp / "out/.viscera.lock") +
                             " ]; do sleep 0.05; done; " + second + " 2>" + shellQuote(tmp / "err") + "; echo $? > " +
                             shellQuote(tmp / "rc") + "; kill -INT $p; wait $p; echo $p > " + shellQuote(tmp / "pid") + ")";
  ASSERT_EQ(std::system(script.c_str()), 0);
  EXPECT_EQ(std::stoi(slurp(tmp / "rc")), 2) << slurp(tmp / "err");
  const std::string err = slurp(tmp / "err");
  EXPECT_NE(err.find("the output folder is in use by another run (process " + lines(slurp(tmp / "pid")).front()), std::string::npos)
      << err;
  EXPECT_NE(err.find("gel_phantom_coarse.xml"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(tmp.path() / "out/beam.pvd"));
  EXPECT_FALSE(fs::exists(tmp.path() / "out/.viscera.lock"));
  const RunResult after = runViscera({"run", sourcePath("scenes/beam.xml"), "--steps", "2", "--quiet", "--out", tmp / "out"});
  EXPECT_EQ(after.rc, 0) << after;
}

// Special files as inputs are refused at once (/dev/zero would never end, a FIFO would block), and
// an exporter may not write outside --out.
TEST(Cli, SpecialFilesAndEscapingOutputsAreRefused) {
  TempDir tmp;
  const std::string scene = slurp(sourcePath("tests/data/study/block.xml"));
  auto withReplaced = [&](const std::string& from, const std::string& to, const std::string& name) {
    std::string s = scene;
    s.replace(s.find(from), from.size(), to);
    std::ofstream(tmp.path() / name) << s;
    return tmp / name;
  };
  fs::copy_file(sourcePath("tests/data/study/poke.csv"), tmp.path() / "poke.csv");
  const RunResult zero = runViscera({"check", withReplaced("poke.csv", "/dev/zero", "zero.xml")});
  EXPECT_EQ(zero.rc, 2) << zero;
  EXPECT_NE(zero.err.find("/dev/zero: cannot open trajectory: it is not a regular file"), std::string::npos) << zero;

  ASSERT_EQ(std::system(("mkfifo " + shellQuote(tmp / "fifo.csv")).c_str()), 0);
  const RunResult fifo = runViscera({"check", withReplaced("poke.csv", "fifo.csv", "fifo.xml")});
  EXPECT_EQ(fifo.rc, 2) << fifo;
  EXPECT_NE(fifo.err.find("not a regular file"), std::string::npos) << fifo;

  for (const std::string name : {"../escape", "/tmp/viscera_escape"}) {
    const RunResult r = runViscera({"run", withReplaced("filename=\"block\"", "filename=\"" + name + "\"", "esc.xml"), "--steps",
                                    "2", "--out", tmp / "out"});
    EXPECT_EQ(r.rc, 2) << r;
    EXPECT_NE(r.err.find("outside the output folder"), std::string::npos) << r;
  }
  EXPECT_FALSE(fs::exists(tmp.path() / "escape.pvd"));
  EXPECT_FALSE(fs::exists("/tmp/viscera_escape.pvd"));
}

// Grid node counts are checked in 64 bits against a documented limit before anything is allocated.
TEST(Cli, HugeGridsAreRefusedBeforeAllocating) {
  TempDir tmp;
  fs::copy_file(sourcePath("tests/data/study/poke.csv"), tmp.path() / "poke.csv");
  for (const std::string n : {"65536 65536 1", "1 1 100000000", "2147483647 2147483647 2147483647"}) {
    std::string s = slurp(sourcePath("tests/data/study/block.xml"));
    s.replace(s.find("n=\"5 3 3\""), 9, "n=\"" + n + "\"");
    std::ofstream(tmp.path() / "big.xml") << s;
    const RunResult r = runViscera({"check", tmp / "big.xml"});
    EXPECT_EQ(r.rc, 2) << n << "\n" << r;
    EXPECT_NE(r.err.find("RegularGridTopology.n"), std::string::npos) << r;
    EXPECT_NE(r.err.find("at most 10000000 nodes"), std::string::npos) << r;
  }
}

// A sphere centre exactly on a surface vertex, edge or face of the coarse phantom (its corner, the
// middle of a top edge's first segment, a point of the top face) has a defined contact normal: the
// run goes on instead of diverging with non-finite forces.
TEST(Cli, ASphereCentreOnTheSurfaceHasADefinedNormal) {
  TempDir tmp;
  std::string scene = slurp(sourcePath("scenes/gel_phantom_coarse.xml"));
  const std::string trajectory = "filename=\"palpation_80s.csv\"";
  scene.replace(scene.find(trajectory), trajectory.size(), "filename=\"still.csv\"");
  const auto exporter = scene.find("<VTKExporter");
  scene.erase(exporter, scene.find("/>", exporter) + 2 - exporter);
  std::ofstream(tmp.path() / "phantom.xml") << scene;
  for (const std::string at : {"0,0,0", "2.8625,0,35.8", "30,19.65,35.8"}) {
    std::ofstream(tmp.path() / "still.csv") << "t,x,y,z,qx,qy,qz,qw\n0," << at << ",0,0,0,1\n";
    const RunResult r = runViscera({"run", tmp / "phantom.xml", "--steps", "30", "--quiet"});
    EXPECT_EQ(r.rc, 0) << at << "\n" << r;
  }
}

// Ten thousand ignored elements give twenty notes and a count, not 600 KB of notes.
TEST(Cli, RepeatedNotesAreCapped) {
  TempDir tmp;
  fs::copy_file(sourcePath("tests/data/study/poke.csv"), tmp.path() / "poke.csv");
  std::string s = slurp(sourcePath("tests/data/study/block.xml"));
  std::string many;
  for (int i = 0; i < 10000; ++i) many += "<BruteForceBroadPhase/>";
  s.replace(s.find("<FreeMotionAnimationLoop/>"), 26, "<FreeMotionAnimationLoop/>" + many);
  std::ofstream(tmp.path() / "many.xml") << s;
  const RunResult r = runViscera({"check", tmp / "many.xml"});
  EXPECT_EQ(r.rc, 0) << r;
  EXPECT_NE(r.err.find("... and 9980 more notes"), std::string::npos) << r.err.substr(0, 2000);
  EXPECT_LT(r.err.size(), 5000u);
}

// A 100 KB attribute value and raw binary bytes are not echoed as they are: the message cuts the
// one and escapes the other.
TEST(Cli, MessagesCutLongValuesAndEscapeBinaryBytes) {
  TempDir tmp;
  std::string xml = slurp(sourcePath("scenes/beam.xml"));
  const size_t at = xml.find("youngModulus=\"");
  ASSERT_NE(at, std::string::npos);
  const size_t end = xml.find('"', at + 14);
  std::string binary = xml;
  xml.replace(at + 14, end - at - 14, std::string(100000, 'x'));
  binary.replace(at + 14, end - at - 14, "\x01\x02\xFF abc");
  std::ofstream(tmp.path() / "long.xml") << xml;
  std::ofstream(tmp.path() / "binary.xml") << binary;
  const RunResult longValue = runViscera({"check", tmp / "long.xml"});
  EXPECT_EQ(longValue.rc, 2) << longValue;
  EXPECT_LT(longValue.err.size(), 1000u);
  EXPECT_NE(longValue.err.find("youngModulus"), std::string::npos) << longValue;
  EXPECT_NE(longValue.err.find("characters left out"), std::string::npos) << longValue;
  const RunResult bytes = runViscera({"check", tmp / "binary.xml"});
  EXPECT_EQ(bytes.rc, 2) << bytes;
  EXPECT_NE(bytes.err.find("\\x01\\x02\\xFF abc"), std::string::npos) << bytes;
  EXPECT_EQ(bytes.err.find('\x01'), std::string::npos);
}

// An output that is a symbolic link is refused before the run (the link's target is untouched); a
// device is written through, never replaced by a file.
TEST(Cli, OutputsNeverFollowLinksNorReplaceDevices) {
  TempDir tmp;
  std::ofstream(tmp.path() / "target.json") << "mine";
  fs::create_symlink(tmp.path() / "target.json", tmp.path() / "link.json");
  const RunResult link = runViscera({"run", sourcePath("scenes/beam.xml"), "--steps", "2", "--out", tmp / "out", "--summary",
                                     tmp / "link.json"});
  EXPECT_EQ(link.rc, 2) << link;
  EXPECT_NE(link.err.find("symbolic link"), std::string::npos) << link;
  EXPECT_EQ(slurp(tmp.path() / "target.json"), "mine");
  EXPECT_FALSE(fs::exists(tmp.path() / "out"));
  const RunResult null = runViscera({"run", sourcePath("scenes/beam.xml"), "--steps", "2", "--out", tmp / "out2", "--summary", "/dev/null"});
  EXPECT_EQ(null.rc, 0) << null;
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
}

// Amounts of work derived from options are bounded before the work starts.
TEST(Cli, WorkFromOptionsIsBoundedBeforeItStarts) {
  TempDir tmp;
  std::ofstream(tmp.path() / "span.csv") << "t,q1,q2,q3,q4,q5,q6\n0,0,0,0.1,0,0,0\n1e9,0,0,0.1,0,0,0\n";
  struct Case {
    std::vector<std::string> args;
    const char* message;
  };
  const std::vector<Case> cases = {
      {{"velocity", "compare", "--out", tmp / "v", "--step", "1e-12"}, "at most 1e8"},
      {{"espm", "synth", "--joints", tmp / "span.csv", "--out", tmp / "cap.bin"}, "span.csv: the log spans 1e+09 s"},
      {{"distance", "--factor", "2147483647", "--cloud", tmp / "c.pcd", "--mesh", tmp / "m.msh"}, "not in range 1 to 100"},
      {{"espm", "synth", "--joints", sourcePath("scenes/psm_palpation_joints.csv"), "--out", tmp / "cap.bin", "--line-rate", "1e15"},
       "at most 1e10"},
  };
  for (const auto& c : cases) {
    const RunResult r = runViscera(c.args);
    EXPECT_EQ(r.rc, 2) << c.message << "\n" << r;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r;
  }
  EXPECT_FALSE(fs::exists(tmp.path() / "v"));
  EXPECT_FALSE(fs::exists(tmp.path() / "cap.bin"));
}
