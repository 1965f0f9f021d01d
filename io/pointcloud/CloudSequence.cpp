// Sequences of cloud files: listing them (index.csv, or times from the file names) and writing
// them (frame files plus an index rewritten after each frame). No PCL here: the frames are read
// and written through readCloud / writeCloud.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/Files.h"
#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/pointcloud/CloudIo.h"
#include "core/Text.h"

namespace viscera::cloud {
namespace {

namespace fs = std::filesystem;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

// A whole-string finite number, or false.
bool parseFinite(const std::string& text, double& value) { return parseNumber(text, value) && std::isfinite(value); }


// The last number in a file name without its extension: `frame_12.5` -> "12.5",
// `cloud_000123` -> "000123", `scan2_0007` -> "0007". A '.' belongs to the number only between
// digits; a '-' is never a sign (it separates words in file names). Empty if there is no digit.
std::string lastNumber(const std::string& stem) {
  const auto lastDigit = stem.find_last_of("0123456789");
  if (lastDigit == std::string::npos) return "";
  size_t begin = lastDigit + 1;
  auto digitsBefore = [&](size_t pos) {
    while (pos > 0 && std::isdigit(static_cast<unsigned char>(stem[pos - 1]))) --pos;
    return pos;
  };
  begin = digitsBefore(begin);
  if (begin >= 2 && stem[begin - 1] == '.' && std::isdigit(static_cast<unsigned char>(stem[begin - 2])))
    begin = digitsBefore(begin - 1);
  return stem.substr(begin, lastDigit + 1 - begin);
}

std::vector<CloudFrame> readIndex(const std::string& indexPath) {
  std::ifstream in(indexPath);
  if (!in) throw Error(SourceLoc{indexPath}, "cannot open the index file");
  const fs::path folder = fs::path(indexPath).parent_path();
  std::vector<CloudFrame> frames;
  bool header = false;
  int previousLine = 0;
  std::string raw;
  for (int line = 1; std::getline(in, raw); ++line) {
    const std::string text = trim(raw);
    if (text.empty() || text[0] == '#') continue;
    auto fail = [&](const std::string& what) { throw Error(SourceLoc{indexPath, line}, what); };
    const auto comma = text.find(',');
    if (!header) {
      if (comma == std::string::npos || lower(trim(text.substr(0, comma))) != "time" ||
          lower(trim(text.substr(comma + 1))) != "file")
        fail("expected the header line 'time,file', got '" + text + "'");
      header = true;
      continue;
    }
    if (comma == std::string::npos) fail("expected 'time,file', got '" + text + "'");
    const std::string timeText = trim(text.substr(0, comma)), file = trim(text.substr(comma + 1));
    double time = 0;
    if (!parseFinite(timeText, time)) fail("time '" + timeText + "' is not a finite number");
    if (file.empty()) fail("no file name after the time");
    if (!isCloudFileName(file)) fail("'" + file + "' is not a .pcd or .ply file");
    if (!frames.empty() && !(time > frames.back().time))
      fail("time " + timeText + " is not after the time " + formatNumber(frames.back().time) + " of line " +
           std::to_string(previousLine) + " (times must increase strictly)");
    const fs::path path = fs::path(file).is_absolute() ? fs::path(file) : folder / file;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) fail("frame file '" + path.string() + "' does not exist");
    frames.push_back({time, path.string()});
    previousLine = line;
  }
  if (!header) throw Error(SourceLoc{indexPath}, "the index file is empty (expected a 'time,file' header and frame lines)");
  if (frames.empty()) throw Error(SourceLoc{indexPath}, "the index lists no frames");
  return frames;
}

std::vector<CloudFrame> framesFromNames(const std::string& folder, double nameTimeScale) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec))
    if (entry.is_regular_file() && isCloudFileName(entry.path().string())) files.push_back(entry.path().string());
  if (ec) throw Error(SourceLoc{folder}, "cannot list the folder: " + ec.message());
  if (files.empty()) throw Error(SourceLoc{folder}, "no .pcd or .ply files in the folder (and no index.csv)");
  std::sort(files.begin(), files.end());

  std::vector<CloudFrame> frames;
  for (const auto& file : files) {
    const std::string number = lastNumber(fs::path(file).stem().string());
    double value = 0;
    if (number.empty() || !parseFinite(number, value))
      throw Error(SourceLoc{file}, "no number in the file name to take the frame time from (name the files like "
                                   "frame_0.033.pcd, or add an index.csv with time,file columns)");
    frames.push_back({value * nameTimeScale, file});
  }
  std::stable_sort(frames.begin(), frames.end(), [](const CloudFrame& a, const CloudFrame& b) { return a.time < b.time; });
  for (size_t i = 1; i < frames.size(); ++i)
    if (frames[i].time == frames[i - 1].time)
      throw Error(SourceLoc{folder}, "frames " + fs::path(frames[i - 1].path).filename().string() + " and " +
                                         fs::path(frames[i].path).filename().string() + " have the same time " +
                                         formatNumber(frames[i].time) + " s (from their names)");
  return frames;
}

}  // namespace

bool isCloudFileName(const std::string& path) {
  const std::string ext = lower(fs::path(path).extension().string());
  return ext == ".pcd" || ext == ".ply";
}

std::vector<CloudFrame> listCloudSequence(const std::string& where, double nameTimeScale) {
  if (!(nameTimeScale > 0) || !std::isfinite(nameTimeScale))
    throw Error(SourceLoc{where}, "the time scale for file names must be a positive number, got " + formatNumber(nameTimeScale));
  std::error_code ec;
  if (!fs::exists(where, ec)) throw Error(SourceLoc{where}, "no such folder or index file");
  if (fs::is_directory(where, ec)) {
    const fs::path index = fs::path(where) / "index.csv";
    if (fs::exists(index, ec)) return readIndex(index.string());
    return framesFromNames(where, nameTimeScale);
  }
  if (isCloudFileName(where))
    throw Error(SourceLoc{where}, "is a single cloud file, not a sequence (give a folder or an index CSV)");
  return readIndex(where);
}

CloudSequenceWriter::CloudSequenceWriter(std::string folder, std::string prefix, std::string extension, CloudEncoding encoding)
    : folder_(std::move(folder)), prefix_(std::move(prefix)), extension_(lower(std::move(extension))), encoding_(encoding) {
  if (!extension_.empty() && extension_[0] == '.') extension_.erase(0, 1);
  if (extension_ != "pcd" && extension_ != "ply")
    throw Error(SourceLoc{folder_}, "frame files must be .pcd or .ply, not '" + extension_ + "'");
  if (prefix_.empty() || prefix_.find('/') != std::string::npos)
    throw Error(SourceLoc{folder_}, "the frame file prefix must be a plain, non-empty name, got '" + prefix_ + "'");
  std::error_code ec;
  fs::create_directories(folder_, ec);
  if (ec || !fs::is_directory(folder_)) throw Error(SourceLoc{folder_}, "cannot create the folder" + (ec ? ": " + ec.message() : ""));
}

std::string CloudSequenceWriter::add(const PointCloud& cloud, double time) {
  if (!std::isfinite(time)) throw Error(SourceLoc{folder_}, "frame time " + formatNumber(time) + " is not finite");
  if (!frames_.empty() && !(time > frames_.back().time))
    throw Error(SourceLoc{folder_}, "frame time " + formatNumber(time) + " is not after the previous frame's " +
                                        formatNumber(frames_.back().time) + " (times must increase strictly)");
  char number[16];
  std::snprintf(number, sizeof number, "%06zu", frames_.size());
  const std::string name = prefix_ + "_" + number + "." + extension_;
  const std::string path = (fs::path(folder_) / name).string();
  writeCloud(path, cloud, encoding_);
  frames_.push_back({time, path});

  std::string index = "time,file\n";
  for (const auto& f : frames_) index += formatNumber(f.time) + "," + fs::path(f.path).filename().string() + "\n";
  writeFileAtomic((fs::path(folder_) / "index.csv").string(), index);
  return path;
}

}  // namespace viscera::cloud
