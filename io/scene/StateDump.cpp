#include "io/scene/StateDump.h"

#include <unistd.h>
#include <zlib.h>

#include <cstdio>
#include <filesystem>

#include "core/Error.h"

namespace viscera::io {

StateDumpWriter::StateDumpWriter(const std::string& path) : path_(path) {
  const bool gz = path.size() > 3 && path.compare(path.size() - 3, 3, ".gz") == 0;
  temporary_ = path + ".part" + std::to_string(::getpid());
  // zlib writes plain text too ("T": transparent), so one code path serves both.
  file_ = gzopen(temporary_.c_str(), gz ? "wb" : "wT");
  if (!file_) throw Error(SourceLoc{path}, "cannot write the state dump");
}

StateDumpWriter::~StateDumpWriter() {
  if (file_) {
    gzclose(static_cast<gzFile>(file_));
    std::error_code ec;
    std::filesystem::remove(temporary_, ec);
  }
}

void StateDumpWriter::append(const std::string& text) {
  if (!file_) throw Error(SourceLoc{path_}, "the state dump is already finished");
  if (!text.empty() && gzwrite(static_cast<gzFile>(file_), text.data(), static_cast<unsigned>(text.size())) == 0)
    throw Error(SourceLoc{path_}, "cannot write the state dump (disk full?)");
}

void StateDumpWriter::finish() {
  if (!file_) return;
  const int rc = gzclose(static_cast<gzFile>(file_));
  file_ = nullptr;
  std::error_code ec;
  if (rc != Z_OK) {
    std::filesystem::remove(temporary_, ec);
    throw Error(SourceLoc{path_}, "cannot write the state dump (disk full?)");
  }
  std::filesystem::rename(temporary_, path_, ec);
  if (ec) {
    std::filesystem::remove(temporary_, ec);
    throw Error(SourceLoc{path_}, "cannot put the state dump in place: " + ec.message());
  }
}

}  // namespace viscera::io
