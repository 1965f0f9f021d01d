// What a learned component binds to in its scene: the body it acts on, as the rest mesh a model is
// checked against, and the instrument it follows.
#pragma once

#include "core/Component.h"
#include "learning/data/Rollout.h"

namespace viscera {

class MechanicalObject;
class SphereCollisionModel;

namespace learning {

// The body's rest mesh: its rest positions, the tetrahedra of its topology and the nodes its
// projective constraints hold. Throws `c`'s error when the body has no tetrahedra.
RestMesh boundRestMesh(Component& c, MechanicalObject& body);

// The instrument `c` follows: its `instrument` link, else the scene's only SphereCollisionModel
// (initialised). Throws `c`'s error naming the attribute otherwise.
SphereCollisionModel& boundInstrument(Component& c);

}  // namespace learning
}  // namespace viscera
