// SOFA's state dump (what its WriteState writes and its regression references hold): a text file,
// gzip-compressed when its name ends in .gz, with one frame per written time:
//   T= <time>
//     X= <x y z of every node>
//     V= <velocities>            (and F= forces, X0= rest positions, when written)
#pragma once

#include <string>

namespace viscera::io {

// A dump written as it grows, gzip-compressed if the name ends in ".gz": frames go to a temporary
// file beside `path`, which replaces `path` only when finish() is called (so a reader never sees a
// half-written dump, and an older one stays until then). The temporary is removed if never finished.
class StateDumpWriter {
 public:
  explicit StateDumpWriter(const std::string& path);
  ~StateDumpWriter();
  StateDumpWriter(const StateDumpWriter&) = delete;
  StateDumpWriter& operator=(const StateDumpWriter&) = delete;
  void append(const std::string& text);
  void finish();

 private:
  std::string path_, temporary_;
  void* file_ = nullptr;  // zlib's gzFile, also for plain text ("wT")
};

}  // namespace viscera::io
