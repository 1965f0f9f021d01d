#include "apps/viscera/LearnCommand.h"

#include <CLI/CLI.hpp>

#include <iostream>
#include <memory>
#include <sstream>

#include "core/Error.h"
#include "core/Text.h"
#include "engine/Run.h"
#include "learning/Record.h"

namespace viscera {

namespace {

// "MIN:MAX" (or one number for both) into the two bounds; errors name the option.
void parseRange(const std::string& text, const std::string& option, double& lo, double& hi) {
  const auto colon = text.find(':');
  const std::string a = text.substr(0, colon), b = colon == std::string::npos ? a : text.substr(colon + 1);
  if (!parseNumber(a, lo) || !parseNumber(b, hi))
    throw Error(option + ": expected MIN:MAX (two numbers in the scene's units), got " + viscera::quoted(text));
}

struct LearnRecordCli {
  learning::RecordOptions options;
  std::string depth = "2:6", speed = "5:15", faces = "top,x-,x+,y-,y+";
  bool quiet = false;
};

int recordRollouts(LearnRecordCli& c) {
  learning::RecordOptions& o = c.options;
  parseRange(c.depth, "--depth", o.depthMin, o.depthMax);
  parseRange(c.speed, "--speed", o.speedMin, o.speedMax);
  o.faces.clear();
  std::istringstream in(c.faces);
  for (std::string f; std::getline(in, f, ',');) {
    try {
      o.faces.push_back(motion::parseFace(f));
    } catch (const std::invalid_argument& e) {
      throw Error(std::string("--faces: ") + e.what());
    }
  }
  const learning::RecordResult r =
      learning::record(o, c.quiet ? std::function<void(const std::string&)>() : [](const std::string& line) { std::cerr << line << "\n"; });
  if (!c.quiet)
    std::cerr << "wrote " << r.rollouts << " rollouts (" << r.frames << " frames, " << formatNumber(r.simulatedTime)
              << " s simulated) to " << o.out << " in " << formatDuration(r.wallSeconds) << "\n";
  if (r.diverged > 0) {
    std::cerr << o.out << ": " << r.diverged << " rollout" << (r.diverged == 1 ? "" : "s")
              << " diverged (kept up to the divergence; see rollouts.json)\n";
    return kExitDiverged;
  }
  return kExitOk;
}

}  // namespace

void addLearnCommand(CLI::App& app, std::function<int()>& action) {
  auto* cmd = app.add_subcommand("learn", "learned components: record rollouts for a learned stepper");
  cmd->require_subcommand(1);
  auto c = std::make_shared<LearnRecordCli>();
  auto* rec = cmd->add_subcommand("record", "run randomised palpations of a scene in parallel and write their rollouts");
  rec->footer("The scene has one deformable body with tetrahedra and one instrument: a SphereCollisionModel on a rigid body\n"
              "driven by a TrajectoryDriver. Each rollout replaces that trajectory with a generated palpation (pokes on the\n"
              "faces given, depth and speed drawn from their ranges with seed + k) and records the body's nodes and the\n"
              "instrument at --rate frames per unit time. Output: mesh.bin, rollout_NNNN.bin, trajectories/, rollouts.json\n"
              "(docs/user-guide.md, \"Rollouts\"). Exit code 3 when a rollout diverged (its frames up to then are kept).");
  rec->add_option("scene", c->options.scene, "scene file (.xml or SOFA .scn)")->required();
  rec->add_option("--out", c->options.out, "the folder to create (must not exist)")->required();
  rec->add_option("--rollouts", c->options.rollouts, "number of rollouts (8)");
  rec->add_option("--time", c->options.time, "simulated time of each rollout, in the scene's time unit (20)");
  rec->add_option("--rate", c->options.rate, "frames per unit time, rounded to a whole number of steps (30)");
  rec->add_option("--depth", c->depth, "range of the poke depth past the face, MIN:MAX in the scene's length unit (2:6)");
  rec->add_option("--speed", c->speed, "range of the press speed, MIN:MAX in length per time unit (5:15)");
  rec->add_option("--faces", c->faces, "faces to poke, comma-separated: top, x-, x+, y-, y+ (all)");
  rec->add_option("--seed", c->options.seed, "rollout k draws from seed + k (1)");
  rec->add_option("--jobs", c->options.jobs, "rollouts run at once (0: one per core)");
  rec->add_option("--set", c->options.sets, "set a scene attribute, ADDRESS=VALUE; repeatable");
  rec->add_flag("--quiet", c->quiet, "no progress or summary");
  rec->callback([c, &action] { action = [c] { return recordRollouts(*c); }; });
}

}  // namespace viscera
