// Fuzz target of the volume-mesh readers: the input's first byte picks the format (modulo 3: '0'
// Gmsh .msh, '1' legacy .vtk, '2' VTK XML .vtu), the rest is the file; a mesh that reads is also
// checked (counts, indices, degenerate or inverted tetrahedra). Bad input must end in
// viscera::Error, nothing else.
#include <cstdint>
#include <string>

#include "io/mesh/Mesh.h"
#include "tests/fuzz/FuzzInput.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* const kExtensions[3] = {".msh", ".vtk", ".vtu"};
  const std::string path = viscera_fuzz::asFile(data + 1, size - 1, kExtensions[data[0] % 3]);
  viscera_fuzz::expectOnlyInputErrors([&] {
    const auto mesh = viscera::io::readVolumeMesh(path);
    viscera::io::checkTetMesh(mesh, path);
  });
  return 0;
}
