#include "engine/core/SceneDesc.h"

namespace viscera {

const AttrDesc* ElementDesc::find(const std::string& name) const {
  for (const auto& a : attrs)
    if (a.name == name) return &a;
  return nullptr;
}

void ElementDesc::set(const std::string& name, const std::string& value) {
  for (auto& a : attrs)
    if (a.name == name) {
      a.value = value;
      return;
    }
  attrs.push_back({name, value, loc});
}

ElementDesc* ElementDesc::findByName(const std::string& name) {
  const AttrDesc* n = find("name");
  if (n && n->value == name) return this;
  for (auto& c : children)
    if (ElementDesc* e = c.findByName(name)) return e;
  return nullptr;
}

}  // namespace viscera
