// LearnedStepper: a learned stepper (learning/nn/Stepper.h) in place of the FEM solve of its node.
// Each step maps the body's nodes and the instrument at the step's end (drivers have set it) to the
// nodes at the step's end; velocities are the step's displacement over its length. The model steps
// frames of a fixed period, so the scene's dt must be that period.
#include <algorithm>
#include <cmath>
#include <memory>

#include "core/Error.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "core/Text.h"
#include "engine/Roles.h"
#include "engine/collision/Collision.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/Placement.h"
#include "engine/rigid/RigidObject.h"
#include "learning/components/Binding.h"
#include "learning/nn/Stepper.h"
#include "observation/Tissue.h"

namespace viscera {

namespace {

using learning::RestMesh;
using learning::Stepper;

class LearnedStepper : public Component, public OdeSolver {
 public:
  using Component::Component;

  void init() override {
    state_ = &contextState(*this);
    const RestMesh mesh = learning::boundRestMesh(*this, *state_);
    model_ = learning::boundModel<Stepper>(*this, mesh, state_->name());
    const double period = model_->framePeriod();
    if (std::abs(scene().dt() / period - 1) > 1e-6)
      throw error("model", "the model steps frames of " + formatNumber(period) + " (" + formatNumber(1 / period) +
                               " per unit time); the scene's dt is " + formatNumber(scene().dt()) +
                               ": set the root's dt to the model's frame period");

    sphere_ = &learning::boundInstrument(*this);
  }

  std::optional<Diverged> step(State& st, double t, double dt, int stepIndex) const override {
    MechanicalObject::Live& s = state_->live(st);
    const RigidObject::Live& tool = sphere_->body().live(st);
    const Eigen::Matrix3Xd next = model_->step(s.x, {tool.p, tool.v});
    if (!next.allFinite()) {
      Diverged d;
      d.step = stepIndex;
      d.time = t + dt;
      d.reason = "the learned stepper gave non-finite positions";
      d.object = state_->name();
      return d;
    }
    s.v = (next - s.x) / dt;
    s.x = next;
    return std::nullopt;
  }

 private:
  MechanicalObject* state_ = nullptr;
  SphereCollisionModel* sphere_ = nullptr;
  std::shared_ptr<const Stepper> model_;
};

}  // namespace

void registerLearnedCorrection(Registry& r);

void registerLearnedComponents(Registry& r) {
  registerLearnedCorrection(r);
  ComponentSpec s;
  s.name = "LearnedStepper";
  s.category = "solver";
  s.doc = "A learned stepper (graph U-Net, dissertation 4.4) in place of the FEM solve of its node: each step maps the "
          "body's nodes and the instrument's sphere at the step's end to the nodes at the step's end. The model folder "
          "(viscera learn train) must have been trained on this body's mesh and fixed nodes, in the scene's units; the "
          "scene's dt must be the model's frame period. Contact and force fields of the node are not used.";
  s.add(AttrSpec::string("model").req().help("model folder (config.json, weights.pt, mesh.bin), relative to the scene"));
  s.add(AttrSpec::link("instrument").help("the instrument's SphereCollisionModel (default: the scene's only one)"));
  s.add(AttrSpec::link("mstate").help("the body (default: the MechanicalObject of the node)"));
  s.factory = [](BuildContext& c) { return std::make_unique<LearnedStepper>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
