// ParaView collections (.pvd) read with pugixml, like the scenes.
#include <pugixml.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/Error.h"
#include "io/mesh/Mesh.h"

namespace viscera::io {

std::vector<SeriesFrame> readPvd(const std::string& path) {
  namespace fs = std::filesystem;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(SourceLoc{path}, "cannot read the series file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  auto lineAt = [&](std::ptrdiff_t offset) {
    offset = std::clamp<std::ptrdiff_t>(offset, 0, static_cast<std::ptrdiff_t>(text.size()));
    return 1 + static_cast<int>(std::count(text.begin(), text.begin() + offset, '\n'));
  };
  pugi::xml_document doc;
  const pugi::xml_parse_result parsed = doc.load_buffer(text.data(), text.size());
  if (!parsed) throw Error(SourceLoc{path, lineAt(parsed.offset)}, std::string("not a readable series file: ") + parsed.description());
  const pugi::xml_node collection = doc.child("VTKFile").child("Collection");
  if (!collection) throw Error(SourceLoc{path}, "not a ParaView series: no <VTKFile><Collection>");
  const fs::path folder = fs::path(path).parent_path();
  std::vector<SeriesFrame> frames;
  for (const pugi::xml_node d : collection.children("DataSet")) {
    // offset_debug points at the element name; the '<' is just before it.
    const int line = lineAt(d.offset_debug() - 1);
    const pugi::xml_attribute time = d.attribute("timestep"), file = d.attribute("file");
    if (!file) throw Error(SourceLoc{path, line}, "<DataSet> without a file attribute");
    if (!time) throw Error(SourceLoc{path, line}, "<DataSet> without a timestep attribute");
    const std::string t = time.value();
    char* stop = nullptr;
    const double value = std::strtod(t.c_str(), &stop);
    if (t.empty() || stop != t.c_str() + t.size() || !std::isfinite(value))
      throw Error(SourceLoc{path, line}, "timestep '" + t + "' is not a finite number");
    const fs::path f(file.value());
    frames.push_back({value, (f.is_absolute() ? f : folder / f).string()});
  }
  if (frames.empty()) throw Error(SourceLoc{path}, "the series has no <DataSet> frames");
  std::stable_sort(frames.begin(), frames.end(), [](const SeriesFrame& a, const SeriesFrame& b) { return a.time < b.time; });
  for (size_t i = 1; i < frames.size(); ++i)
    if (frames[i].time == frames[i - 1].time)
      throw Error(SourceLoc{path}, "two frames at time " + std::to_string(frames[i].time) + ": " + frames[i - 1].path + " and " +
                                       frames[i].path);
  return frames;
}

}  // namespace viscera::io
