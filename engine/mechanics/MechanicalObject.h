// The degrees of freedom of a deformable body: positions, velocities and rest positions (Vec3d).
#pragma once

#include <Eigen/Core>

#include "engine/Roles.h"
#include "core/State.h"
#include "core/Component.h"

namespace viscera {

class Registry;

class MechanicalObject : public Component, public Stateful {
 public:
  explicit MechanicalObject(BuildContext& ctx) : Component(ctx) {}
  void init() override;
  bool field(const std::string& name, FieldValue& out) const override;
  // Positions, velocities and the last total force, in a simulation's state; the rest and initial
  // positions belong to the model.
  struct Live : ComponentStateOf<Live> {
    Eigen::Matrix3Xd x;  // positions, 3 x #nodes
    Eigen::Matrix3Xd v;  // velocities
    Eigen::Matrix3Xd f;  // last total force (for outputs)
    void save(StateWriter& out) const override {
      out.put(x);
      out.put(v);
      out.put(f);
    }
    void load(StateReader& in) override;
  };
  std::unique_ptr<ComponentState> initialState() const override;
  Live& live(State& s) const { return stateIn<Live>(s); }
  const Live& live(const State& s) const { return stateIn<Live>(s); }
  Eigen::Matrix3Xd& x(State& s) const { return live(s).x; }
  const Eigen::Matrix3Xd& x(const State& s) const { return live(s).x; }
  Eigen::Matrix3Xd& v(State& s) const { return live(s).v; }
  const Eigen::Matrix3Xd& v(const State& s) const { return live(s).v; }

  int size() const { return static_cast<int>(x0.cols()); }
  // A mapped state: its x and v are written by `mapping` every step, not integrated. One mapping
  // per state. Force fields on it are refused unless the mapping carries them to its input.
  void setMappedBy(const Component& mapping, bool carriesForces = false);
  const Component* mappedBy() const { return mappedBy_; }

  Eigen::Matrix3Xd x0;     // rest positions
  Eigen::Matrix3Xd xInit;  // positions at the start of a simulation, 3 x #nodes
  Eigen::Matrix3Xd vInit;  // velocities at the start

 private:
  const Component* mappedBy_ = nullptr;
};

void registerMechanicalObject(Registry& r);

// Applies a component's `scale3d`, then `rotation` (degrees about x, then y, then z), then
// `translation` to points (MechanicalObject and mesh loaders declare these attributes).
void applyPlacement(const Attributes& attrs, Eigen::Matrix3Xd& points);
// Declares those three attributes (SOFA's older dx dy dz, rx ry rz and scale are read into them
// by the scene builder). `what` names the points they place.
void addPointPlacementAttributes(ComponentSpec& spec, const std::string& what);

// The MechanicalObject a component acts on: its `mstate` link if set, else the nearest in its
// context. Throws a clear error if there is none.
MechanicalObject& contextState(Component& c, const std::string& linkAttr = "mstate");
// The topology a component uses: its link `attr` if set, else the last topology in its context
// that has tetrahedra (or hexahedra if `allowHexa`). Throws if there is none.
Topology& contextTopology(Component& c, const std::string& attr = "topology", bool allowHexa = true);
// The topology with hexahedra a component uses: its link `attr` if set, else the nearest topology in
// its context that has hexahedra. Throws if there is none.
Topology& contextHexahedra(Component& c, const std::string& attr = "topology");

}  // namespace viscera
