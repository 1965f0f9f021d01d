// The parsed, editable form of a scene: elements with their attributes as text and the file,
// line and column of each. Batch studies edit this description and build scene variants from it.
#pragma once

#include <string>
#include <vector>

#include "core/Error.h"

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
  std::string comment;  // written before the element when the description is written out (io/scene/SceneWriter.h)

  const AttrDesc* find(const std::string& name) const;
  // Sets (or adds) an attribute. Messages about its value name `origin` when given (e.g.
  // "--set phantom/fem.youngModulus"), else where the element or attribute was written.
  void set(const std::string& name, const std::string& value, const SourceLoc& origin = {});
  // The name an address uses for this element: its `name` attribute, else its tag.
  std::string addressName() const;
};

// Elements are addressed by the names on their path from the root: "phantom/fem" is the element
// named fem in the node named phantom. An address matches every element whose path ends with it;
// a leading '/' anchors it at the root (whose own name may be given or left out). Attributes are
// addressed as "phantom/fem.youngModulus".
struct SceneDesc {
  std::string file;       // the scene file (for messages and relative paths)
  std::string directory;  // its folder; mesh and data paths are relative to it
  // Where a file named in the scene is looked for when it is not in `directory` (SOFA's data
  // search path; io/scene/SceneReader.h fills it).
  std::vector<std::string> searchPath;
  ElementDesc root;
  // What reading the scene noticed (an <include> attribute that matched nothing, ...).
  std::vector<std::string> notes;

  // The one element at `path`; an Error listing the candidates when none or several match.
  ElementDesc& element(const std::string& path);
  const ElementDesc& element(const std::string& path) const;
  // Every element matching `path` with its full path ("/phantom/fem"), in scene order.
  std::vector<std::pair<std::string, const ElementDesc*>> matches(const std::string& path) const;
  // The text written for "path.attribute", or nullptr when the scene leaves it to its default.
  const AttrDesc* get(const std::string& address) const;
  // Sets "path.attribute" to `value` (text as in the scene: "3.2 kPa"); the value is checked
  // when the scene is built, with messages naming "--set ADDRESS" when `origin` says so.
  void set(const std::string& address, const std::string& value, const SourceLoc& origin = {});
  // Applies "ADDRESS=VALUE" (the command line's --set); errors name the option.
  void applySetting(const std::string& assignment);
};

// Splits "phantom/fem.youngModulus" into ("phantom/fem", "youngModulus"); Error if there is no
// attribute part.
std::pair<std::string, std::string> splitAddress(const std::string& address);

}  // namespace viscera
