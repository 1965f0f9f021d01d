// Components and nodes of the scene graph.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/Attributes.h"
#include "core/Schema.h"

namespace viscera {

class Node;
class Scene;

// A value another component can link to with "@name.field" (indices, positions, ...).
struct FieldValue {
  std::vector<double> values;
};

// What a factory receives: the validated attributes and where the component lives.
class BuildContext {
 public:
  BuildContext(const ComponentSpec& spec, Attributes attrs, Node& node, Scene& scene, std::string name)
      : spec_(spec), attrs_(std::move(attrs)), node_(node), scene_(scene), name_(std::move(name)) {}
  const std::string& name() const { return name_; }
  const ComponentSpec& spec() const { return spec_; }
  Attributes& attrs() { return attrs_; }
  Node& node() const { return node_; }
  Scene& scene() const { return scene_; }

 private:
  const ComponentSpec& spec_;
  Attributes attrs_;
  Node& node_;
  Scene& scene_;
  std::string name_;
};

class Component {
 public:
  explicit Component(BuildContext& ctx);
  virtual ~Component() = default;
  Component(const Component&) = delete;
  Component& operator=(const Component&) = delete;

  const std::string& name() const { return name_; }
  const std::string& typeName() const { return spec_.name; }
  const ComponentSpec& spec() const { return spec_; }
  const SourceLoc& loc() const { return attrs_.componentLoc(); }
  Node& node() const { return node_; }
  Scene& scene() const { return scene_; }
  const Attributes& attrs() const { return attrs_; }

  // Resolves links, allocates state and precomputes. Called once, producers before consumers
  // (a component asks for another's init through Scene::initComponent when it links to it).
  virtual void init() {}
  bool initialized() const { return initState_ == 2; }

  // Named outputs for "@name.field" links; false if there is no such field.
  virtual bool field(const std::string& name, FieldValue& out) const { return false; }

  // An input error about one of this component's attributes.
  Error error(const std::string& attr, const std::string& msg) const { return attrs_.error(attr, msg); }
  // An input error about the component as a whole.
  Error error(const std::string& msg) const { return Error(loc(), spec_.name + " '" + name_ + "': " + msg); }

  // Linked numeric attribute: the scene value, or the linked component's field, checked
  // against the attribute's declaration.
  std::vector<double> linkedReals(const std::string& attr);
  std::vector<int> linkedInts(const std::string& attr);
  // A component linked by attribute `attr` ("@name"), or nullptr if unset.
  Component* linkedComponent(const std::string& attr);

 protected:
  Attributes attrs_;

 private:
  friend class Scene;
  const ComponentSpec& spec_;
  std::string name_;
  Node& node_;
  Scene& scene_;
  int initState_ = 0;  // 0 not started, 1 in progress (cycle detection), 2 done
};

class Node {
 public:
  Node(std::string name, Node* parent, SourceLoc loc) : name_(std::move(name)), parent_(parent), loc_(std::move(loc)) {}
  const std::string& name() const { return name_; }
  Node* parent() const { return parent_; }
  const SourceLoc& loc() const { return loc_; }
  const std::vector<std::unique_ptr<Node>>& children() const { return children_; }
  const std::vector<std::unique_ptr<Component>>& components() const { return components_; }
  Node& addChild(std::string name, SourceLoc loc);
  Component& addComponent(std::unique_ptr<Component> c);
  // An object element this node skips (SOFA-only or visual), kept so that SOFA's positional
  // links ("@[-1]": the object just before) count the node's objects as written.
  void addSkippedObject(std::string tag) { objects_.push_back({std::move(tag), nullptr}); }
  // The node's object elements in the order written: their tags and components (null if skipped).
  const std::vector<std::pair<std::string, Component*>>& objects() const { return objects_; }
  std::string path() const;  // "/root/Beam"
  // An inactive node (`activated="false"`) is built and validated but not simulated: it and its
  // sub-nodes are left out of every role lookup and of init.
  bool active() const { return active_; }
  void setActive(bool a) { active_ = a; }
  // Whether this node and all its ancestors are active.
  bool activeInTree() const {
    for (const Node* n = this; n; n = n->parent_)
      if (!n->active_) return false;
    return true;
  }

  // The first component of role T in this node, or nullptr.
  template <class T>
  T* find() const {
    for (const auto& c : components_)
      if (auto* t = dynamic_cast<T*>(c.get())) return t;
    return nullptr;
  }
  // The last component of role T in this node or, failing that, the nearest ancestor; as SOFA's
  // context lookup, where a later component of the same role takes the slot.
  template <class T>
  T* findInContext() const {
    for (const Node* n = this; n; n = n->parent_) {
      for (auto it = n->components_.rbegin(); it != n->components_.rend(); ++it)
        if (auto* t = dynamic_cast<T*>(it->get())) return t;
    }
    return nullptr;
  }
  // Every component of role T in this node and its active descendants, depth first.
  template <class T>
  void collect(std::vector<T*>& out) const {
    if (!active_) return;
    for (const auto& c : components_)
      if (auto* t = dynamic_cast<T*>(c.get())) out.push_back(t);
    for (const auto& ch : children_) ch->collect(out);
  }

 private:
  std::string name_;
  Node* parent_;
  SourceLoc loc_;
  std::vector<std::unique_ptr<Node>> children_;
  std::vector<std::unique_ptr<Component>> components_;
  std::vector<std::pair<std::string, Component*>> objects_;
  bool active_ = true;
};

}  // namespace viscera
