// Declarations of the collision components (models, pipeline, intersection, response).
#include "engine/collision/Collision.h"
#include "core/Registry.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"

namespace viscera {

namespace {

void addSofaModelFlags(ComponentSpec& s) {
  s.add(AttrSpec::ints("group").help("collision group (accepted for SOFA scenes; instruments and tissue always collide)"));
  s.add(AttrSpec::boolean("moving").def("true").help("accepted for SOFA scenes; no effect"));
  s.add(AttrSpec::boolean("simulated").def("true").help("accepted for SOFA scenes; no effect"));
  s.add(AttrSpec::boolean("selfCollision").def("false").help("must be false: self-collision is not handled"));
  s.add(AttrSpec::real("proximity").def("0").atLeast(0).unit(Dimension::length()).help("accepted for SOFA scenes; use the intersection's contactDistance"));
}

}  // namespace

void registerCollision(Registry& r) {
  {
    ComponentSpec s;
    s.name = "SphereCollisionModel";
    s.aliases = {"SphereModel", "Sphere"};
    s.category = "collision";
    s.doc = "A sphere at the origin of a rigid body's frame (the instrument tip). On a Vec3d MechanicalObject "
            "(written after it in the node): a sphere on every node, e.g. mapped from a body's volume; those collide "
            "with nothing, so the scene may hold no other collision model.";
    s.add(AttrSpec::reals("radius").def("1").unit(Dimension::length()).help("sphere radius (one value; on a Vec3d object also one per node)"));
    s.add(AttrSpec::reals("listRadius").unit(Dimension::length()).linked().help("on a Vec3d object: one radius per node, e.g. \"@[-2].listRadius\" from a SphereLoader"));
    s.add(AttrSpec::real("contactStiffness").def("10").atLeast(0).linked().help(
        "SOFA's stiffness factor: a penalty contact's stiffness is this times the surface's, over contactDistance "
        "plus the radius (force per length in the scene's units)"));
    s.add(AttrSpec::link("mstate").help("the Rigid3d MechanicalObject (default: the one in the node)"));
    addSofaModelFlags(s);
    s.factory = [](BuildContext& c) -> std::unique_ptr<Component> {
      // The object it sits on is written before it in the node, as SOFA's context lookup expects.
      const Node& n = c.node();
      if (n.find<MechanicalObject>() && !n.find<RigidObject>()) return std::make_unique<NodeSphereCollisionModel>(c);
      return std::make_unique<SphereCollisionModel>(c);
    };
    r.add(std::move(s));
  }
  const char* docs[3][2] = {
      {"TriangleCollisionModel",
       "The boundary surface of a body's tetrahedra as contact geometry: triangle interiors, edges and vertices, each "
       "a contact only where it is the local closest feature to a sphere. Carries the penalty stiffness."},
      {"LineCollisionModel", "The edges and vertices of the boundary surface (no triangle interiors); a "
                             "TriangleCollisionModel on the same body covers it."},
      {"PointCollisionModel", "The vertices of the boundary surface; a Triangle- or LineCollisionModel on the same body "
                              "covers it. Spheres can sink between vertices by the sagitta of the vertex spacing."}};
  for (auto& d : docs) {
    ComponentSpec s;
    s.name = d[0];
    std::string base = std::string(d[0]).substr(0, std::string(d[0]).size() - std::string("CollisionModel").size());
    s.aliases = {base + "Model", base + "SetModel"};
    s.category = "collision";
    s.doc = d[1];
    s.add(AttrSpec::real("contactStiffness").def("10").atLeast(0).linked().help(
        "SOFA's stiffness factor: a penalty contact's stiffness is this times the sphere's, over contactDistance plus "
        "the sphere's radius (force per length in the scene's units)"));
    s.add(AttrSpec::real("contactDistance").def("0").atLeast(0).unit(Dimension::length()).help(
        "added to the intersection's alarm and contact distances for this surface's contacts, as in SOFA"));
    s.add(AttrSpec::link("topology").help("the topology whose boundary is the surface: tetrahedra, or hexahedra (default: the nearest in the node or above)"));
    s.add(AttrSpec::link("mstate").help("the MechanicalObject (default: the one in the node)"));
    s.add(AttrSpec::boolean("bothSide").def("false").help("accepted for SOFA scenes; the outer side is used"));
    addSofaModelFlags(s);
    s.factory = [](BuildContext& c) { return std::make_unique<SurfaceCollisionModel>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "CollisionPipeline";
    s.aliases = {"DefaultPipeline"};
    s.category = "collision";
    s.doc = "Runs collision detection every step: the instrument is moved to its end-of-step pose, a bounding-volume "
            "hierarchy over each surface (refitted every step) finds the triangles near each sphere, and the "
            "closest features become contacts. One per scene, in the root node, beside the intersection method "
            "and the response.";
    s.add(AttrSpec::integer("depth").def("6").atLeast(0).help("accepted for SOFA scenes; the hierarchy depth is automatic"));
    s.add(AttrSpec::boolean("verbose").def("false").help("accepted for SOFA scenes"));
    s.factory = [](BuildContext& c) { return std::make_unique<CollisionPipeline>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "MinProximityIntersection";
    s.aliases = {"LocalMinDistance", "NewProximityIntersection"};
    s.category = "collision";
    s.doc = "Contact distances: features closer than alarmDistance to a sphere become contacts, and the response "
            "keeps them at least contactDistance away from it. Only local-minimum features are kept, so a contact is "
            "never counted twice through neighbouring triangles. Between two bodies' surfaces, written as "
            "LocalMinDistance with a TriangleCollisionModel on both, the contacts are SOFA's: a vertex against a "
            "triangle's interior or an edge's interior, two edges at interior points, two vertices (as the bodies' "
            "Line/PointCollisionModels allow; triangles alone do not meet), each along the line between the closest "
            "points and, with the filter, only where each feature sees the other from outside its body; otherwise "
            "one contact per vertex at its closest feature, plus crossing edges.";
    s.add(AttrSpec::real("alarmDistance").def("1").above(0).unit(Dimension::length()).help("detection distance"));
    s.add(AttrSpec::real("contactDistance").def("0.5").atLeast(0).unit(Dimension::length()).help("distance kept between surfaces"));
    s.add(AttrSpec::real("angleCone").def("0").help("LocalMinDistance between surfaces: widens each validity cone (as a cosine) beyond "
                                                    "the one the faces make"));
    s.add(AttrSpec::real("coneFactor").def("0.5").help("LocalMinDistance between surfaces: how far an edge's or a vertex's validity "
                                                       "cone reaches over its faces (times the cosine of their mean normal with the face)"));
    s.add(AttrSpec::boolean("useLMDFilters").def("false").help("LocalMinDistance: SOFA leaves the validity tests to a separate filter "
                                                               "component; here that means no validity tests"));
    s.add(AttrSpec::boolean("filterIntersection").def("true").help("LocalMinDistance between surfaces: the validity tests (a feature "
                                                                   "must see the other from outside its body)"));
    s.add(AttrSpec::boolean("useSphereTriangle").def("true").help("accepted for SOFA scenes"));
    s.add(AttrSpec::boolean("usePointPoint").def("true").help("accepted for SOFA scenes"));
    s.add(AttrSpec::boolean("useLinePoint").def("true").help("accepted for SOFA scenes"));
    s.add(AttrSpec::boolean("useLineLine").def("true").help("accepted for SOFA scenes"));
    s.factory = [](BuildContext& c) { return std::make_unique<ProximityIntersection>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "DiscreteIntersection";
    s.category = "collision";
    s.doc = "Exact intersection: only surface features that overlap a sphere become contacts (alarmDistance and "
            "contactDistance 0), as SOFA's DiscreteIntersection.";
    s.factory = [](BuildContext& c) { return std::make_unique<ProximityIntersection>(c); };
    r.add(std::move(s));
  }
  {
    ComponentSpec s;
    s.name = "CollisionResponse";
    s.aliases = {"DefaultContactManager", "RuleBasedContactManager"};
    s.category = "collision";
    s.doc = "How contacts respond. PenalityContactForceField: a spring k min(gap, 0) per contact, with SOFA's "
            "stiffness from the models' contactStiffness factors (k_sphere k_surface / (contactDistance + radius) for "
            "an instrument's sphere, k1 k2 / contactDistance between two surfaces); implicit (its stiffness in the "
            "body's step) against an instrument or a fixed obstacle, held from the step start between two integrated "
            "bodies, as SOFA's interaction forces. FrictionContactConstraint: "
            "non-penetration with Coulomb friction mu, solved after the free motion (needs FreeMotionAnimationLoop, "
            "GenericConstraintSolver and a constraint correction in the tissue's node).";
    s.add(AttrSpec::choice("response", {"PenalityContactForceField", "PenaltyContactForceField", "default",
                                        "FrictionContactConstraint", "FrictionContact", "UnilateralContactConstraint"})
              .def("PenalityContactForceField")
              .help("the contact response"));
    s.add(AttrSpec::string("responseParams").def("").help("SOFA's parameters, e.g. \"mu=0.9\""));
    s.add(AttrSpec::real("mu").atLeast(0).help(
        "Coulomb friction coefficient (overrides responseParams); unless given, SOFA's: 0.8 for FrictionContactConstraint "
        "and FrictionContact, none for UnilateralContactConstraint"));
    s.add(AttrSpec::string("rules").help(
        "RuleBasedContactManager's rules, triplets \"model model response\"; one response serves every contact here, "
        "so each rule must name `response`"));
    s.factory = [](BuildContext& c) { return std::make_unique<CollisionResponse>(c); };
    r.add(std::move(s));
  }
  r.addIgnored("BruteForceBroadPhase", "the pipeline's broad phase is a bounding-volume hierarchy");
  r.addIgnored("BruteForceDetection", "the pipeline's broad phase is a bounding-volume hierarchy");
  r.addIgnored("ParallelBruteForceBroadPhase", "the pipeline's broad phase is a bounding-volume hierarchy");
  r.addIgnored("BVHNarrowPhase", "the pipeline's narrow phase is built in");
  r.addIgnored("ParallelBVHNarrowPhase", "the pipeline's narrow phase is built in");
  r.addIgnored("CollisionGroup", "every pair of collision models may collide; two integrated bodies' penalty contacts are held from the step start, as SOFA's without a group manager (their solvers are not merged)");
  r.addIgnored("DefaultCollisionGroupManager", "every pair of collision models may collide; two integrated bodies' penalty contacts are held from the step start, as SOFA's without a group manager (their solvers are not merged)");
}

}  // namespace viscera
