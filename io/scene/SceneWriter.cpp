#include "io/scene/SceneWriter.h"

#include <pugixml.hpp>
#include <sstream>

#include "core/Files.h"

namespace viscera::io {

namespace {

// "--" may not appear in an XML comment.
std::string commentText(std::string s) {
  for (size_t p = s.find("--"); p != std::string::npos; p = s.find("--", p)) s.replace(p, 2, "- -");
  return " " + s + " ";
}

void add(pugi::xml_node parent, const ElementDesc& el) {
  if (!el.comment.empty()) parent.append_child(pugi::node_comment).set_value(commentText(el.comment).c_str());
  pugi::xml_node n = parent.append_child(el.tag.c_str());
  for (const auto& a : el.attrs) n.append_attribute(a.name.c_str()).set_value(a.value.c_str());
  for (const auto& c : el.children) add(n, c);
}

}  // namespace

std::string formatScene(const SceneDesc& scene, const std::string& header) {
  pugi::xml_document doc;
  auto decl = doc.append_child(pugi::node_declaration);
  decl.append_attribute("version") = "1.0";
  if (!header.empty()) doc.append_child(pugi::node_comment).set_value(commentText(header).c_str());
  add(doc, scene.root);
  std::ostringstream out;
  doc.save(out, "    ", pugi::format_indent, pugi::encoding_utf8);
  return out.str();
}

void writeScene(const std::string& path, const SceneDesc& scene, const std::string& header) {
  writeFileAtomic(path, formatScene(scene, header));
}

}  // namespace viscera::io
