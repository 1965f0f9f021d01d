#include "io/scene/StateDump.h"

#include <zlib.h>

#include "core/Error.h"
#include "core/Files.h"

namespace viscera::io {

namespace {

// The gzip stream of `text` (zlib's deflate with a gzip header: windowBits 15 + 16).
std::string gzip(const std::string& text, const std::string& path) {
  if (text.size() > (1u << 31)) throw Error(SourceLoc{path}, "more than 2 GiB of text to compress in one go");
  z_stream z{};
  if (deflateInit2(&z, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw Error(SourceLoc{path}, "cannot start gzip compression");
  std::string out(deflateBound(&z, static_cast<uLong>(text.size())) + 32, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
  z.avail_in = static_cast<uInt>(text.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  if (rc != Z_STREAM_END) throw Error(SourceLoc{path}, "gzip compression failed");
  return out;
}

}  // namespace

void writeMaybeGzip(const std::string& path, const std::string& text) {
  const bool gz = path.size() > 3 && path.compare(path.size() - 3, 3, ".gz") == 0;
  writeFileAtomic(path, gz ? gzip(text, path) : text);
}

}  // namespace viscera::io
