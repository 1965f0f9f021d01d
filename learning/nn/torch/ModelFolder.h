// What every model folder's config.json shares (the stepper's and the corrector's): its kind, the
// mesh it was trained on and that mesh's fingerprint.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "learning/data/Rollout.h"

namespace viscera::learning {

std::string hexFingerprint(std::uint64_t hash);

// Reads folder/config.json (its path in `configPath`) and checks that it is a model of `kind`, of a
// format version from 1 to `newestVersion` (a missing version is 1). Throws Error naming the folder
// or the file.
nlohmann::json readModelConfig(const std::string& folder, const std::string& kind, std::string& configPath, int newestVersion);

// The "mesh" entry: mesh.bin, the mesh's counts and fingerprint.
nlohmann::ordered_json meshEntry(const RestMesh& mesh, std::uint64_t hash);
// Throws Error when mesh.bin's fingerprint is not the one config.json holds.
void checkMeshEntry(const nlohmann::json& config, std::uint64_t hash, const std::string& configPath);

}  // namespace viscera::learning
