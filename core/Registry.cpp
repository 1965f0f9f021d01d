#include "core/Registry.h"

#include <algorithm>
#include <stdexcept>

namespace viscera {

void Registry::add(ComponentSpec spec) {
  const std::string name = spec.name;
  if (specs_.count(name) || aliases_.count(name)) throw std::logic_error("component registered twice: " + name);
  for (const auto& a : spec.aliases) aliases_[a] = name;
  specs_.emplace(name, std::move(spec));
}

void Registry::addIgnored(const std::string& tag, const std::string& why) { ignored_[tag] = why; }

const ComponentSpec* Registry::find(const std::string& tag) const {
  auto it = specs_.find(tag);
  if (it != specs_.end()) return &it->second;
  auto a = aliases_.find(tag);
  if (a != aliases_.end()) return &specs_.at(a->second);
  return nullptr;
}

const std::string* Registry::ignoredReason(const std::string& tag) const {
  auto it = ignored_.find(tag);
  return it == ignored_.end() ? nullptr : &it->second;
}

namespace {
size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (std::tolower(a[i - 1]) == std::tolower(b[j - 1]) ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}
}  // namespace

std::vector<std::string> Registry::suggest(const std::string& tag) const {
  std::vector<std::pair<size_t, std::string>> c;
  auto consider = [&](const std::string& n) {
    size_t d = editDistance(tag, n);
    if (d <= std::max<size_t>(2, n.size() / 4)) c.push_back({d, n});
  };
  for (const auto& [n, s] : specs_) consider(n);
  for (const auto& [a, n] : aliases_) consider(a);
  std::sort(c.begin(), c.end());
  std::vector<std::string> out;
  for (size_t i = 0; i < c.size() && i < 3; ++i) out.push_back(c[i].second);
  return out;
}

const ComponentSpec& Registry::nodeSpec() {
  static const ComponentSpec spec = [] {
    ComponentSpec s;
    s.name = "Node";
    s.category = "scene";
    s.doc = "A node of the scene graph. The root node carries the time step, gravity and unit system.";
    s.add(AttrSpec::string("name").def("").help("name of the node, used in links (@node/component)"));
    s.add(AttrSpec::real("dt").def("0.01").above(0).unit(Dimension::time()).help("time step (root only; a sub-node's is noted and ignored, as in SOFA)"));
    s.add(AttrSpec::reals("gravity", 3).def("0 -9.81 0").unit(Dimension::acceleration()).help("gravity vector (root only; a sub-node's is noted and ignored, as in SOFA)"));
    s.add(AttrSpec::string("units").def("m kg s").help("unit system 'length mass time' of plain numbers in the scene, e.g. \"mm g s\" (root only)"));
    s.add(AttrSpec::boolean("activated").def("true").help("inactive nodes are skipped"));
    s.add(AttrSpec::real("time").def("0").atLeast(0).unit(Dimension::time()).help("start time (root only; a sub-node's is noted and ignored)"));
    s.add(AttrSpec::boolean("animate").def("false").help("accepted for SOFA compatibility; ignored"));
    return s;
  }();
  return spec;
}

}  // namespace viscera
