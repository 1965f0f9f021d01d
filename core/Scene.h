// A built scene: the node tree with its components, the root settings, and link resolution.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "core/Component.h"
#include "core/Registry.h"
#include "core/SceneDesc.h"

namespace viscera {

class Scene {
 public:
  // Validates every element and attribute against the registry and creates the components.
  // Throws Error with file:line:col on the first problem.
  // `registry` says which components exist (builtin/Builtins.h has the built-in ones).
  static std::unique_ptr<Scene> build(const SceneDesc& desc, const Registry& registry);

  // Initialises every component (links, state, precomputation).
  void init();

  Node& root() { return *root_; }
  const Node& root() const { return *root_; }
  double dt() const { return dt_; }
  double startTime() const { return startTime_; }
  const Eigen::Vector3d& gravity() const { return gravity_; }
  const UnitSystem& units() const { return units_; }
  const std::string& file() const { return file_; }
  // A path written in the scene: relative to the scene's folder or, when it is not there, to the
  // first folder of the data search path that has it (SOFA's lookup). A file found nowhere
  // resolves against the scene's folder, so that the message names where it was expected.
  std::string resolvePath(const std::string& p) const;
  // Puts a folder (relative to the scene's) first on the data search path (SOFA's AddDataRepository).
  void addDataFolder(const std::string& folder);
  // Replaces the root's gravity (SOFA's Gravity component in the root node), in scene units.
  void setGravity(const Eigen::Vector3d& g) { gravity_ = g; }
  const std::vector<std::string>& searchPath() const { return searchPath_; }
  // Where exporters write (`--out`); relative output names resolve against it. Defaults to the
  // scene's folder.
  void setOutputDirectory(const std::string& d) { outDir_ = d; }
  std::string outputPath(const std::string& p) const;
  // Whether the output name `p` would leave the output folder set with setOutputDirectory (an
  // absolute path, or ".." climbing out of it); false when none is set.
  bool escapesOutputFolder(const std::string& p) const;
  // Notes about accepted but ignored elements and attributes.
  const std::vector<std::string>& notes() const { return notes_; }
  // Adds a note (components explain at init what they ignore or assume).
  void addNote(const std::string& n) { notes_.push_back(n); }

  // Resolves "@path" (or "path") from `from`'s node: "name", "../name", "/a/b/name", "child/name".
  // A bare name is looked up in the node, then in its ancestors. Throws with `loc` if missing.
  Component& resolve(const Component& from, const std::string& path, const SourceLoc& loc, const std::string& what);
  // Makes sure `c` is initialised (producers before consumers); detects cycles.
  void initComponent(Component& c);

  template <class T>
  std::vector<T*> all() const {
    std::vector<T*> v;
    root_->collect(v);
    return v;
  }

 private:
  std::unique_ptr<Node> root_;
  double dt_ = 0.01;
  double startTime_ = 0.0;
  Eigen::Vector3d gravity_{0, -9.81, 0};
  UnitSystem units_;
  std::string file_, dir_, outDir_;
  std::vector<std::string> searchPath_;
  std::vector<std::string> notes_;
  bool initialized_ = false;
};

// The node a link names, for SOFA's node links ("@..": the parent, "@.": this node,
// "@/root/body", "@child/"); nullptr if the path does not name a node.
const Node* linkedNode(const Node& from, const std::string& link);
// What a link attribute names: a component or, as SOFA allows, a node.
struct LinkTarget {
  Component* component = nullptr;
  const Node* node = nullptr;
};
LinkTarget linkTarget(Component& c, const std::string& attr);

// `p` relative to `dir`, else to the first folder of `searchPath` that has it (Scene::resolvePath).
std::string resolveDataPath(const std::string& p, const std::string& dir, const std::vector<std::string>& searchPath);

// Splits "@a/b/name.field" into ("a/b/name", "field"); field empty if none.
void splitLink(const std::string& link, std::string& path, std::string& field);

}  // namespace viscera
