// Small helpers shared by the contact tests: build a scene from inline XML and run it, and the
// total contact force the pipeline applied to the tissue.
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <memory>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "core/Scene.h"
#include "io/scene/SceneReader.h"

namespace viscera::contact_test {

struct SceneRun {
  std::unique_ptr<Scene> scene;
  std::unique_ptr<Simulation> sim;
};

// `file` names the scene in messages and sets the folder relative paths (meshes) resolve against.
inline SceneRun buildRun(const std::string& xml, const std::string& file = "inline.xml") {
  SceneRun r;
  r.scene = buildScene(io::parseSceneText(xml, file));
  r.sim = std::make_unique<Simulation>(*r.scene);
  return r;
}

// Sum of the forces on the tissue over the contacts of the last step (active surface models).
inline Eigen::Vector3d contactForceOnTissue(const CollisionPipeline& pipe, const State& state) {
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  for (const SurfaceCollisionModel* s : pipe.surfaces())
    if (s->active())
      for (const Contact& c : s->contacts(state)) f += c.force;
  return f;
}

inline double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace viscera::contact_test
