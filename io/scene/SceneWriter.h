// Writes a scene description back as XML: what a study that edits a scene (the audit's augmented
// scene) hands to the user, readable by `viscera run` and by SOFA for the components it shares.
#pragma once

#include <string>

#include "core/SceneDesc.h"

namespace viscera::io {

// The description as XML text: elements and attributes in their order, four spaces per level,
// each element's `comment` as an XML comment on the line before it, `header` as a comment before
// the root. Paths are written as they are in the description (relative to its folder).
std::string formatScene(const SceneDesc& scene, const std::string& header = "");

// Writes formatScene atomically.
void writeScene(const std::string& path, const SceneDesc& scene, const std::string& header = "");

}  // namespace viscera::io
