#include "core/Files.h"
#include "io/scene/SceneReader.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <pugixml.hpp>
#include <sstream>

namespace viscera::io {

namespace {

// Deeper scenes are refused rather than followed (every later stage walks the tree).
constexpr int kMaxDepth = 256;

bool blank(const char* s) {
  for (; *s; ++s)
    if (!std::isspace(static_cast<unsigned char>(*s))) return false;
  return true;
}

// Maps byte offsets to 1-based line and column.
class LineIndex {
 public:
  explicit LineIndex(const std::string& text) {
    starts_.push_back(0);
    for (size_t i = 0; i < text.size(); ++i)
      if (text[i] == '\n') starts_.push_back(i + 1);
  }
  void locate(size_t offset, int& line, int& col) const {
    auto it = std::upper_bound(starts_.begin(), starts_.end(), offset);
    size_t l = static_cast<size_t>(it - starts_.begin());
    line = static_cast<int>(l);
    col = static_cast<int>(offset - starts_[l - 1]) + 1;
  }

 private:
  std::vector<size_t> starts_;
};

struct Converter {
  const std::string& text;
  const std::string& file;
  LineIndex lines;

  SourceLoc at(size_t offset) const {
    SourceLoc loc{file, 0, 0};
    lines.locate(offset, loc.line, loc.col);
    return loc;
  }

  // pugixml's offset_debug points at the element name; step back to '<'.
  size_t elementStart(const pugi::xml_node& n) const {
    size_t o = static_cast<size_t>(n.offset_debug());
    while (o > 0 && text[o] != '<') --o;
    return o;
  }

  // Offset of attribute `name` inside the start tag that begins at `tagStart`.
  size_t attributeOffset(size_t tagStart, const std::string& name) const {
    size_t end = text.find('>', tagStart);
    if (end == std::string::npos) end = text.size();
    size_t p = tagStart;
    while (true) {
      p = text.find(name, p);
      if (p == std::string::npos || p >= end) return tagStart;
      bool leftOk = p > 0 && std::isspace(static_cast<unsigned char>(text[p - 1]));
      size_t q = p + name.size();
      while (q < end && std::isspace(static_cast<unsigned char>(text[q]))) ++q;
      if (leftOk && q < end && text[q] == '=') return p;
      p += name.size();
    }
  }

  // Text in a scene is a mistake (a '<' lost, a value outside its quotes): the elements would
  // otherwise be read without it, silently.
  void refuseText(const pugi::xml_node& c, const std::string& where) const {
    if ((c.type() == pugi::node_pcdata || c.type() == pugi::node_cdata) && !blank(c.value()))
      throw Error(at(static_cast<size_t>(std::max<ptrdiff_t>(0, c.offset_debug()))),
                  "text " + quoted(c.value()) + " " + where + ": a scene holds elements only (is a '<' missing?)");
  }

  ElementDesc convert(const pugi::xml_node& n, int depth = 0) const {
    ElementDesc el;
    el.tag = n.name();
    size_t start = elementStart(n);
    el.loc = at(start);
    if (depth > kMaxDepth) throw Error(el.loc, "elements nested more than " + std::to_string(kMaxDepth) + " deep");
    for (const auto& a : n.attributes()) {
      AttrDesc d;
      d.name = a.name();
      d.value = a.value();
      d.loc = at(attributeOffset(start, d.name));
      el.attrs.push_back(std::move(d));
    }
    for (const auto& c : n.children()) {
      if (c.type() == pugi::node_element) el.children.push_back(convert(c, depth + 1));
      else refuseText(c, "inside <" + el.tag + ">");
    }
    return el;
  }
};

}  // namespace

SceneDesc parseSceneText(const std::string& text, const std::string& file) {
  pugi::xml_document doc;
  pugi::xml_parse_result r = doc.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_utf8);
  Converter conv{text, file, LineIndex(text)};
  if (!r) {
    size_t off = r.offset < 0 ? 0 : static_cast<size_t>(r.offset);
    throw Error(conv.at(std::min(off, text.size())), std::string("malformed XML: ") + r.description());
  }
  pugi::xml_node root = doc.document_element();
  if (!root) throw Error(SourceLoc{file, 1, 1}, "the file has no XML element");
  for (const auto& c : doc.children()) {
    if (c.type() == pugi::node_element && c != root)
      throw Error(conv.at(conv.elementStart(c)), "a second root element <" + std::string(c.name()) + ">: a scene has one root <Node>");
    conv.refuseText(c, "outside the root element");
  }
  // pugixml drops text before the first and after the last element without a word.
  const size_t first = text.find('<'), last = text.rfind('>');
  for (const auto& [from, to] : {std::pair<size_t, size_t>{0, first}, {last + 1, text.size()}})
    for (size_t i = from; i < to && i < text.size(); ++i)
      if (!std::isspace(static_cast<unsigned char>(text[i])) && !(i < 3 && text.compare(0, 3, "\xEF\xBB\xBF") == 0))
        throw Error(conv.at(i), "text " + quoted(std::string_view(text).substr(i, to - i)) +
                                    " outside the root element: a scene holds elements only");
  SceneDesc desc;
  desc.file = file;
  desc.directory = std::filesystem::path(file).parent_path().string();
  desc.root = conv.convert(root);
  return desc;
}

SceneDesc readScene(const std::string& path) {
  return parseSceneText(readInputFile(path, "the scene file"), path);
}

}  // namespace viscera::io
