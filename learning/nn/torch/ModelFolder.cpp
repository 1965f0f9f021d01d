#include "learning/nn/torch/ModelFolder.h"

#include <filesystem>
#include <sstream>

#include "core/Error.h"
#include "core/Files.h"

namespace viscera::learning {

std::string hexFingerprint(std::uint64_t hash) {
  std::ostringstream s;
  s << std::hex;
  s.width(16);
  s.fill('0');
  s << hash;
  return s.str();
}

nlohmann::json readModelConfig(const std::string& folder, const std::string& kind, std::string& configPath, int newestVersion) {
  configPath = (std::filesystem::path(folder) / "config.json").string();
  if (!std::filesystem::is_directory(folder)) throw Error(SourceLoc{folder}, "not a model folder (no such folder)");
  nlohmann::json c;
  try {
    c = nlohmann::json::parse(readInputFile(configPath, "model configuration"));
  } catch (const nlohmann::json::exception& e) {
    throw Error(SourceLoc{configPath}, std::string("not valid JSON: ") + e.what());
  }
  if (!c.is_object() || c.value("format", "") != "viscera model") throw Error(SourceLoc{configPath}, "format is not \"viscera model\"");
  if (c.value("kind", "") != kind) throw Error(SourceLoc{configPath}, "is a " + c.value("kind", std::string("?")) + " model, not a " + kind);
  const nlohmann::json& version = c.contains("version") ? c.at("version") : nlohmann::json(1);
  if (!version.is_number_integer() || version.get<int>() < 1 || version.get<int>() > newestVersion)
    throw Error(SourceLoc{configPath}, "version " + version.dump() + " of a " + kind + " model; this Viscera reads versions 1 to " +
                                           std::to_string(newestVersion) + " (a newer Viscera wrote it?)");
  return c;
}

nlohmann::ordered_json meshEntry(const RestMesh& mesh, std::uint64_t hash) {
  return {{"file", "mesh.bin"},
          {"nodes", mesh.points.cols()},
          {"tetrahedra", mesh.tets.cols()},
          {"fixedNodes", mesh.fixed.size()},
          {"hash", hexFingerprint(hash)}};
}

void checkMeshEntry(const nlohmann::json& config, std::uint64_t hash, const std::string& configPath) {
  const std::string stored = config.at("mesh").at("hash").get<std::string>();
  if (stored != hexFingerprint(hash))
    throw Error(SourceLoc{configPath}, "the mesh file's fingerprint is " + hexFingerprint(hash) + ", the configuration says " + stored +
                                           ": mesh.bin is not the mesh the model was trained on");
}

}  // namespace viscera::learning
