// A visual surface (SOFA's OglModel / VisualModel): triangles whose vertices a mapping
// (BarycentricMapping, IdentityMapping) moves with a deformable body every step. It takes no part
// in the mechanics; exporters write it (VTKExporter in its node writes a .vtp series).
#pragma once

#include <Eigen/Core>

#include "core/Component.h"
#include "core/State.h"
#include "engine/mapping/Embedding.h"

namespace viscera {

class Registry;

class VisualModel : public Component, public Stateful {
 public:
  explicit VisualModel(BuildContext& ctx) : Component(ctx) {}
  // Rest positions and triangles from one of `filename` (a surface file), `src` (a loader's
  // position and triangles), `position` with `triangles`, or, when none is given, the boundary
  // surface of the tetrahedra above (all the nodes of the MechanicalObject there, so that an
  // IdentityMapping fits). Then the placement (scale3d, rotation, translation).
  void init() override;
  // Fields for links: position (at the start), restPosition, triangles.
  bool field(const std::string& name, FieldValue& out) const override;
  // The positions in a simulation: its mapping writes them after every step, so a saved state
  // leaves them out.
  struct Live : ComponentStateOf<Live> {
    Eigen::Matrix3Xd x;
    void save(StateWriter&) const override {}
    void load(StateReader&) override {}
  };
  std::unique_ptr<ComponentState> initialState() const override {
    auto l = std::make_unique<Live>();
    l->x = x0;
    return l;
  }
  Eigen::Matrix3Xd& x(State& s) const { return stateIn<Live>(s).x; }
  const Eigen::Matrix3Xd& x(const State& s) const { return stateIn<Live>(s).x; }

  int size() const { return static_cast<int>(x0.cols()); }
  // Records the mapping that moves this surface; a second one is an error (two mappings would
  // overwrite each other's result every step).
  void setDriver(const Component& mapping);

  Eigen::Matrix3Xd x0;     // rest positions (placement applied), 3 x #vertices
  TriangleList triangles;  // 3 x #triangles, 0-based vertex indices

 private:
  void fromFile();
  void fromSource();
  void fromAttributes();
  void fromContextBoundary();
  const Component* driver_ = nullptr;
};

// The tetrahedra of the last topology with tetrahedra in node `from` or, failing that, in the
// nearest ancestor that has one (as the force fields find theirs); initialises the topologies it
// looks at. nullptr if there is none.
const TetList* tetrahedraAbove(Scene& scene, const Node& from);
// The nearest topology in `from` or above that has hexahedra (a grid), or nullptr.
const Topology* hexahedraAbove(Scene& scene, const Node& from);
// The nearest topology in `from` or above with tetrahedra or hexahedra (in one node, tetrahedra
// first), or nullptr: what a body's elements are, seen from a node under it.
const Topology* volumeAbove(Scene& scene, const Node& from);

// Checks a `template` attribute of a visual model or mapping: one or two (input,output) vector
// types of three coordinates (Vec3d, Vec3f, Vec3, ExtVec3f, ExtVec3d); SOFA's float variants run in
// double precision. Throws the component's error otherwise.
void checkVec3Template(const Component& c);

void registerVisualModel(Registry& r);

}  // namespace viscera
