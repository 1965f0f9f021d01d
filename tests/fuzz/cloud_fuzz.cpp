// Fuzz target of the point-cloud readers: the input's first byte picks the format (even: .pcd,
// odd: .ply) and whether non-finite points are dropped (bit 1); the rest is the file. Bad input
// must end in viscera::Error, nothing else.
#include <cstdint>
#include <string>

#include "io/pointcloud/CloudIo.h"
#include "tests/fuzz/FuzzInput.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = viscera_fuzz::asFile(data + 1, size - 1, data[0] % 2 ? ".ply" : ".pcd");
  viscera::cloud::ReadOptions options;
  options.dropNonFinite = (data[0] >> 1) & 1;
  options.allowEmpty = true;
  viscera_fuzz::expectOnlyInputErrors([&] { viscera::cloud::readCloud(path, options); });
  return 0;
}
