// Files written whole or not at all.
#pragma once

#include <string>

namespace viscera {

// Writes `content` to `path` through a temporary file in the same folder and a rename, so that
// readers never see a half-written file. Throws viscera::Error naming the path on failure.
void writeFileAtomic(const std::string& path, const std::string& content);

}  // namespace viscera
