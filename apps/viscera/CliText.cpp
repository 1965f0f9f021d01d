#include "apps/viscera/CliText.h"

#include <nlohmann/json.hpp>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "core/Error.h"
#include "core/Text.h"

namespace viscera::cli {

std::vector<std::string> words(const std::string& s) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == ',' || c == ' ' || c == '\t') {
      if (!cur.empty()) out.push_back(cur), cur.clear();
    } else {
      cur += c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

void requireParentFolder(const std::string& path, const std::string& option) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty() && !std::filesystem::is_directory(parent, ec))
    throw Error(SourceLoc{path}, option + ": the folder " + parent.string() + " does not exist");
  // What writeFileAtomic refuses, refused before the work rather than after it.
  const auto st = std::filesystem::symlink_status(path, ec);
  if (std::filesystem::is_symlink(st))
    throw Error(SourceLoc{path}, option + ": is a symbolic link, and outputs do not follow links");
  if (std::filesystem::is_directory(st)) throw Error(SourceLoc{path}, option + ": is a folder, not a file");
}

void requireNotAnInput(const std::string& path, const std::string& option, const std::vector<std::string>& inputs) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return;
  for (const auto& in : inputs)
    if (std::filesystem::equivalent(path, in, ec) && !ec)
      throw Error(SourceLoc{path}, option + ": this is an input of the command (" + in + "); it is not overwritten");
}

std::vector<double> finiteNumbers(const std::string& text, const std::string& option, size_t count, const std::string& shape) {
  const auto w = words(text);
  if (w.size() != count)
    throw Error(option + ": expected " + std::to_string(count) + " numbers \"" + shape + "\", got " + std::to_string(w.size()) +
                " in '" + text + "'");
  std::vector<double> v(count);
  for (size_t i = 0; i < count; ++i) {
    if (!parseNumber(w[i], v[i]) || !std::isfinite(v[i]))
      throw Error(option + ": '" + w[i] + "' is not a finite number");
  }
  return v;
}

std::string jsonString(const std::string& s) {
  // Bytes that are not UTF-8 (a file name from another system) are replaced, not refused.
  return nlohmann::json(s).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void printNotes(const std::vector<std::string>& notes, size_t limit) {
  for (size_t i = 0; i < notes.size() && i < limit; ++i)
    std::cerr << printable(notes[i]) << "\n";
  if (notes.size() > limit)
    std::cerr << "... and " << notes.size() - limit << " more note" << (notes.size() - limit == 1 ? "" : "s") << "\n";
}

}  // namespace viscera::cli
