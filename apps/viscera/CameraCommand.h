// `viscera camera`: see docs/user-guide.md.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/SceneDesc.h"

namespace CLI {
class App;
class Option;
}

namespace viscera {

// The depth-camera options shared by `viscera camera` and `viscera dataset make`: a scene without
// a DepthCamera gets one made from them; a scene with its own takes none of them.
class CameraOptionSet {
 public:
  CameraOptionSet();
  // Declares --position, --look-at, ... --tissue-only and --name on `cmd`.
  void declare(CLI::App& cmd);
  // Adds the DepthCamera made from the options to `desc`, or checks that none was given when the
  // scene has its own. `defaults` are attribute values used where no option was given (e.g. the
  // dataset's frame rate). Errors name the option (`--fov: DepthCamera.fov: ...`).
  void apply(SceneDesc& desc, const std::map<std::string, std::string>& defaults = {}) const;
  std::string name = "camera";
  bool tissueOnly = false;

 private:
  struct AttributeOption {
    AttributeOption(const char* f, const char* a, const char* h) : flag(f), attribute(a), help(h) {}
    const char* flag;
    const char* attribute;
    const char* help;
    CLI::Option* option = nullptr;  // set when declared
    std::string value;
  };
  std::vector<AttributeOption> attributes_;
  bool ascii_ = false;
  CLI::Option* asciiFlag_ = nullptr;
  CLI::Option* tissueFlag_ = nullptr;
  CLI::Option* nameOption_ = nullptr;
};

// Whether the description has a DepthCamera.
bool hasDepthCamera(const ElementDesc& el);

// Adds the `camera` subcommand to `app`. When it is given, parsing sets `action` to the work to
// do; the action returns the exit code and throws viscera::Error for unusable input.
void addCameraCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
