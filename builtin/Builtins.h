// The built-in components: the top of the build, where every module's components are registered.
// Core knows no component; a scene is built against a registry, and this is the usual one.
#pragma once

#include <memory>

#include "core/Registry.h"
#include "core/Scene.h"
#include "core/SceneDesc.h"

namespace viscera {

// Registers every built-in component and the SOFA elements accepted without effect.
void registerBuiltins(Registry& r);
// The registry of the built-in components, made once.
const Registry& builtinRegistry();
// Scene::build with the built-in components.
std::unique_ptr<Scene> buildScene(const SceneDesc& desc);

}  // namespace viscera
