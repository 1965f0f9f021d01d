#include "core/Files.h"
#include "core/Scene.h"
#include "io/scene/SceneReader.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <pugixml.hpp>
#include <sstream>

namespace viscera::io {

namespace {

// Deeper scenes are refused rather than followed (every later stage walks the tree).
constexpr int kMaxDepth = 256;
// Includes nested deeper than this are refused (a file that includes itself through others).
constexpr int kMaxIncludeDepth = 16;

std::mutex dataPathMutex;
std::vector<std::string>& givenDataPath() {
  static std::vector<std::string> folders;
  return folders;
}

// What the files of one scene share while they are read: the search path for includes, the
// chain of files being included (to refuse cycles) and the notes.
struct ReadContext {
  std::vector<std::string> searchPath;
  std::vector<std::string> includeChain;
  std::vector<std::string> notes;
  long long elements = 0;  // across all files, against kMaxElements
};

// A scene may hold at most this many elements once its includes are expanded (a file that
// includes another many times, several levels deep, multiplies them).
constexpr long long kMaxElements = 1'000'000;

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

ElementDesc parseRoot(const std::string& text, const std::string& file, ReadContext& rc, int depth);

// Replaces every attribute called `a.name` in `el` and below by `a` (SOFA's `node__attr`: `attr`
// in the elements named `node` only); returns how many it replaced.
int replaceAttribute(ElementDesc& el, const AttrDesc& a) {
  const size_t sep = a.name.find("__");
  const std::string attr = sep == std::string::npos ? a.name : a.name.substr(sep + 2);
  const AttrDesc* name = el.find("name");
  const bool here = sep == std::string::npos || (name && name->value == a.name.substr(0, sep));
  int n = 0;
  for (auto& mine : el.attrs)
    if (here && mine.name == attr) {
      mine.value = a.value;
      mine.loc = a.loc;
      ++n;
    }
  for (auto& c : el.children) n += replaceAttribute(c, a);
  return n;
}

// SOFA's merge of an included root named "_Merge_" into the including element: its attributes
// (but the name) set on it, each named child merged into the child of the same tag and name,
// the others added.
void mergeInto(ElementDesc& dest, ElementDesc&& src) {
  for (const AttrDesc& a : src.attrs)
    if (a.name != "name") dest.set(a.name, a.value, a.loc);
  for (ElementDesc& child : src.children) {
    const AttrDesc* name = child.find("name");
    ElementDesc* match = nullptr;
    if (name && !name->value.empty())
      for (ElementDesc& d : dest.children) {
        const AttrDesc* dn = d.find("name");
        if (d.tag == child.tag && dn && dn->value == name->value) {
          match = &d;
          break;
        }
      }
    if (match) mergeInto(*match, std::move(child));
    else dest.children.push_back(std::move(child));
  }
}

struct Converter {
  const std::string& text;
  const std::string& file;
  LineIndex lines;
  ReadContext& rc;

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
    if (++rc.elements > kMaxElements)
      throw Error(el.loc, "the scene has more than " + std::to_string(kMaxElements) + " elements with its includes expanded");
    for (const auto& a : n.attributes()) {
      AttrDesc d;
      d.name = a.name();
      d.value = a.value();
      d.loc = at(attributeOffset(start, d.name));
      el.attrs.push_back(std::move(d));
    }
    for (const auto& c : n.children()) {
      if (c.type() != pugi::node_element) {
        refuseText(c, "inside <" + el.tag + ">");
        continue;
      }
      ElementDesc child = convert(c, depth + 1);
      if (child.tag != "include") {
        el.children.push_back(std::move(child));
        continue;
      }
      ElementDesc included = include(child, depth + 1);
      const AttrDesc* name = included.find("name");
      const std::string as = included.tag == "Node" && name ? name->value : "";
      if (included.tag == "Group" || as == "Group" || as == "_Group_")
        for (auto& g : included.children) el.children.push_back(std::move(g));
      else if (as == "_Merge_")
        mergeInto(el, std::move(included));
      else
        el.children.push_back(std::move(included));
    }
    return el;
  }

  // The root element of the file an <include> names, with the include's attributes applied.
  ElementDesc include(const ElementDesc& inc, int depth) const {
    const AttrDesc* href = inc.find("href");
    if (!href || href->value.empty()) throw Error(inc.loc, "include.href: required attribute is missing (the file to include)");
    const std::string dir = std::filesystem::path(file).parent_path().string();
    const std::string path = resolveDataPath(href->value, dir, rc.searchPath);
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
      throw Error(href->loc, "include.href: '" + href->value + "' is neither in " + (dir.empty() ? "." : dir) +
                                 " nor in the data search path (" + std::to_string(rc.searchPath.size()) +
                                 " folders; --data-path and SOFA_DATA_PATH add to it)");
    const std::string canonical = std::filesystem::weakly_canonical(path, ec).string();
    if (std::find(rc.includeChain.begin(), rc.includeChain.end(), canonical) != rc.includeChain.end())
      throw Error(href->loc, "include.href: '" + path + "' includes itself (through " +
                                 std::to_string(rc.includeChain.size()) + " files)");
    if (static_cast<int>(rc.includeChain.size()) >= kMaxIncludeDepth)
      throw Error(href->loc, "include.href: includes nested more than " + std::to_string(kMaxIncludeDepth) + " deep");
    std::string text;
    try {
      text = readInputFile(path, "the included file");
    } catch (const Error& e) {
      throw Error(href->loc, std::string("include.href: ") + e.what());
    }
    rc.includeChain.push_back(canonical);
    ElementDesc root = parseRoot(text, path, rc, depth);
    rc.includeChain.pop_back();
    for (const auto& a : inc.attrs) {
      if (a.name == "href") continue;
      if (a.name == "name") {
        root.set("name", a.value, a.loc);
        continue;
      }
      if (replaceAttribute(root, a) == 0)
        rc.notes.push_back(a.loc.str() + ": note: include." + a.name + " matches no attribute written in " + path +
                           "; ignored");
    }
    return root;
  }
};

ElementDesc parseRoot(const std::string& text, const std::string& file, ReadContext& rc, int depth) {
  pugi::xml_document doc;
  pugi::xml_parse_result r = doc.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_utf8);
  Converter conv{text, file, LineIndex(text), rc};
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
  return conv.convert(root, depth);
}

}  // namespace

std::vector<std::string> dataSearchPath(const std::string& sceneFile) {
  namespace fs = std::filesystem;
  std::vector<std::string> out;
  {
    std::lock_guard<std::mutex> lock(dataPathMutex);
    out = givenDataPath();
  }
  if (const char* env = std::getenv("SOFA_DATA_PATH")) {
    std::string list = env;
    for (size_t start = 0; start <= list.size();) {
      size_t end = list.find(':', start);
      if (end == std::string::npos) end = list.size();
      if (end > start) out.push_back(list.substr(start, end - start));
      start = end + 1;
    }
  }
  std::error_code ec;
  fs::path dir = fs::absolute(fs::path(sceneFile), ec).parent_path().lexically_normal();
  for (fs::path d = dir;; d = d.parent_path()) {
    if (fs::is_directory(d / "share", ec)) {
      out.push_back((d / "share").string());
      if (fs::is_directory(d / "share" / "mesh", ec)) out.push_back((d / "share" / "mesh").string());
    }
    if (d.filename() == "examples") out.push_back(d.string());
    if (d == d.parent_path() || d.empty()) break;
  }
  return out;
}

void setDataPath(std::vector<std::string> folders) {
  std::lock_guard<std::mutex> lock(dataPathMutex);
  givenDataPath() = std::move(folders);
}

SceneDesc parseSceneText(const std::string& text, const std::string& file) {
  ReadContext rc;
  rc.searchPath = dataSearchPath(file);
  std::error_code ec;
  rc.includeChain.push_back(std::filesystem::weakly_canonical(file, ec).string());
  SceneDesc desc;
  desc.file = file;
  desc.directory = std::filesystem::path(file).parent_path().string();
  desc.root = parseRoot(text, file, rc, 0);
  desc.searchPath = std::move(rc.searchPath);
  desc.notes = std::move(rc.notes);
  return desc;
}

SceneDesc readScene(const std::string& path) {
  return parseSceneText(readInputFile(path, "the scene file"), path);
}

}  // namespace viscera::io
