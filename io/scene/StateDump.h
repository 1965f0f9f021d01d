// SOFA's state dump (what its WriteState writes and its regression references hold): a text file,
// gzip-compressed when its name ends in .gz, with one frame per written time:
//   T= <time>
//     X= <x y z of every node>
//     V= <velocities>            (and F= forces, X0= rest positions, when written)
#pragma once

#include <string>

namespace viscera::io {

// Writes `text` to `path` whole (atomically), gzip-compressed if the name ends in ".gz".
void writeMaybeGzip(const std::string& path, const std::string& text);

}  // namespace viscera::io
