// LearnedCorrection: a learned correction (learning/nn/Corrector.h) applied at the post-solve seam,
// so that mappings, exporters, cameras and scores see the corrected body. By default the mechanics
// continue from the state the solver left (the correction is put back at the next step's start), as
// the corrector was trained on uncorrected simulations; `persistent` keeps it in the state instead.
#include <algorithm>
#include <memory>

#include "core/Error.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "core/State.h"
#include "engine/Roles.h"
#include "engine/collision/Collision.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/Placement.h"
#include "engine/rigid/RigidObject.h"
#include "learning/components/Binding.h"
#include "learning/nn/Corrector.h"
#include "observation/Tissue.h"

namespace viscera {

namespace {

using learning::Corrector;
using learning::RestMesh;

class LearnedCorrection : public Component, public Correction, public Stateful {
 public:
  using Component::Component;

  void init() override {
    state_ = &contextState(*this);
    const RestMesh mesh = learning::boundRestMesh(*this, *state_);
    model_ = learning::boundModel<Corrector>(*this, mesh, state_->name());
    persistent_ = attrs_.boolean("persistent");
    sphere_ = &learning::boundInstrument(*this);
  }

  // While a correction is shown: the positions the solver left and the corrected ones.
  struct Live : ComponentStateOf<Live> {
    Eigen::Matrix3Xd solved, corrected;
    void save(StateWriter& out) const override {
      out.put(solved);
      out.put(corrected);
    }
    void load(StateReader& in) override {
      in.get(solved);
      in.get(corrected);
    }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }

  void correct(State& st, double t, int stepIndex) const override {
    Eigen::Matrix3Xd& x = state_->x(st);
    const RigidObject::Live& tool = sphere_->body().live(st);
    const Eigen::Matrix3Xd corrected = model_->correct(x, {tool.p, tool.v});
    if (!persistent_) {
      Live& live = stateIn<Live>(st);
      live.solved = x;
      live.corrected = corrected;
    }
    x = corrected;
  }

  // Takes the correction back: exactly the solver's positions when nothing changed the state since,
  // else only the correction is subtracted (what a later correction added stays).
  bool restore(State& st) const override {
    Live& live = stateIn<Live>(st);
    if (live.solved.size() == 0) return false;
    Eigen::Matrix3Xd& x = state_->x(st);
    if (x == live.corrected)
      x = live.solved;
    else
      x -= live.corrected - live.solved;
    live.solved.resize(3, 0);
    live.corrected.resize(3, 0);
    return true;
  }

 private:
  MechanicalObject* state_ = nullptr;
  SphereCollisionModel* sphere_ = nullptr;
  std::shared_ptr<const Corrector> model_;
  bool persistent_ = false;
};

}  // namespace

void registerLearnedCorrection(Registry& r) {
  ComponentSpec s;
  s.name = "LearnedCorrection";
  s.category = "correction";
  s.doc = "A learned correction (U-Net over the body's grid, dissertation 4.3) applied after each step's solve: mappings, "
          "exporters, cameras and scores see the corrected body. The model folder (viscera learn train on correction "
          "pairs) must have been trained on this body's grid and fixed nodes, in the scene's units. By default the next "
          "step starts from the solver's uncorrected state, as the corrector was trained.";
  s.add(AttrSpec::string("model").req().help("model folder (config.json, weights.pt, mesh.bin), relative to the scene"));
  s.add(AttrSpec::boolean("persistent").def("false").help("the next step starts from the corrected state"));
  s.add(AttrSpec::link("instrument").help("the instrument's SphereCollisionModel (default: the scene's only one)"));
  s.add(AttrSpec::link("mstate").help("the body (default: the MechanicalObject of the node)"));
  s.factory = [](BuildContext& c) { return std::make_unique<LearnedCorrection>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
