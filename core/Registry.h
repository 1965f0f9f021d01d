// The one table of component types: the scene builder, `viscera components`, and error messages
// all read it. Modules add their components with plain functions (registerX(Registry&)).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/Schema.h"

namespace viscera {

class Registry {
 public:
  // Adds a component type; its aliases (SOFA's names) resolve to it.
  void add(ComponentSpec spec);
  // Accepts a tag that does not change the physics (drawing, plugins, SOFA loop managers);
  // any attribute is allowed and the element is skipped with a note.
  void addIgnored(const std::string& tag, const std::string& why);

  // nullptr if unknown. Looks through aliases.
  const ComponentSpec* find(const std::string& tag) const;
  // Why a tag is ignored, or nullptr if it is not an ignored tag.
  const std::string* ignoredReason(const std::string& tag) const;
  // Names close to `tag` (edit distance), for "did you mean" messages.
  std::vector<std::string> suggest(const std::string& tag) const;

  const std::map<std::string, ComponentSpec>& specs() const { return specs_; }
  const std::map<std::string, std::string>& ignored() const { return ignored_; }

  // The spec of the `Node` element itself (dt, gravity, units, name).
  static const ComponentSpec& nodeSpec();

 private:
  std::map<std::string, ComponentSpec> specs_;
  std::map<std::string, std::string> aliases_;
  std::map<std::string, std::string> ignored_;
};

}  // namespace viscera
