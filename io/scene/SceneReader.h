// Reads an XML scene (SOFA-style nested <Node>s holding components) into a SceneDesc, keeping
// the line and column of every element and attribute for messages.
#pragma once

#include <string>

#include "core/SceneDesc.h"

namespace viscera::io {

// Throws viscera::Error "file:line:col: ..." for unreadable or malformed XML. SOFA's
// `<include href="FILE" .../>` elements are expanded (see parseSceneText).
SceneDesc readScene(const std::string& path);
// Parses scene text; `file` names it in messages and sets the folder for relative paths.
// An `<include href="FILE" a="v" .../>` is replaced by FILE's root element as SOFA does: a root
// named "Group" or "_Group_" gives its children to the including node, one named "_Merge_" is
// merged into it (its attributes set there, each child merged into the child of the same tag and
// name, the others added), any other root becomes a child node (the name is the include's `name`
// when given, and decides the above), and every other attribute of the include replaces the
// attribute of that name wherever it is written in FILE (`node__a` only in elements named node).
SceneDesc parseSceneText(const std::string& text, const std::string& file);

// SOFA's data search path for the scene `sceneFile`: the folders given with setDataPath (the
// command line's --data-path), then those of the SOFA_DATA_PATH environment variable (separated
// by ':'), then the default: for the scene's folder and each folder above it, its `share/` and
// `share/mesh/` subfolders, and the folder itself when it is named `examples` (SOFA's source tree).
// Files named in a scene are looked for in the scene's folder first, then along this path.
std::vector<std::string> dataSearchPath(const std::string& sceneFile);
void setDataPath(std::vector<std::string> folders);

}  // namespace viscera::io
