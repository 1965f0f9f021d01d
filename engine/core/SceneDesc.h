// The parsed, editable form of a scene: elements with their attributes as text and the file,
// line and column of each. Batch studies edit this description and build scene variants from it.
#pragma once

#include <string>
#include <vector>

#include "engine/core/Error.h"

namespace viscera {

struct AttrDesc {
  std::string name;
  std::string value;
  SourceLoc loc;
};

struct ElementDesc {
  std::string tag;
  SourceLoc loc;
  std::vector<AttrDesc> attrs;
  std::vector<ElementDesc> children;

  const AttrDesc* find(const std::string& name) const;
  // Sets (or adds) an attribute, keeping the element's location for messages.
  void set(const std::string& name, const std::string& value);
  // Finds a descendant element (depth first, self included) by its `name` attribute.
  ElementDesc* findByName(const std::string& name);
};

struct SceneDesc {
  std::string file;       // the scene file (for messages and relative paths)
  std::string directory;  // its folder; mesh and data paths are relative to it
  ElementDesc root;
};

}  // namespace viscera
