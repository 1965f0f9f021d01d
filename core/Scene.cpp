#include "core/Scene.h"
#include "core/Text.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <sstream>
#include <stdexcept>

namespace viscera {

namespace {

// Components without their own `template` attribute take the template of the state they act on;
// they check at init that it is one they support.
bool isTemplateOk(const std::string& t) {
  // SOFA writes a pair for components with a second type ("Vec3,Vec3": state and geometry).
  if (const size_t comma = t.find(','); comma != std::string::npos)
    return isTemplateOk(t.substr(0, comma)) && isTemplateOk(t.substr(comma + 1));
  return t == "Vec3d" || t == "Vec3" || t == "Vec3f" || t == "Rigid3d" || t == "Rigid3" || t == "Rigid3f";
}

// SOFA's legacy attribute names that SOFA still reads as parts of one vector attribute: the
// placement (dx dy dz, rx ry rz) and the grid's per-axis counts and bounds. A part left out keeps
// the vector's default (or the value given to the vector itself, which the parts then override).
struct LegacyParts {
  const char* target;
  const char* parts[3];
};
constexpr LegacyParts kLegacyParts[] = {
    {"translation", {"dx", "dy", "dz"}}, {"rotation", {"rx", "ry", "rz"}}, {"n", {"nx", "ny", "nz"}},
    {"min", {"xmin", "ymin", "zmin"}},   {"max", {"xmax", "ymax", "zmax"}},
};

// The element's attributes with SOFA's legacy names folded into the attributes `spec` declares:
// the parts above, and `scale` (one factor for all axes, or three) into `scale3d`.
std::vector<AttrDesc> withLegacyNames(const ElementDesc& el, const ComponentSpec& spec) {
  std::vector<AttrDesc> out = el.attrs;
  auto given = [&](const std::string& name) -> AttrDesc* {
    for (auto& a : out)
      if (a.name == name) return &a;
    return nullptr;
  };
  auto tokens = [](const std::string& text) {
    std::vector<std::string> t;
    std::istringstream in(text);
    for (std::string w; in >> w;) t.push_back(w);
    return t;
  };
  for (const auto& group : kLegacyParts) {
    const AttrSpec* target = spec.find(group.target);
    if (!target || target->count != 3 || spec.find(group.parts[0])) continue;
    std::vector<const AttrDesc*> parts;
    for (const char* p : group.parts) parts.push_back(given(p));
    if (std::none_of(parts.begin(), parts.end(), [](const AttrDesc* a) { return a != nullptr; })) continue;
    AttrDesc* whole = given(group.target);
    std::vector<std::string> value = tokens(whole ? whole->value : target->defaultValue);
    if (value.size() != 3) {
      if (whole)  // e.g. a unit after the three numbers: the parts cannot be merged into it
        throw Error(whole->loc, el.tag + "." + group.target + ": give three plain numbers when " + group.parts[0] +
                                    " " + group.parts[1] + " " + group.parts[2] + " are also given, or only one of the two forms");
      value = {"0", "0", "0"};
    }
    SourceLoc loc;
    for (int i = 0; i < 3; ++i)
      if (parts[i]) {
        const auto t = tokens(parts[i]->value);
        double number = 0;
        if (t.size() != 1 || !parseNumber(t[0], number))
          throw Error(parts[i]->loc, el.tag + "." + group.parts[i] + ": expects one number (SOFA's part of " +
                                         group.target + "), got '" + parts[i]->value + "'");
        value[i] = t[0];
        if (!loc.known()) loc = parts[i]->loc;
      }
    const std::string text = value[0] + " " + value[1] + " " + value[2];
    out.erase(std::remove_if(out.begin(), out.end(),
                             [&](const AttrDesc& a) {
                               return a.name == group.target || a.name == group.parts[0] || a.name == group.parts[1] ||
                                      a.name == group.parts[2];
                             }),
              out.end());
    out.push_back({group.target, text, loc});
  }
  // SOFA's rigid mass written whole: vertexMass="mass volume [inertia per unit mass, 9 numbers]"
  // (rows split by commas or not); the volume is not used for the motion.
  if (spec.find("inertiaMatrix"))
    if (AttrDesc* vm = given("vertexMass"); vm && vm->value.find('[') != std::string::npos) {
      const size_t open = vm->value.find('['), close = vm->value.find(']', open);
      std::string inside = vm->value.substr(open + 1, close == std::string::npos ? std::string::npos : close - open - 1);
      std::replace(inside.begin(), inside.end(), ',', ' ');
      const auto head = tokens(vm->value.substr(0, open));
      const auto inertia = tokens(inside);
      double number = 0;
      if (close == std::string::npos || head.empty() || head.size() > 2 || inertia.size() != 9 ||
          !std::all_of(head.begin(), head.end(), [&](const std::string& t) { return parseNumber(t, number); }) ||
          !tokens(vm->value.substr(close + 1)).empty())
        throw Error(vm->loc, el.tag + ".vertexMass: SOFA's rigid mass is 'mass volume [9 numbers of the inertia per unit "
                                      "mass]', got '" + vm->value + "'");
      if (given("inertiaMatrix"))
        throw Error(vm->loc, el.tag + ".vertexMass: gives an inertia matrix, and so does inertiaMatrix: give one");
      std::string matrix;
      for (const auto& t : inertia) matrix += (matrix.empty() ? "" : " ") + t;
      const SourceLoc loc = vm->loc;
      vm->value = head[0];
      out.push_back({"inertiaMatrix", matrix, loc});
    }
  if (spec.find("scale3d") && !spec.find("scale"))
    if (AttrDesc* scale = given("scale")) {
      const auto t = tokens(scale->value);
      if (given("scale3d"))
        throw Error(scale->loc, el.tag + ".scale: give either scale (SOFA's older name) or scale3d, not both");
      scale->name = "scale3d";
      if (t.size() == 1) scale->value = t[0] + " " + t[0] + " " + t[0];
    }
  return out;
}

// Parses the element's attributes against `spec` into validated values.
Attributes parseAttributes(const ElementDesc& el, const ComponentSpec& spec, const UnitSystem& units,
                           std::vector<std::string>& notes) {
  Attributes attrs(el.tag, el.loc);
  for (const auto& a : spec.attrs) {
    AttrValue v;
    v.spec = &a;
    v.text = a.defaultValue;
    v.loc = el.loc;
    if (!a.defaultValue.empty() && a.kind != AttrKind::Link) parseAttrText(a, a.defaultValue, units, v);
    attrs.values()[a.name] = std::move(v);
  }
  for (const auto& given : withLegacyNames(el, spec)) {
    const AttrSpec* a = spec.find(given.name);
    if (!a) {
      if (given.name == "name") continue;
      if (given.name == "template" && !spec.find("template")) {
        if (!isTemplateOk(given.value))
          throw Error(given.loc, el.tag + ".template: '" + given.value + "' is not supported here (Vec3d or Rigid3d)");
        continue;
      }
      if (isCosmeticAttribute(given.name)) {
        notes.push_back(given.loc.str() + ": note: " + el.tag + "." + given.name + " does not change the physics; ignored");
        continue;
      }
      std::string known;
      for (const auto& s : spec.attrs) known += (known.empty() ? "" : ", ") + s.name;
      throw Error(given.loc, el.tag + "." + given.name + ": unknown attribute (" + spec.name + " has: " + known + ")");
    }
    AttrValue& v = attrs.values()[a->name];
    if (v.set)
      throw Error(given.loc, el.tag + "." + given.name + ": given twice (also as another name of " + a->name + ")");
    v.set = true;
    v.text = given.value;
    v.loc = given.loc;
    v.nums.clear();
    v.link = false;
    try {
      if (a->kind == AttrKind::Link) {
        if (given.value.empty() || given.value[0] != '@') throw std::invalid_argument("a link must start with '@'");
        v.link = true;
      } else if (a->linkable && !given.value.empty() && given.value[0] == '@') {
        v.link = true;
      } else {
        parseAttrText(*a, given.value, units, v);
      }
    } catch (const std::invalid_argument& e) {
      throw Error(given.loc, el.tag + "." + given.name + ": " + e.what());
    }
  }
  for (const auto& a : spec.attrs)
    if (a.required && !attrs.values()[a.name].set)
      throw Error(el.loc, el.tag + "." + a.name + ": required attribute is missing");
  return attrs;
}

std::string nameOf(const ElementDesc& el, const std::string& fallback) {
  const AttrDesc* n = el.find("name");
  return n && !n->value.empty() ? n->value : fallback;
}

struct Builder {
  const Registry& registry;
  Scene& scene;
  std::vector<std::string>& notes;

  void buildNode(const ElementDesc& el, Node& node, const UnitSystem& units, bool isRoot) {
    // Node attributes (root settings are read by Scene::build).
    Attributes na = parseAttributes(el, Registry::nodeSpec(), units, notes);
    if (!isRoot) {
      if (na.isSet("units")) throw na.error("units", "only the root node may set this");
      // SOFA scenes often repeat these on sub-nodes; SOFA steps the whole scene with the root's.
      for (const char* rootsValue : {"dt", "gravity", "time"})
        if (na.isSet(rootsValue))
          notes.push_back(na.get(rootsValue).loc.str() + ": note: Node." + rootsValue + " on node '" + node.name() +
                          "' is ignored: the whole scene uses the root node's, as in SOFA");
    }
    if (!na.boolean("activated")) {
      node.setActive(false);
      notes.push_back(el.loc.str() + ": note: node '" + node.name() + "' is inactive (activated=\"false\"): it and its "
                      "sub-nodes are not simulated");
    }
    // Names given in one node must differ: a link names one component.
    std::map<std::string, const ElementDesc*> named;
    for (const auto& child : el.children) {
      if (const AttrDesc* n = child.find("name"); n && !n->value.empty()) {
        auto [it, fresh] = named.emplace(n->value, &child);
        if (!fresh)
          throw Error(n->loc, child.tag + ".name: '" + n->value + "' is already the name of the <" + it->second->tag + "> at " +
                                  it->second->loc.str() + " in this node");
      }
    }
    for (const auto& child : el.children) {
      if (child.tag == "Node") {
        Node& sub = node.addChild(nameOf(child, "Node"), child.loc);
        buildNode(child, sub, units, false);
        continue;
      }
      if (const std::string* why = registry.ignoredReason(child.tag)) {
        notes.push_back(child.loc.str() + ": note: " + child.tag + " ignored (" + *why + ")");
        node.addSkippedObject(child.tag);
        continue;
      }
      const ComponentSpec* spec = registry.find(child.tag);
      if (!spec) {
        std::string msg = "unknown component '" + child.tag + "'";
        auto s = registry.suggest(child.tag);
        if (!s.empty()) {
          msg += " (did you mean ";
          for (size_t i = 0; i < s.size(); ++i) msg += (i ? ", " : "") + s[i];
          msg += "?)";
        }
        msg += "; `viscera components` lists the supported ones";
        throw Error(child.loc, msg);
      }
      if (!spec->factory) {
        notes.push_back(child.loc.str() + ": note: " + child.tag + " ignored (" + spec->doc + ")");
        node.addSkippedObject(child.tag);
        continue;
      }
      Attributes attrs = parseAttributes(child, *spec, units, notes);
      BuildContext ctx(*spec, std::move(attrs), node, scene, nameOf(child, spec->name));
      node.addComponent(spec->factory(ctx));
    }
  }
};

}  // namespace

void splitLink(const std::string& link, std::string& path, std::string& field) {
  std::string s = !link.empty() && link[0] == '@' ? link.substr(1) : link;
  size_t slash = s.rfind('/');
  size_t dot = s.find('.', slash == std::string::npos ? 0 : slash + 1);
  // "../x" has dots that are not a field separator
  while (dot != std::string::npos && dot + 1 < s.size() && s[dot + 1] == '.') dot = s.find('.', dot + 2);
  if (dot != std::string::npos && dot > 0 && s[dot - 1] != '.') {
    path = s.substr(0, dot);
    field = s.substr(dot + 1);
  } else {
    path = s;
    field.clear();
  }
}

std::unique_ptr<Scene> Scene::build(const SceneDesc& desc, const Registry& registry) {
  auto scene = std::unique_ptr<Scene>(new Scene());
  scene->file_ = desc.file;
  scene->dir_ = desc.directory;
  scene->searchPath_ = desc.searchPath;
  scene->notes_ = desc.notes;
  const ElementDesc& rootEl = desc.root;
  if (rootEl.tag != "Node")
    throw Error(rootEl.loc, "the root element must be <Node>, got <" + rootEl.tag + ">");
  // The unit system comes first: other root values may carry units.
  if (const AttrDesc* u = rootEl.find("units")) {
    try {
      scene->units_ = UnitSystem::parse(u->value);
    } catch (const std::invalid_argument& e) {
      throw Error(u->loc, std::string("Node.units: ") + e.what());
    }
  }
  Attributes ra = parseAttributes(rootEl, Registry::nodeSpec(), scene->units_, scene->notes_);
  scene->dt_ = ra.real("dt");
  scene->startTime_ = ra.real("time");
  if (ra.isSet("gravity")) {
    const auto& g = ra.reals("gravity");
    scene->gravity_ = Eigen::Vector3d(g[0], g[1], g[2]);
  } else {
    // The default (9.81 m/s^2 along -y) is in SI; express it in the scene's units.
    scene->gravity_ = Eigen::Vector3d(0, -9.81, 0) / scene->units_.siOf(Dimension::acceleration());
  }
  scene->root_ = std::make_unique<Node>(nameOf(rootEl, "root"), nullptr, rootEl.loc);
  Builder b{registry, *scene, scene->notes_};
  b.buildNode(rootEl, *scene->root_, scene->units_, true);
  return scene;
}

std::string Scene::resolvePath(const std::string& p) const {
  return resolveDataPath(p, dir_, searchPath_);
}

void Scene::addDataFolder(const std::string& folder) {
  namespace fs = std::filesystem;
  const fs::path f(folder);
  searchPath_.insert(searchPath_.begin(), f.is_absolute() || dir_.empty() ? f.string() : (fs::path(dir_) / f).lexically_normal().string());
}

std::string resolveDataPath(const std::string& p, const std::string& dir, const std::vector<std::string>& searchPath) {
  namespace fs = std::filesystem;
  const fs::path path(p);
  if (path.is_absolute() || p.empty()) return p;
  const fs::path local = dir.empty() ? path : (fs::path(dir) / path).lexically_normal();
  std::error_code ec;
  if (fs::exists(local, ec)) return local.string();
  for (const auto& d : searchPath) {
    const fs::path candidate = (fs::path(d) / path).lexically_normal();
    if (fs::exists(candidate, ec)) return candidate.string();
  }
  return local.string();
}

std::string Scene::outputPath(const std::string& p) const {
  namespace fs = std::filesystem;
  fs::path path(p);
  if (path.is_absolute()) return p;
  const std::string& base = outDir_.empty() ? dir_ : outDir_;
  return base.empty() ? p : (fs::path(base) / path).lexically_normal().string();
}

bool Scene::escapesOutputFolder(const std::string& p) const {
  namespace fs = std::filesystem;
  if (outDir_.empty()) return false;
  const fs::path path = fs::path(p).lexically_normal();
  return path.is_absolute() || path.has_root_name() || (!path.empty() && *path.begin() == "..");
}

namespace {
void initTree(Scene& s, Node& n) {
  if (!n.active()) return;
  for (const auto& c : n.components()) s.initComponent(*c);
  for (const auto& ch : n.children()) initTree(s, *ch);
}
}  // namespace

void Scene::init() {
  if (initialized_) return;
  initTree(*this, *root_);
  initialized_ = true;
}

void Scene::initComponent(Component& c) {
  if (c.initState_ == 2) return;
  if (c.initState_ == 1) throw c.error("circular links: this component depends on itself");
  c.initState_ = 1;
  c.init();
  c.initState_ = 2;
}

Component& Scene::resolve(const Component& from, const std::string& link, const SourceLoc& loc, const std::string& what) {
  std::string path, field;
  splitLink(link, path, field);
  std::vector<std::string> parts;
  size_t start = 0;
  bool absolute = !path.empty() && path[0] == '/';
  if (absolute) start = 1;
  while (start <= path.size()) {
    size_t e = path.find('/', start);
    if (e == std::string::npos) e = path.size();
    if (e > start) parts.push_back(path.substr(start, e - start));
    start = e + 1;
  }
  auto fail = [&](const std::string& why) -> Error {
    return Error(loc, what + ": link '" + link + "': " + why);
  };
  if (parts.empty()) throw fail("empty link");
  // SOFA's positional link: "[-k]" is the object written k places before this one in its node.
  if (parts.size() == 1 && !absolute && parts[0].size() > 3 && parts[0].compare(0, 2, "[-") == 0 && parts[0].back() == ']') {
    const std::string digits = parts[0].substr(2, parts[0].size() - 3);
    if (digits.size() > 6 || digits.find_first_not_of("0123456789") != std::string::npos)
      throw fail("a positional link is [-k] with k a positive whole number");
    const long k = std::stol(digits);
    const auto& objs = from.node().objects();
    long self = -1;
    for (size_t j = 0; j < objs.size(); ++j)
      if (objs[j].second == &from) self = static_cast<long>(j);
    if (k <= 0 || self < k)
      throw fail("there are only " + std::to_string(std::max(self, 0L)) + " objects before this one in " + from.node().path());
    const auto& [tag, target] = objs[static_cast<size_t>(self - k)];
    if (!target) throw fail("it names the <" + tag + ">, which is ignored here");
    if (!target->node().activeInTree()) throw fail("it names a component in the inactive node " + target->node().path());
    return *target;
  }
  Node* node = absolute ? root_.get() : &from.node();
  // An absolute path may name the root node first.
  size_t i = 0;
  if (absolute && parts.size() > 1 && parts[0] == root_->name()) i = 1;
  bool aboveRoot = false;
  for (; i + 1 < parts.size(); ++i) {
    if (parts[i] == "..") {
      // As SOFA's lookup, ".." from the root stays at the root.
      if (!node->parent()) {
        // A link is resolved more than once (init, then the users of its target): one note.
        const std::string note = loc.str() + ": note: " + what + ": link '" + link + "' goes above the root node; taken from the root, as SOFA does";
        if (!aboveRoot && std::find(notes_.begin(), notes_.end(), note) == notes_.end()) addNote(note);
        aboveRoot = true;
        continue;
      }
      node = node->parent();
    } else if (parts[i] == ".") {
      continue;
    } else {
      Node* next = nullptr;
      for (const auto& ch : node->children())
        if (ch->name() == parts[i]) next = ch.get();
      // As SOFA's lookup, a relative path whose first node is no child of this one starts from
      // the nearest node above that has such a child.
      if (!next && i == 0 && !absolute)
        for (Node* up = node->parent(); up && !next; up = up->parent())
          for (const auto& ch : up->children())
            if (ch->name() == parts[i]) next = ch.get();
      if (!next) throw fail("no node '" + parts[i] + "' in " + node->path() + (i == 0 && !absolute ? " or above it" : ""));
      node = next;
    }
  }
  const std::string& target = parts.back();
  bool bare = parts.size() == 1 && !absolute;
  for (Node* n = node; n; n = bare ? n->parent() : nullptr) {
    for (const auto& c : n->components())
      if (c->name() == target) {
        if (!c->node().activeInTree()) throw fail("'" + target + "' is in the inactive node " + c->node().path());
        return *c;
      }
  }
  throw fail("no component named '" + target + "'" + (bare ? " in this node or its ancestors" : " in " + node->path()));
}

const Node* linkedNode(const Node& from, const std::string& link) {
  std::string path = !link.empty() && link[0] == '@' ? link.substr(1) : link;
  const Node* node = &from;
  if (!path.empty() && path[0] == '/') {
    while (node->parent()) node = node->parent();
    path.erase(0, 1);
    // An absolute path may name the root node first.
    const size_t slash = path.find('/');
    if (path.substr(0, slash) == node->name()) path.erase(0, slash == std::string::npos ? path.size() : slash + 1);
  }
  size_t start = 0;
  while (start < path.size()) {
    size_t end = path.find('/', start);
    if (end == std::string::npos) end = path.size();
    const std::string part = path.substr(start, end - start);
    start = end + 1;
    if (part.empty() || part == ".") continue;
    if (part == "..") {
      if (node->parent()) node = node->parent();  // from the root, ".." stays there (as SOFA)
    } else {
      const Node* next = nullptr;
      for (const auto& child : node->children())
        if (child->name() == part) next = child.get();
      // As SOFA's context lookup, a leading name that is no child may name this node or one above.
      if (!next && start - part.size() - 1 == 0 && path[0] != '/')
        for (const Node* up = node; up && !next; up = up->parent())
          if (up->name() == part) next = up;
      node = next;
    }
    if (!node) return nullptr;
  }
  return node;
}

LinkTarget linkTarget(Component& c, const std::string& attr) {
  const AttrValue& v = c.attrs().get(attr);
  try {
    return {&c.scene().resolve(c, v.text, v.loc, c.attrs().component() + "." + attr), nullptr};
  } catch (const Error&) {
    if (const Node* n = linkedNode(c.node(), v.text)) return {nullptr, n};
    throw;
  }
}


}  // namespace viscera
