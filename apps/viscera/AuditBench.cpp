// `viscera audit bench SCENE`: how often the audit names what was planted. Every effect of the
// library is planted in SCENE at several strengths and seeds (and controls with none), a dataset
// is made from each ground truth (its own depth camera, force noise, the scene's own palpation),
// the audit runs on it with SCENE as the nominal model, and the first effect it names is counted:
// the confusion matrix planted x named, the detection rate and the false-discovery rate.
#include "apps/viscera/AuditBench.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "apps/viscera/DatasetCommand.h"
#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Files.h"
#include "core/Text.h"
#include "io/scene/SceneReader.h"
#include "io/scene/SceneWriter.h"
#include "io/scene/Transform.h"
#include "study/Audit.h"

namespace viscera {

namespace fs = std::filesystem;

void absolutiseInputs(ElementDesc& el, const fs::path& sceneDir) {
  const ComponentSpec* spec = builtinRegistry().find(el.tag);
  if (spec && spec->category != "output" && spec->category != "sensor")
    for (auto& at : el.attrs) {
      const AttrSpec* a = spec->find(at.name);
      if (a && a->kind == AttrKind::File && !at.value.empty() && fs::path(at.value).is_relative())
        at.value = (sceneDir / at.value).lexically_normal().string();
    }
  for (auto& c : el.children) absolutiseInputs(c, sceneDir);
}

namespace {

struct Case {
  std::string planted;  // effect key, or "none" for a control
  double strength = 0;
  unsigned seed = 1;
  std::vector<double> values;
  std::vector<std::string> found;
  double seconds = 0;
  std::string error;
};

// The camera the bench films each truth with: above and in front of the tissue, looking at its
// centre, from about four diagonals away.
ElementDesc benchCamera(const study::AuditScene& as, unsigned seed) {
  const Eigen::Vector3d c = as.tissueBox.center();
  const double d = as.tissueBox.diagonal().norm();
  const Eigen::Vector3d p = c + d * Eigen::Vector3d(0, -4, 5);
  auto text = [](const Eigen::Vector3d& v) { return formatNumber(v.x()) + " " + formatNumber(v.y()) + " " + formatNumber(v.z()); };
  ElementDesc cam;
  cam.tag = "DepthCamera";
  cam.loc = SourceLoc{"audit bench"};
  cam.set("name", "camera");
  cam.set("position", text(p));
  cam.set("lookAt", text(c));
  cam.set("rate", "10");
  cam.set("tissueOnly", "true");
  cam.set("seed", std::to_string(seed));
  return cam;
}

std::string json(const AuditBenchArgs& a, const std::vector<Case>& cases, const std::vector<std::string>& keys,
                 double detection, double fdr, double seconds) {
  nlohmann::ordered_json j;
  j["scene"] = fs::absolute(a.scene).string();
  j["time"] = a.time;
  j["seeds"] = a.seeds;
  j["strengths"] = a.strengths;
  j["effects"] = keys;
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (const Case& c : cases)
    rows.push_back({{"planted", c.planted},
                    {"strength", c.strength},
                    {"seed", c.seed},
                    {"values", c.values},
                    {"found", c.found},
                    {"named", c.found.empty() ? std::string("none") : c.found.front()},
                    {"seconds", c.seconds},
                    {"error", c.error}});
  j["cases"] = rows;
  j["detection_rate"] = detection;
  j["false_discovery_rate"] = fdr;
  j["seconds"] = seconds;
  return j.dump(2) + "\n";
}

}  // namespace

int auditBench(const AuditBenchArgs& a) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  if (!(a.time > 0)) throw Error("--time: the simulated time of each case must be > 0");
  if (a.seeds < 1) throw Error("--seeds: must be at least 1");
  for (double s : a.strengths)
    if (!(s > 0 && s <= 1)) throw Error("--strengths: each must be in (0, 1], got " + formatNumber(s));
  const SceneDesc scene = io::readScene(a.scene);
  const fs::path sceneDir = fs::absolute(a.scene).parent_path();
  const fs::path out = a.out;
  if (fs::exists(out)) throw Error(SourceLoc{a.out}, "--out: already exists; the bench writes a new folder (nothing was changed)");
  const fs::path parent = fs::absolute(out).parent_path();
  if (!fs::is_directory(parent)) throw Error(SourceLoc{a.out}, "--out: the folder " + parent.string() + " does not exist");

  const study::AuditScene as = study::describeScene(scene);
  const auto library = study::effectLibrary();
  std::vector<const study::Effect*> effects;
  for (const auto& e : library) {
    if (!a.effects.empty() && std::find(a.effects.begin(), a.effects.end(), e->key()) == a.effects.end()) continue;
    if (e->params(as).empty()) {
      std::cerr << "effect '" << e->key() << "' does not apply to this scene: not planted\n";
      continue;
    }
    effects.push_back(e.get());
  }
  for (const auto& k : a.effects)
    if (std::none_of(library.begin(), library.end(), [&](const auto& e) { return e->key() == k; }))
      throw Error("--effects: '" + k + "' is not an effect of the library");

  std::vector<Case> cases;
  for (unsigned seed = 1; seed <= static_cast<unsigned>(a.seeds); ++seed) {
    Case c;
    c.planted = "none";
    c.seed = seed;
    cases.push_back(c);
  }
  for (const study::Effect* e : effects)
    for (double s : a.strengths)
      for (unsigned seed = 1; seed <= static_cast<unsigned>(a.seeds); ++seed) {
        Case c;
        c.planted = e->key();
        c.strength = s;
        c.seed = seed;
        c.values = e->plant(as, s, seed);
        cases.push_back(c);
      }

  const fs::path temp = out.string() + ".tmp-" + std::to_string(::getpid());
  fs::remove_all(temp);
  fs::create_directories(temp);
  study::AuditOptions o;
  o.jobs = a.jobs;
  o.replay.threads = 1;
  for (size_t i = 0; i < cases.size(); ++i) {
    Case& c = cases[i];
    const auto t0 = clock::now();
    const fs::path dir = temp / (c.planted + "_" + formatNumber(c.strength) + "_" + std::to_string(c.seed));
    fs::create_directories(dir);
    std::cerr << "[" << i + 1 << "/" << cases.size() << "] planted " << c.planted;
    if (c.planted != "none") std::cerr << " (strength " << formatNumber(c.strength) << ")";
    std::cerr << ", seed " << c.seed << ": " << std::flush;
    try {
      // The ground truth: the scene with the effect planted, filmed by its own camera.
      SceneDesc truth = scene;
      const study::Effect* effect = nullptr;
      for (const study::Effect* e : effects)
        if (e->key() == c.planted) effect = e;
      if (effect) effect->apply(truth, c.values, as);
      absolutiseInputs(truth.root, sceneDir);
      std::function<void(ElementDesc&)> dropCameras = [&](ElementDesc& el) {
        el.children.erase(std::remove_if(el.children.begin(), el.children.end(),
                                         [](const ElementDesc& x) { return x.tag == "DepthCamera"; }),
                          el.children.end());
        for (auto& ch : el.children) dropCameras(ch);
      };
      dropCameras(truth.root);
      truth.root.children.push_back(benchCamera(as, c.seed));
      io::writeScene((dir / "truth.xml").string(), truth, "ground truth of viscera audit bench");
      DatasetMakeOptions m;
      m.scene = (dir / "truth.xml").string();
      m.out = (dir / "data").string();
      m.time = a.time;
      m.forceNoise = a.forceNoise;
      m.seed = c.seed;
      m.quiet = true;
      if (makeDataset(m) != 0) throw Error("the ground truth did not run to the end");
      if (effect) {
        if (auto correction = effect->cloudCorrection(c.values, as)) {
          // A registration error: the dataset's transform is off by the inverse of the correction.
          const fs::path tf = dir / "data" / "camera_to_scene.txt";
          const RigidTransform T = readTransform(tf.string());
          writeTransform(tf.string(), correction->inverse() * T, "camera -> scene, off by the planted registration error");
        }
      }
      const study::PreparedDataset data = study::prepareDataset((dir / "data").string(), o.replay.score);
      const study::AuditReport r = study::runAudit(scene, data, o);
      c.found = r.found;
    } catch (const Error& e) {
      c.error = e.what();
    }
    c.seconds = std::chrono::duration<double>(clock::now() - t0).count();
    std::cerr << (c.error.empty() ? (c.found.empty() ? std::string("named none") : "named " + c.found.front()) : "error: " + c.error)
              << " (" << formatNumber(std::round(c.seconds * 10) / 10) << " s)\n";
    if (!a.keep) fs::remove_all(dir);
  }

  // The confusion matrix: planted (rows) x first effect named (columns).
  std::vector<std::string> keys;
  for (const study::Effect* e : effects) keys.push_back(e->key());
  std::vector<std::string> rowsK = keys, colsK = keys;
  rowsK.insert(rowsK.begin(), "none");
  colsK.push_back("none");
  std::map<std::string, std::map<std::string, int>> m;
  int planted = 0, detected = 0, named = 0, wrong = 0, failed = 0;
  for (const Case& c : cases) {
    if (!c.error.empty()) {
      ++failed;
      continue;
    }
    const std::string first = c.found.empty() ? "none" : c.found.front();
    m[c.planted][first] += 1;
    if (c.planted != "none") {
      ++planted;
      detected += first == c.planted;
    }
    for (const auto& f : c.found) {
      ++named;
      wrong += f != c.planted;
    }
  }
  const double detection = planted ? static_cast<double>(detected) / planted : 0.0;
  const double fdr = named ? static_cast<double>(wrong) / named : 0.0;
  const double seconds = std::chrono::duration<double>(clock::now() - start).count();
  std::ostringstream md;
  md << "# Audit bench\n\nScene `" << fs::absolute(a.scene).string() << "`, " << formatNumber(a.time) << " s per case, "
     << a.seeds << " seed(s), strengths";
  for (double s : a.strengths) md << " " << formatNumber(s);
  md << ", force noise " << a.forceNoise << ".\n\nRows: the effect planted in the ground truth; columns: the first effect the "
     << "audit named.\n\n| planted \\ named |";
  for (const auto& k : colsK) md << " " << k << " |";
  md << "\n|---|";
  for (size_t k = 0; k < colsK.size(); ++k) md << "---|";
  md << "\n";
  for (const auto& r : rowsK) {
    md << "| " << r << " |";
    for (const auto& k : colsK) md << " " << (m[r][k] ? std::to_string(m[r][k]) : std::string("")) << " |";
    md << "\n";
  }
  md << "\nDetection rate (the planted effect named first): " << detected << "/" << planted << " = " << formatNumber(detection)
     << ". False-discovery rate (effects named that were not planted, over all named): " << wrong << "/" << named << " = "
     << formatNumber(fdr) << ".";
  if (failed) md << " Cases that failed: " << failed << " (see bench.json).";
  md << " Wall time " << formatNumber(std::round(seconds)) << " s.\n";
  writeFileAtomic((temp / "bench.md").string(), md.str());
  writeFileAtomic((temp / "bench.json").string(), json(a, cases, keys, detection, fdr, seconds));
  std::error_code ec;
  fs::rename(temp, out, ec);
  if (ec) throw Error(SourceLoc{a.out}, "cannot move the results into place: " + ec.message() + " (kept at " + temp.string() + ")");
  std::cout << md.str();
  std::cerr << "wrote " << (out / "bench.md").string() << " and bench.json\n";
  return failed ? kExitInvalidInput : kExitOk;
}

}  // namespace viscera
