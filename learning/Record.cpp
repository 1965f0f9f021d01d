#include "learning/Record.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <thread>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "engine/Roles.h"
#include "engine/Run.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "learning/data/Pairs.h"
#include "learning/data/Rollout.h"
#include "motion/Trajectory.h"
#include "observation/Tissue.h"
#include "study/Replay.h"

namespace viscera::learning {

namespace fs = std::filesystem;

namespace {

// What a recording needs of the scene: its one deformable body with tetrahedra, at rest, and the
// instrument's sphere.
struct SceneParts {
  const MechanicalObject* body = nullptr;
  const RigidObject* instrument = nullptr;
  RestMesh mesh;
  double radius = 0;
  double dt = 0, start = 0;
  std::string units;
};

SceneParts inspect(Scene& scene, const std::string& file) {
  SceneParts p;
  scene.init();
  const auto bodies = obs::tissueSurfaces(scene);
  if (bodies.size() != 1)
    throw Error(SourceLoc{file}, "rollouts record one deformable body with tetrahedra; the scene has " +
                                     std::to_string(bodies.size()));
  MechanicalObject& body = *bodies.front().state;
  p.body = &body;
  p.mesh.points = body.x0;
  p.mesh.tets = *obs::bodyTetrahedra(body);
  for (const ProjectiveConstraint* c : scene.all<ProjectiveConstraint>())
    if (&c->mstate() == &body) p.mesh.fixed.insert(p.mesh.fixed.end(), c->fixedNodes().begin(), c->fixedNodes().end());
  std::sort(p.mesh.fixed.begin(), p.mesh.fixed.end());
  p.mesh.fixed.erase(std::unique(p.mesh.fixed.begin(), p.mesh.fixed.end()), p.mesh.fixed.end());
  const auto spheres = scene.all<SphereCollisionModel>();
  if (spheres.size() != 1)
    throw Error(SourceLoc{file}, "rollouts record one instrument with one SphereCollisionModel; the scene has " +
                                     std::to_string(spheres.size()) + " sphere collision models");
  p.instrument = &spheres.front()->body();
  p.radius = spheres.front()->radius();
  p.dt = scene.dt();
  p.start = scene.startTime();
  p.units = scene.units().str();
  return p;
}

// Writes a frame every `every` steps, the initial state included.
class FrameRecorder : public RunObserver {
 public:
  FrameRecorder(const MechanicalObject& body, const RigidObject& tool, int every, RolloutWriter& out)
      : body_(body), tool_(tool), every_(every), out_(out) {}
  void begin(const Simulation& sim, int) override { write(sim); }
  void step(const Simulation& sim) override {
    if (sim.steps() % every_ == 0) write(sim);
  }

 private:
  void write(const Simulation& sim) {
    const RigidObject::Live& b = tool_.live(sim.state());
    frame_.t = sim.time();
    frame_.x = body_.x(sim.state()).cast<float>();
    frame_.tip = b.p;
    frame_.orientation = b.q;
    frame_.velocity = b.v;
    frame_.angularVelocity = b.w;
    frame_.force = b.force;
    frame_.contacts = b.contacts;
    out_.add(frame_);
  }
  const MechanicalObject& body_;
  const RigidObject& tool_;
  int every_;
  RolloutWriter& out_;
  RolloutFrame frame_;
};

struct RolloutPlan {
  int index = 0;
  std::uint64_t seed = 0;
  double depth = 0, speed = 0;
  int pokes = 0;
  std::string name;
};

struct RolloutOutcome {
  int frames = 0;
  std::string status = "ok";  // or the divergence
  double wallSeconds = 0;
};

std::string rolloutName(int k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "rollout_%04d", k);
  return buf;
}

void checkOptions(const RecordOptions& o) {
  auto fail = [](const std::string& what) { throw Error(what); };
  if (o.rollouts < 1 || o.rollouts > 100000) fail("--rollouts: must be 1 to 100000, got " + std::to_string(o.rollouts));
  if (!(o.time > 0) || !std::isfinite(o.time) || o.time > 1e6) fail("--time: must be a positive duration (at most 1e6), got " + formatNumber(o.time));
  if (!(o.rate > 0) || !std::isfinite(o.rate)) fail("--rate: must be a positive number of frames per unit time, got " + formatNumber(o.rate));
  if (!(o.depthMin > 0) || !(o.depthMax >= o.depthMin) || !std::isfinite(o.depthMax))
    fail("--depth: needs 0 < MIN <= MAX, got " + formatNumber(o.depthMin) + ":" + formatNumber(o.depthMax));
  if (!(o.speedMin > 0) || !(o.speedMax >= o.speedMin) || !std::isfinite(o.speedMax))
    fail("--speed: needs 0 < MIN <= MAX, got " + formatNumber(o.speedMin) + ":" + formatNumber(o.speedMax));
  if (o.faces.empty()) fail("--faces: name at least one face (top, x-, x+, y-, y+)");
  if (o.sceneTrajectory && o.rollouts != 1) fail("--scene-trajectory: records one rollout (--rollouts 1)");
  if (o.jobs < 0) fail("--jobs: must be >= 0 (0: one per core)");
  if (fs::exists(o.out)) throw Error(SourceLoc{o.out}, "--out: already exists; rollouts are written to a new folder (nothing was changed)");
  const fs::path parent = fs::absolute(o.out).parent_path();
  if (!fs::is_directory(parent)) throw Error(SourceLoc{o.out}, "--out: the folder " + parent.string() + " does not exist");
}

RecordResult recordInto(const RecordOptions& o, const SceneDesc& desc, const SceneParts& parts, const fs::path& temp,
                        const std::function<void(const std::string&)>& progress);

}  // namespace

RecordResult record(const RecordOptions& o, const std::function<void(const std::string&)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  checkOptions(o);
  SceneDesc desc = io::readScene(o.scene);
  for (const auto& a : o.sets) desc.applySetting(a);

  // The scene as given (its own trajectory, no outputs) tells the body, the instrument and the step.
  SceneDesc plain = desc;
  study::removeOutputs(plain.root, true);
  auto model = buildScene(plain);
  const SceneParts parts = inspect(*model, o.scene);

  const fs::path temp = fs::path(o.out).string() + ".tmp-" + std::to_string(::getpid());
  fs::remove_all(temp);
  fs::create_directories(temp / "trajectories");
  try {
    RecordResult result = recordInto(o, desc, parts, temp, progress);
    std::error_code ec;
    fs::rename(temp, o.out, ec);
    if (ec) throw Error(SourceLoc{o.out}, "cannot move the rollouts into place: " + ec.message());
    result.wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return result;
  } catch (...) {
    std::error_code ec;
    fs::remove_all(temp, ec);
    throw;
  }
}

PairResult recordPairs(const PairOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (o.maxPoints < 1) throw Error("--points: must be at least 1");
  if (fs::exists(o.out)) throw Error(SourceLoc{o.out}, "--out: already exists; pairs are written to a new folder (nothing was changed)");
  const fs::path parent = fs::absolute(o.out).parent_path();
  if (!fs::is_directory(parent)) throw Error(SourceLoc{o.out}, "--out: the folder " + parent.string() + " does not exist");
  study::ScoreOptions score;
  score.maxPoints = o.maxPoints;
  const study::PreparedDataset data = study::prepareDataset(o.data, score);
  SceneDesc desc = io::readScene(o.scene);
  for (const auto& a : o.sets) desc.applySetting(a);
  const SceneDesc replayed = study::replayDescription(desc, data.data);

  // The body, its grid and the camera's direction.
  auto model = buildScene(replayed);
  const SceneParts parts = inspect(*model, o.scene);
  PairSet pairs;
  pairs.scene = fs::absolute(o.scene).string();
  pairs.dataset = fs::absolute(o.data).string();
  pairs.units = parts.units;
  pairs.mesh = parts.mesh;
  for (const Topology* t : model->all<Topology>()) {
    const auto cells = t->gridCells();
    if (cells[0] > 0 && (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1) == parts.body->size()) {
      pairs.grid = {cells[0] + 1, cells[1] + 1, cells[2] + 1};
      break;
    }
  }
  if (pairs.grid.nodes() == 0)
    throw Error(SourceLoc{o.scene}, "a learned correction needs a body whose nodes are a RegularGridTopology's; '" + parts.body->name() +
                                        "' has none");
  checkGrid(pairs.mesh, pairs.grid, o.scene);
  if (data.data.cameraToScene) pairs.viewDirection = data.data.cameraToScene->linear() * Eigen::Vector3d::UnitZ();

  study::ReplayOptions ro;
  ro.score = data.score;
  ro.keepSurfaces = true;
  const study::ReplayScore r = study::replay(replayed, data, ro);
  if (!r.ok()) throw Error(SourceLoc{o.scene}, "the replay of " + o.data + " did not finish: " + r.reason);
  const study::RecordedSurfaces& rec = *r.surfaces;
  if (rec.nodes != parts.body->size()) throw Error(SourceLoc{o.scene}, "pairs record one deformable body; the scene has several");
  for (size_t i = 0; i < rec.frame.size(); ++i) {
    RolloutFrame f;
    f.t = data.data.frames[rec.frame[i]].time;
    f.x = rec.x[i].cast<float>();
    f.tip = rec.tip[i];
    // The instrument's velocity from its neighbouring frames.
    const size_t a = i > 0 ? i - 1 : i, b = i + 1 < rec.frame.size() ? i + 1 : i;
    const double dt = data.data.frames[rec.frame[b]].time - data.data.frames[rec.frame[a]].time;
    if (dt > 0) f.velocity = (rec.tip[b] - rec.tip[a]) / dt;
    pairs.states.push_back(std::move(f));
    pairs.clouds.push_back(data.clouds[rec.frame[i]].cast<float>());
  }
  const fs::path temp = fs::path(o.out).string() + ".tmp-" + std::to_string(::getpid());
  fs::remove_all(temp);
  fs::create_directories(temp);
  try {
    writePairSet(temp.string(), pairs);
    fs::rename(temp, o.out);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(temp, ec);
    throw;
  }
  PairResult result;
  result.frames = static_cast<int>(pairs.states.size());
  result.cloudRms = r.cloudRms;
  result.wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

RestMesh sceneRestMesh(const std::string& scene, const std::vector<std::string>& sets) {
  SceneDesc desc = io::readScene(scene);
  for (const auto& a : sets) desc.applySetting(a);
  study::removeOutputs(desc.root, true);
  auto model = buildScene(desc);
  return inspect(*model, scene).mesh;
}

namespace {

RecordResult recordInto(const RecordOptions& o, const SceneDesc& desc, const SceneParts& parts, const fs::path& temp,
                        const std::function<void(const std::string&)>& progress) {
  const int every = std::max(1, static_cast<int>(std::lround(1.0 / (o.rate * parts.dt))));
  const double frameRate = 1.0 / (every * parts.dt);
  // Each rollout's palpation: its own seed, depth and speed; the trajectory in the scene's frame.
  std::vector<RolloutPlan> plans(o.rollouts);
  std::vector<SceneDesc> variants(o.rollouts);
  for (int k = 0; k < o.rollouts; ++k) {
    RolloutPlan& p = plans[k];
    p.index = k;
    p.seed = o.seed + static_cast<std::uint64_t>(k);
    p.name = rolloutName(k);
    if (o.sceneTrajectory) {
      variants[k] = desc;
      study::removeOutputs(variants[k].root, true);
      continue;
    }
    std::mt19937_64 rng(p.seed);
    p.depth = std::uniform_real_distribution<double>(o.depthMin, o.depthMax)(rng);
    p.speed = std::uniform_real_distribution<double>(o.speedMin, o.speedMax)(rng);
    motion::PalpationSpec spec;
    spec.boxMin = parts.mesh.points.rowwise().minCoeff();
    spec.boxMax = parts.mesh.points.rowwise().maxCoeff();
    spec.radius = parts.radius;
    spec.depth = p.depth;
    spec.speed = p.speed;
    spec.travelSpeed = 3 * p.speed;
    spec.duration = o.time;
    spec.rate = std::min(1.0 / parts.dt, 1000.0);
    spec.faces = o.faces;
    spec.seed = p.seed;
    motion::PalpationResult pal;
    try {
      pal = motion::generatePalpation(spec);
    } catch (const std::invalid_argument& e) {
      // The generator names its spec's fields; the one a user sets here is the rollout's time.
      std::string why = e.what();
      if (why.rfind("duration", 0) == 0) why = "--time" + why.substr(8);
      throw Error("rollout " + std::to_string(k) + ": cannot make a palpation of the body: " + why);
    }
    p.pokes = pal.pokes;
    const std::string traj = (temp / "trajectories" / (p.name + ".csv")).string();
    motion::writeTrajectoryCsv(traj, pal.trajectory);
    // The trajectory starts at time 0; the scene at its start time.
    variants[k] = study::withTrajectory(desc, traj, -parts.start, "each rollout's instrument follows a generated palpation");
  }

  writeRestMesh((temp / "mesh.bin").string(), parts.mesh);

  std::vector<RolloutOutcome> outcomes(o.rollouts);
  std::atomic<int> next{0};
  std::mutex errorMutex, progressMutex;
  std::string firstError;
  int done = 0;
  auto worker = [&] {
    for (int k; (k = next++) < o.rollouts;) {
      try {
        const auto w0 = std::chrono::steady_clock::now();
        auto scene = buildScene(variants[k]);
        Simulation sim(*scene);
        const SceneParts mine = inspect(*scene, o.scene);
        RolloutWriter writer((temp / (plans[k].name + ".bin")).string(), mine.body->size());
        FrameRecorder recorder(*mine.body, *mine.instrument, every, writer);
        RunOptions ro;
        ro.steps = static_cast<int>(std::lround(o.time / parts.dt));
        ro.threads = 1;
        ro.recordWrench = false;
        ro.observers.push_back(&recorder);
        const RunResult r = run(sim, ro);
        writer.close();
        RolloutOutcome& out = outcomes[k];
        out.frames = writer.frames();
        if (r.failure) out.status = r.failure->str();
        out.wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
        if (progress) {
          std::lock_guard<std::mutex> lock(progressMutex);
          std::ostringstream line;
          line.precision(3);
          line << plans[k].name << " (" << ++done << "/" << o.rollouts << "): " << out.frames << " frames, ";
          if (o.sceneTrajectory)
            line << "the scene's trajectory";
          else
            line << plans[k].pokes << (plans[k].pokes == 1 ? " poke" : " pokes") << ", depth " << plans[k].depth
                 << ", speed " << plans[k].speed;
          line << ", " << formatDuration(out.wallSeconds)
               << (r.failure ? ", DIVERGED: " + r.failure->str() : std::string());
          progress(line.str());
        }
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(errorMutex);
        if (firstError.empty()) firstError = plans[k].name + ": " + e.what();
        next = o.rollouts;  // stop handing out rollouts
      }
    }
  };
  const int jobs = std::max(1, std::min(o.rollouts, o.jobs > 0 ? o.jobs : static_cast<int>(std::thread::hardware_concurrency())));
  std::vector<std::thread> pool;
  for (int j = 0; j < jobs; ++j) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  if (!firstError.empty()) throw Error(firstError + " (no rollouts were written)");

  RecordResult result;
  result.rollouts = o.rollouts;
  nlohmann::ordered_json index;
  index["format"] = "viscera rollouts";
  index["version"] = 1;
  index["scene"] = fs::absolute(o.scene).string();
  index["sets"] = o.sets;
  index["units"] = parts.units;
  index["dt"] = parts.dt;
  index["frameRate"] = frameRate;
  index["stepsPerFrame"] = every;
  index["mesh"] = {{"file", "mesh.bin"},
                   {"nodes", parts.mesh.points.cols()},
                   {"tetrahedra", parts.mesh.tets.cols()},
                   {"fixedNodes", parts.mesh.fixed.size()}};
  index["instrumentRadius"] = parts.radius;
  index["seed"] = o.seed;
  std::vector<std::string> faces;
  for (motion::Face f : o.faces) faces.push_back(motion::faceName(f));
  index["faces"] = faces;
  auto& list = index["rollouts"] = nlohmann::ordered_json::array();
  for (int k = 0; k < o.rollouts; ++k) {
    const RolloutPlan& p = plans[k];
    const RolloutOutcome& out = outcomes[k];
    if (o.sceneTrajectory) {
      list.push_back({{"file", p.name + ".bin"}, {"trajectory", "the scene's own"}, {"frames", out.frames},
                      {"status", out.status == "ok" ? "ok" : "diverged"}});
      if (out.status != "ok") list.back()["failure"] = out.status;
      result.frames += out.frames;
      result.diverged += out.status != "ok";
      continue;
    }
    list.push_back({{"file", p.name + ".bin"},
                    {"trajectory", "trajectories/" + p.name + ".csv"},
                    {"seed", p.seed},
                    {"depth", p.depth},
                    {"speed", p.speed},
                    {"pokes", p.pokes},
                    {"frames", out.frames},
                    {"status", out.status == "ok" ? "ok" : "diverged"}});
    if (out.status != "ok") list.back()["failure"] = out.status;
    result.frames += out.frames;
    result.diverged += out.status != "ok";
  }
  writeFileAtomic((temp / "rollouts.json").string(), index.dump(2) + "\n");
  result.simulatedTime = o.time * o.rollouts;
  return result;
}

}  // namespace

}  // namespace viscera::learning
