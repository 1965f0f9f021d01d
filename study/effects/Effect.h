// Effects the model audit can add to a scene: each a parametrised edit of the parsed description
// (gravity, the Young's modulus, damping, ...), fitted to a dataset and kept when it explains what
// the nominal scene does not. Adding an effect is one file implementing Effect plus its line in
// Library.cpp.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/SceneDesc.h"
#include "core/Units.h"
#include "io/scene/Transform.h"
#include "study/Search.h"

namespace viscera::study {

// One fitted parameter: its range and the value that leaves the scene as it is.
struct EffectParam {
  std::string name;
  double lo = 0, hi = 1;
  double nominal = 0;
  Scale scale = Scale::Linear;
  std::string unit;  // for reports ("m/s^2", "" for a ratio)
};

// What an effect may know of the nominal scene.
struct AuditScene {
  SceneDesc desc;
  UnitSystem units;
  Eigen::AlignedBox3d tissueBox;  // the deformable bodies' rest positions
  double instrumentRadius = 0;    // the first SphereCollisionModel's (0: none)
  // The tetrahedra of each TetrahedronFEMForceField, in document order: the rest positions of
  // each element's four vertices (columns 4e .. 4e+3), in the force field's element order.
  std::vector<Eigen::Matrix3Xd> femElements;
  // Where the instrument touched the tissue in the last replay and by how much the measured force
  // exceeded the simulated one (scene force units): a stiffer region is felt where it is large.
  struct Touch {
    Eigen::Vector3d at;
    double excess = 0;
  };
  std::vector<Touch> touches;
};

class Effect {
 public:
  virtual ~Effect() = default;
  // The key the report names it by ("gravity") and a line saying what it changes.
  virtual std::string key() const = 0;
  virtual std::string what() const = 0;
  // Its parameters for this scene; empty when it does not apply (e.g. friction without friction
  // contact).
  virtual std::vector<EffectParam> params(const AuditScene& scene) const = 0;
  // Applies it with `values` (one per parameter, in their order) to `desc`, marking each element
  // it changes or adds with a comment (ElementDesc::comment).
  virtual void apply(SceneDesc& desc, const std::vector<double>& values, const AuditScene& scene) const = 0;
  // A rigid correction of the clouds (scene frame) instead of a scene edit (registration).
  virtual std::optional<RigidTransform> cloudCorrection(const std::vector<double>& values, const AuditScene& scene) const {
    return std::nullopt;
  }
  // Values that plant this effect in a ground truth at `strength` (0: none, 1: strong), for
  // `viscera audit bench`; `seed` varies it where that matters (an inclusion's place). By default
  // each parameter moves from its nominal value toward the farther end of its range (log or
  // linear) by strength / 2 of the way.
  virtual std::vector<double> plant(const AuditScene& scene, double strength, unsigned seed) const;
  // The parameters a coarse fit (the one that ranks the candidates) moves, in the order it
  // moves them, one line search each; the others keep their nominal values until the leaders are
  // refined. Empty: all of them together.
  virtual std::vector<size_t> coarseParams() const { return {}; }
  // Whether apply() changes what the scene simulates. An effect that only corrects the clouds is
  // fitted by scoring one recorded replay again, without running the scene.
  virtual bool changesSimulation() const { return true; }
};

// Every effect of the library, in report order.
std::vector<std::unique_ptr<Effect>> effectLibrary();

// Helpers for effects: the elements with a tag (SOFA aliases included), the value of a real
// attribute in scene units (its default when not written), whether an attribute is a link, and a
// number as scene text.
std::vector<ElementDesc*> elementsOf(ElementDesc& root, const std::string& tag);
std::vector<double> realsOf(const ElementDesc& el, const std::string& attribute, const UnitSystem& units);
bool isLink(const ElementDesc& el, const std::string& attribute);  // "@engine.field": set by another component
std::string numberText(double v);
void noteChange(ElementDesc& el, const std::string& effect, const std::string& what);

}  // namespace viscera::study
