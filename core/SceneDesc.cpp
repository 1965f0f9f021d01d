#include "core/SceneDesc.h"

#include <functional>

namespace viscera {

const AttrDesc* ElementDesc::find(const std::string& name) const {
  for (const auto& a : attrs)
    if (a.name == name) return &a;
  return nullptr;
}

void ElementDesc::set(const std::string& name, const std::string& value, const SourceLoc& origin) {
  for (auto& a : attrs)
    if (a.name == name) {
      a.value = value;
      if (origin.known()) a.loc = origin;
      return;
    }
  attrs.push_back({name, value, origin.known() ? origin : loc});
}

std::string ElementDesc::addressName() const {
  const AttrDesc* n = find("name");
  return n && !n->value.empty() ? n->value : tag;
}

namespace {

std::vector<std::string> splitPath(const std::string& path, bool& anchored) {
  anchored = !path.empty() && path[0] == '/';
  std::vector<std::string> parts;
  size_t start = anchored ? 1 : 0;
  while (start <= path.size()) {
    size_t e = path.find('/', start);
    if (e == std::string::npos) e = path.size();
    if (e > start) parts.push_back(path.substr(start, e - start));
    start = e + 1;
  }
  return parts;
}

// Whether the element with names `full` (root first) is addressed by `parts`.
bool addressed(const std::vector<std::string>& full, const std::vector<std::string>& parts, bool anchored) {
  auto endsWith = [&](size_t from) {
    if (parts.size() > full.size() - from) return false;
    return std::equal(parts.rbegin(), parts.rend(), full.rbegin());
  };
  if (!anchored) return endsWith(1) || (parts.size() == full.size() && endsWith(0));
  // Anchored: the whole path, with or without the root's name.
  return (parts.size() + 1 == full.size() && endsWith(1)) || (parts.size() == full.size() && endsWith(0));
}

}  // namespace

std::vector<std::pair<std::string, const ElementDesc*>> SceneDesc::matches(const std::string& path) const {
  bool anchored = false;
  const std::vector<std::string> parts = splitPath(path, anchored);
  std::vector<std::pair<std::string, const ElementDesc*>> out;
  std::vector<std::string> names;
  std::function<void(const ElementDesc&)> walk = [&](const ElementDesc& e) {
    names.push_back(names.empty() && e.find("name") == nullptr ? "root" : e.addressName());
    if (parts.empty() ? anchored && names.size() == 1 : addressed(names, parts, anchored)) {
      std::string full;
      for (size_t i = 1; i < names.size(); ++i) full += "/" + names[i];
      out.emplace_back(full.empty() ? "/" : full, &e);
    }
    for (const auto& c : e.children) walk(c);
    names.pop_back();
  };
  walk(root);
  return out;
}

const ElementDesc& SceneDesc::element(const std::string& path) const {
  auto found = matches(path);
  if (found.size() == 1) return *found.front().second;
  std::string msg;
  if (found.empty()) {
    // Candidates: elements with the same last name, else every element.
    bool anchored = false;
    auto parts = splitPath(path, anchored);
    auto near = parts.empty() ? found : matches(parts.back());
    if (near.empty()) near = matches("/");
    std::function<void(const ElementDesc&, const std::string&)> all = [&](const ElementDesc& e, const std::string& p) {
      for (const auto& c : e.children) {
        near.emplace_back(p + "/" + c.addressName(), &c);
        all(c, p + "/" + c.addressName());
      }
    };
    if (near.size() == 1 && near.front().first == "/") all(root, "");
    msg = "no element '" + path + "' in the scene";
    found = near;
  } else {
    msg = "'" + path + "' is ambiguous: give more of its path";
  }
  msg += found.size() > 1 || (found.size() == 1 && found.front().first != path) ? "; candidates:" : "";
  const size_t shown = std::min<size_t>(found.size(), 30);
  for (size_t i = 0; i < shown; ++i)
    msg += (i ? ", " : " ") + found[i].first + (found[i].second->tag == "Node" ? " (Node)" : " (" + found[i].second->tag + ")");
  if (found.size() > shown) msg += ", ... (" + std::to_string(found.size() - shown) + " more)";
  throw Error(SourceLoc{file}, msg);
}

ElementDesc& SceneDesc::element(const std::string& path) {
  return const_cast<ElementDesc&>(static_cast<const SceneDesc&>(*this).element(path));
}

std::pair<std::string, std::string> splitAddress(const std::string& address) {
  const size_t slash = address.rfind('/');
  const size_t dot = address.rfind('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash) || dot + 1 == address.size())
    throw Error("address '" + address + "' names no attribute (write path/component.attribute, e.g. phantom/fem.youngModulus)");
  return {address.substr(0, dot), address.substr(dot + 1)};
}

const AttrDesc* SceneDesc::get(const std::string& address) const {
  auto [path, attr] = splitAddress(address);
  return element(path).find(attr);
}

void SceneDesc::set(const std::string& address, const std::string& value, const SourceLoc& origin) {
  auto [path, attr] = splitAddress(address);
  if (attr == "name") throw Error("address '" + address + "': renaming an element would change the addresses of others");
  element(path).set(attr, value, origin);
}

void SceneDesc::applySetting(const std::string& assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw Error("--set " + quoted(assignment) + ": write ADDRESS=VALUE, e.g. --set phantom/fem.youngModulus=\"3.2 kPa\"");
  const std::string address = assignment.substr(0, eq);
  try {
    set(address, assignment.substr(eq + 1), SourceLoc{"--set " + address});
  } catch (const Error& e) {
    throw Error("--set " + address + ": " + e.what());
  }
}

}  // namespace viscera
