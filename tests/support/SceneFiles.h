// A shipped scene read for a test, without its exporters: tests that compare states or results
// leave no files behind.
#pragma once

#include <algorithm>
#include <functional>
#include <string>

#include "builtin/Builtins.h"
#include "core/Registry.h"
#include "core/SceneDesc.h"
#include "io/scene/SceneReader.h"

namespace viscera::test_support {

// A component that writes files (VTKExporter, ExodusExporter, ...): its category is "output".
inline bool isExporter(const std::string& tag) {
  const ComponentSpec* s = builtinRegistry().find(tag);
  return s && s->category == "output";
}

// `rel` is relative to the source tree ("scenes/gel_phantom.xml").
inline SceneDesc readSceneWithoutExports(const std::string& rel) {
  SceneDesc d = io::readScene(std::string(VISCERA_SOURCE_DIR) + "/" + rel);
  std::function<void(ElementDesc&)> strip = [&](ElementDesc& e) {
    auto& c = e.children;
    c.erase(std::remove_if(c.begin(), c.end(), [](const ElementDesc& x) { return isExporter(x.tag); }), c.end());
    for (auto& x : c) strip(x);
  };
  strip(d.root);
  return d;
}

}  // namespace viscera::test_support
