#include "engine/topology/SurfaceFile.h"

#include <filesystem>

#include "core/Component.h"
#include "core/Scene.h"
#include "io/scene/InputCache.h"

namespace viscera {

std::shared_ptr<const io::SurfaceMesh> readSurfaceAttribute(const Component& c, const std::string& attr) {
  const std::string path = c.scene().resolvePath(c.attrs().str(attr));
  if (!std::filesystem::exists(path)) throw c.error(attr, "surface file '" + path + "' does not exist");
  try {
    return io::cachedRead<io::SurfaceMesh>(path, [](const std::string& p) { return io::readSurface(p); });
  } catch (const Error& e) {
    throw c.error(attr, e.what());
  }
}

}  // namespace viscera
