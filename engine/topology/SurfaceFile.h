// A surface file named by a component's attribute: found along the scene's data search path, read
// once per process (the input cache), and any error reported at that attribute.
#pragma once

#include <memory>
#include <string>

#include "io/surface/SurfaceMesh.h"

namespace viscera {

class Component;

std::shared_ptr<const io::SurfaceMesh> readSurfaceAttribute(const Component& c, const std::string& attr);

}  // namespace viscera
