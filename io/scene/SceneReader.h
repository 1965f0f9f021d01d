// Reads an XML scene (SOFA-style nested <Node>s holding components) into a SceneDesc, keeping
// the line and column of every element and attribute for messages.
#pragma once

#include <string>

#include "core/SceneDesc.h"

namespace viscera::io {

// Throws viscera::Error "file:line:col: ..." for unreadable or malformed XML.
SceneDesc readScene(const std::string& path);
// Parses scene text; `file` names it in messages and sets the folder for relative paths.
SceneDesc parseSceneText(const std::string& text, const std::string& file);

}  // namespace viscera::io
