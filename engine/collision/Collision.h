// Contact between rigid spheres (the instrument) and the boundary surface of deformable bodies,
// and (penalty response) between the surfaces of two bodies.
//
// Per step: the instrument is moved to its end-of-step pose, then the pipeline finds, for each
// sphere, the surface features (triangle interiors, edges, vertices) within the alarm distance
// whose closest point is a local minimum of the distance (the sphere centre lies in the feature's
// outer Voronoi region), so that a contact is never counted twice through neighbouring triangles.
// Each contact carries barycentric weights on up to three nodes, a normal and the gap
// g = distance - radius - contactDistance, kept >= 0 by the response:
//  - penalty: f = k min(g, 0) n on the tissue, with stiffness -k w_i w_j n n^T in the implicit
//    system (the surface model is a ForceField of the tissue);
//  - constraint: non-penetration with Coulomb friction, solved after the free motion by the
//    constraint solver on the Delassus operator W = H C H^T (C from the ConstraintCorrection).
// Two bodies: each vertex of one surface is a point of radius 0 against the other's features, and
// (both with line models) crossing edges meet edge to edge; under LocalMinDistance the contacts
// are SOFA's set instead (detectLocalMinDistance). The contact on one body's feature and its
// mirror on the other's (opposite normal, same gap) are the pair's two sides. Penalty: SOFA's
// stiffness k1 k2 / contactDistance; between two integrated bodies each side's force is computed
// at the step start and held over the step (SOFA applies an interaction between two bodies'
// solvers as an external force: equal and opposite, so momentum is exchanged exactly); against a
// fixed obstacle it is implicit in the body's solve. A rigid body's side reaches it as a wrench
// (RigidMapping). Constraint: one non-penetration and friction row block per pair,
// solved with every other pair touching the same bodies (Constraint.cpp). A fixed surface (nothing
// moves its body) takes its side without moving.
#pragma once

#include <cstdint>
#include <Eigen/Core>
#include <array>
#include <initializer_list>
#include <memory>
#include <set>
#include <vector>

#include "engine/Roles.h"
#include "core/State.h"
#include "core/Component.h"

namespace viscera {

class MechanicalObject;
class RigidObject;
class SphereCollisionModel;
class SurfaceCollisionModel;

enum class Feature { Face, Edge, Vertex };

// Nodes a contact spreads over: a triangle's 3 vertices, each (on a mapped surface) a weighted
// sum of up to 8 nodes of the body (a grid cell).
constexpr int kMaxContactNodes = 24;

struct Contact {
  const SphereCollisionModel* sphere = nullptr;     // the instrument's sphere, or
  const SurfaceCollisionModel* partner = nullptr;   // the other body's surface (penalty contact of two bodies)
  int mirror = -1;                                  // then: the index of this contact's mirror in its contacts
  const SurfaceCollisionModel* surface = nullptr;
  Feature feature = Feature::Face;
  int count = 0;                    // nodes used: 3 (face), 2 (edge), 1 (vertex); more through a mapping
  std::array<int, kMaxContactNodes> nodes{};   // nodes of the body the force acts on
  std::array<double, kMaxContactNodes> w{};    // their weights (sum 1)
  Eigen::Vector3d n = Eigen::Vector3d::Zero();   // unit normal, from the tissue towards the sphere centre
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();  // tissue point at detection
  double gap0 = 0;                  // gap at detection (tissue at the step start, sphere at the step end)
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // on the tissue over the step (end-of-step value; held between two integrated bodies)
  bool active = false;              // the response applied a force
  double k = 0;                     // penalty stiffness (force per length), SOFA's k1 k2 / (d + r)

  // The tissue point sum w_i x_i for positions x.
  Eigen::Vector3d point(const Eigen::Matrix3Xd& x) const {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int k = 0; k < count; ++k) p += w[k] * x.col(nodes[k]);
    return p;
  }
  // The gap linearised about detection: g0 - n . (p(x) - p0).
  double gap(const Eigen::Matrix3Xd& x) const { return gap0 - n.dot(point(x) - p0); }
};

// How contacts respond; set by the CollisionResponse and intersection components.
struct ContactSettings {
  enum class Response { Penalty, Constraint } response = Response::Penalty;
  double alarmDistance = 1.0;
  double contactDistance = 0.5;
  double mu = 0.0;  // Coulomb friction (constraint response)
  // SOFA's LocalMinDistance: contacts between two surfaces are its set (see
  // SurfaceCollisionModel::detectLocalMinDistance), with its validity cones unless filter is off.
  bool localMinDistance = false;
  bool filter = true;
  double angleCone = 0.0, coneFactor = 0.5;
};

// A sphere on a rigid body's frame origin: SOFA's SphereCollisionModel on a Rigid3d object.
class SphereCollisionModel : public Component {
 public:
  using Component::Component;
  void init() override;
  RigidObject& body() const { return *body_; }
  double radius() const { return radius_; }
  // SOFA's contactStiffness factor of the model (10 unless given).
  double contactStiffness() const { return stiffness_; }
  Eigen::Vector3d centre(const State& s) const;

 private:
  RigidObject* body_ = nullptr;
  double radius_ = 1.0, stiffness_ = 10;
};

// Spheres on the nodes of a deformable body: SOFA's SphereCollisionModel on a Vec3d object (a
// body approximated by spheres mapped from its volume). Contact between two deformable bodies is
// not handled, so the pipeline accepts these only where they have nothing to touch: no self-
// collision, and no other collision model in the scene.
class NodeSphereCollisionModel : public Component {
 public:
  using Component::Component;
  void init() override;
  MechanicalObject& mstate() const { return *state_; }
  const std::vector<double>& radii() const { return radii_; }

 private:
  MechanicalObject* state_ = nullptr;
  std::vector<double> radii_;
};

// The boundary surface of the tetrahedra of a deformable body (SOFA's TriangleCollisionModel;
// LineCollisionModel and PointCollisionModel use the same surface with fewer features).
class SurfaceCollisionModel : public Component, public ForceField, public Stateful {
 public:
  enum class Kind { Points, Lines, Triangles };
  struct Bvh;
  using Component::Component;
  ~SurfaceCollisionModel() override;
  void init() override;
  // The contacts of the last step and their response; the bounding volumes follow the surface.
  struct Live : ComponentStateOf<Live> {
    const SurfaceCollisionModel* model = nullptr;
    bool penalty = false;
    std::vector<Contact> contacts;
    std::shared_ptr<Bvh> bvh;  // this state's own copy (see the copy constructor)
    Live() = default;
    Live(const Live& o);
    Live& operator=(const Live&) = delete;
    void save(StateWriter& out) const override;
    void load(StateReader& in) override;
  };
  std::unique_ptr<ComponentState> initialState() const override;

  Kind kind() const { return kind_; }
  // The body the contact forces act on: the node's MechanicalObject, or, when that is a mapped
  // state (SOFA's collision node under a body), the mapping's input.
  MechanicalObject& mstate() const override { return *state_; }
  // The rigid body whose surface this is (its state mapped by a RigidMapping), or null. A rigid
  // body's surface moves with it; its contacts with other bodies reach it as a wrench, and an
  // instrument's sphere touching it fails the step.
  RigidObject* rigidBody() const { return rigid_; }
  // A surface nothing integrates (SOFA's fixed obstacle: no ODE solver in its body's node, no rigid body).
  bool isStatic() const { return static_; }
  // What moves the surface: the rigid body, else the body the forces act on.
  const void* body() const { return rigid_ ? static_cast<const void*>(rigid_) : static_cast<const void*>(state_); }
  // Where the surface is: the node's MechanicalObject (mapped or not).
  const Eigen::Matrix3Xd& surfacePositions(const State& s) const;
  const MechanicalObject& surfaceState() const { return *surfaceState_; }
  // Surface vertex v where the body's nodes are in `s` (through the mapping when there is one).
  Eigen::Vector3d vertexPosition(const State& s, int v) const;
  bool actsThroughMapping() const override { return true; }
  const std::vector<std::array<int, 3>>& triangles() const { return tris_; }  // outward (right-hand rule)
  const std::vector<int>& vertices() const { return verts_; }
  // SOFA's contactStiffness factor of the model (10 unless given).
  double contactStiffness() const { return stiffness_; }
  // The model's own contactDistance, added to the intersection's for its contacts.
  double ownContactDistance() const { return ownDistance_; }
  // Inactive when another model on the same body with more features covers it.
  bool active() const { return active_; }
  void setActive(bool a) { active_ = a; }

  // The smallest distance from p to the surface's triangles (or vertices, for a point model) at
  // positions x as last fitted in `s`, if below `within`; +infinity otherwise.
  double distanceTo(const State& s, const Eigen::Vector3d& p, double within, const Eigen::Matrix3Xd& x) const;
  // Mean length of the surface's edges at rest.
  double meanEdgeLength() const { return meanEdge_; }
  // Whether penalty contact c holds its force over the step: a contact between two integrated
  // bodies (neither side a fixed obstacle). SOFA applies such an interaction, outside both bodies'
  // solvers, as an external force computed where the step starts; a contact with an instrument or
  // a fixed obstacle is in the body's implicit system instead.
  static bool explicitPair(const Contact& c) { return c.partner && c.surface->integrated() && c.partner->integrated(); }
  // Whether a solver moves the surface's body: a deformable body under an ODE solver, or a rigid
  // body with a mass, a solver in its node or above it, no driver and no prescribed velocity.
  bool integrated() const;
  // Fits the bounding-volume hierarchy of `s` to positions x; call before detect() when x changed.
  void refit(State& s, const Eigen::Matrix3Xd& x) const;
  // Contacts with `sphere` for the positions x (the tissue at the step start), as fitted.
  void detect(const State& s, const SphereCollisionModel& sphere, const Eigen::Matrix3Xd& x,
              const ContactSettings& settings, std::vector<Contact>& out) const;
  // Penalty contacts between this surface and the vertices of `other` (another body's surface):
  // for each vertex within the alarm distance, a contact on this surface's closest feature and
  // its mirror on the vertex, pushing the two apart. Both surfaces fitted to the step start.
  void detectVertices(const State& s, const SurfaceCollisionModel& other, const ContactSettings& settings,
                      std::vector<Contact>& here, std::vector<Contact>& there) const;
  // Contacts between the edges of this surface and those of `other` (SOFA's line-line proximities,
  // made where both bodies have a LineCollisionModel): a pair of edges whose closest points lie
  // inside both, within the alarm distance, each outside the other body (beyond the faces at its
  // edge), makes a contact on this edge and its mirror on the other. Catches an edge crossing a
  // thin part of another body between its vertices, which vertex contacts miss.
  void detectEdges(const State& s, const SurfaceCollisionModel& other, const ContactSettings& settings,
                   std::vector<Contact>& here, std::vector<Contact>& there) const;
  // The collision models a body carries on its surface (SOFA's TriangleCollisionModel,
  // LineCollisionModel, PointCollisionModel): which features take part in LocalMinDistance's tests.
  struct Features {
    bool lines = false, points = false;
  };
  // SOFA's LocalMinDistance between this surface and `other` (each pair of surfaces once): a vertex
  // against the interior of a triangle (both ways, where the vertex's body has a point model), a
  // vertex against the interior of an edge (both ways, line and point models), two edges at
  // interior points (line models on both) and two vertices (point models on both), each within
  // the alarm distance, along the line between the closest points, and, with the filter on, only
  // where each feature sees the other from outside its body (the faces' side, the cones around
  // edges and vertices). Unlike detectVertices, a vertex may touch several features at once.
  void detectLocalMinDistance(const State& s, const SurfaceCollisionModel& other, const ContactSettings& settings,
                              Features mine, Features theirs, std::vector<Contact>& here, std::vector<Contact>& there) const;
  // The contacts of the current step, with the response they get.
  void setContacts(State& s, std::vector<Contact> c, const ContactSettings& settings) const;
  std::vector<Contact>& contacts(State& s) const { return stateIn<Live>(s).contacts; }
  const std::vector<Contact>& contacts(const State& s) const { return stateIn<Live>(s).contacts; }

  // ForceField: penalty forces and their stiffness (nothing for the constraint response).
  void addForce(State& s, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, Eigen::Matrix3Xd& f) const override;
  void addDForce(const State& s, const Eigen::Matrix3Xd& dx, Eigen::Matrix3Xd& df, double kFactor) const override;
  void stiffnessPattern(std::vector<std::pair<int, int>>& pairs) const override;
  void addStiffness(const State& s, BlockSparseMatrix& K, double kFactor) const override;
  bool assemblesUpper() const override { return true; }  // w_a w_b k n n^T: symmetric
  bool rayleighDamped() const override { return false; }
  // Sets each contact's force from the end-of-step positions, or the force held over the step
  // between two integrated bodies (penalty response).
  void finishPenalty(State& s, const Eigen::Matrix3Xd& x) const;

 private:
  // One box per primitive (triangle, or vertex for point models) at positions x.
  void fitBoxes(const Eigen::Matrix3Xd& x, Bvh& bvh) const;
  // The contacts of a point c of radius R at positions x (as fitted): the features whose closest
  // point is a local minimum of the distance, within the alarm distance, down to `depth` inside.
  void detectAt(const State& st, const Eigen::Vector3d& c, double R, double depth, const Eigen::Matrix3Xd& x,
                const ContactSettings& s, std::vector<Contact>& out) const;
  // Appends surface vertex v with weight w to contact c (on a mapped surface: the body's nodes it follows).
  void addVertex(Contact& c, int v, double w) const;
  // The outward unit normal of triangle t at positions x.
  Eigen::Vector3d faceNormal(int t, const Eigen::Matrix3Xd& x) const;
  // The sum of the outward unit normals of the faces at edge e, or around vertex v, at positions x.
  Eigen::Vector3d edgeNormal(int e, const Eigen::Matrix3Xd& x) const;
  Eigen::Vector3d vertexNormal(int v, const Eigen::Matrix3Xd& x) const;
  // Vertices of `other` against this surface's triangles and edges (one direction of
  // detectLocalMinDistance); vertex contacts go to `there`, their features' to `here`.
  void localMinVertices(const State& st, const SurfaceCollisionModel& other, const ContactSettings& s, Features mine,
                        Features theirs, std::vector<Contact>& here, std::vector<Contact>& there) const;
  // Appends a contact on this surface's feature (its vertices and weights) and its mirror on the
  // other's, the normal n pointing from here to there, the features `dist` apart.
  void addPair(const State& st, const SurfaceCollisionModel& other, const ContactSettings& s, Feature fa,
               std::initializer_list<std::pair<int, double>> a, Feature fb, std::initializer_list<std::pair<int, double>> b,
               const Eigen::Vector3d& n, double dist, std::vector<Contact>& here, std::vector<Contact>& there) const;
  // LocalMinDistance's validity tests: whether the feature sees the other feature, in direction d
  // from its closest point, from outside its body.
  bool vertexSees(const Eigen::Matrix3Xd& x, int v, const Eigen::Vector3d& d, const ContactSettings& s, bool lines) const;
  bool edgeSees(const Eigen::Matrix3Xd& x, int e, const Eigen::Vector3d& d, const ContactSettings& s) const;
  bool triangleSees(const Eigen::Matrix3Xd& x, int t, const Eigen::Vector3d& d, const ContactSettings& s) const;
  // Where the surface comes from: the `topology` link, else the nearest node's topology.
  Component& surfaceSource();
  void checkNodes(const int* nodes, Eigen::Index count, Eigen::Index size) const;
  MechanicalObject* state_ = nullptr;         // receives the forces
  MechanicalObject* surfaceState_ = nullptr;  // carries the surface
  RigidObject* rigid_ = nullptr;              // the rigid body it is on, if any
  bool static_ = false;
  bool solverAbove_ = false;  // a rigid body's: an ODE solver in its node or above it
  // Per surface vertex, the body's nodes and weights it is mapped from (empty: the same nodes).
  std::vector<std::vector<std::pair<int, double>>> vertexMap_;
  Kind kind_ = Kind::Triangles;
  bool active_ = true;
  double stiffness_ = 0, ownDistance_ = 0;
  std::vector<std::array<int, 3>> tris_;
  std::vector<int> verts_;
  std::vector<std::array<int, 2>> edges_;          // surface edges (a < b)
  double meanEdge_ = 0;
  std::vector<std::array<int, 3>> triEdges_;       // per triangle: edge ids of (v0v1, v1v2, v2v0)
  std::vector<std::vector<int>> edgeTris_;         // per edge: adjacent triangles
  std::vector<std::vector<int>> vertexNeighbours_; // per node: surface neighbours (empty off the surface)
  std::vector<std::vector<int>> vertexTris_;       // per node: the triangles around it
  std::shared_ptr<const Bvh> bvh0_;  // the hierarchy built on the rest surface
};

// SOFA's MinProximityIntersection / LocalMinDistance: the alarm and contact distances.
class ProximityIntersection : public Component {
 public:
  using Component::Component;
  void init() override;
  double alarmDistance = 1.0, contactDistance = 0.5;
  // LocalMinDistance (the tag as written) and its filter settings.
  bool localMinDistance = false, filter = true;
  double angleCone = 0.0, coneFactor = 0.5;
};

// SOFA's CollisionResponse (DefaultContactManager): the response and its parameters.
class CollisionResponse : public Component {
 public:
  using Component::Component;
  void init() override;
  ContactSettings::Response response = ContactSettings::Response::Penalty;
  double mu = 0.0;
};

// One step's collision handling for the whole scene: SOFA's CollisionPipeline (DefaultPipeline)
// with its broad phase, narrow phase, intersection method and response.
class CollisionPipeline : public Component, public Stateful {
 public:
  using Component::Component;
  void init() override;
  // Contact statistics over the run so far.
  struct Live : ComponentStateOf<Live> {
    double lastPenetration = -1e300, maxPenetration = -1e300;
    int maxContacts = 0;
    void save(StateWriter& out) const override {
      out.put(lastPenetration);
      out.put(maxPenetration);
      out.put(maxContacts);
    }
    void load(StateReader& in) override {
      in.get(lastPenetration);
      in.get(maxPenetration);
      in.get(maxContacts);
    }
  };
  std::unique_ptr<ComponentState> initialState() const override { return std::make_unique<Live>(); }
  const ContactSettings& settings() const { return settings_; }
  // Finds this step's contacts (instrument at the step end, tissue at the step start). Fails the
  // step when spheres on two deformable bodies touch (contact between them is not handled).
  std::optional<Diverged> detect(State& s, int stepIndex = 0, double t = 0) const;
  // After the solve: contact forces, the wrench on each instrument, statistics.
  void finish(State& s) const;
  const std::vector<SurfaceCollisionModel*>& surfaces() const { return surfaces_; }
  const std::vector<SphereCollisionModel*>& spheres() const { return spheres_; }
  int contactCount(const State& s) const;
  // Penalty contacts of the current step held over it between two integrated bodies, one of them
  // at or below `under` (a contact and its mirror counted once), and their largest stiffness (a
  // failed step names them: a held force has a stability limit).
  int heldContacts(const State& s, const Node& under, double& largestStiffness) const;
  int maxContacts(const State& s) const { return stateIn<Live>(s).maxContacts; }
  // How far a surface vertex is inside a sphere at the end of the last step (radius minus its
  // distance to the centre; <= 0 when none is inside), and the largest over all steps.
  double lastPenetration(const State& s) const { return stateIn<Live>(s).lastPenetration; }
  double maxPenetration(const State& s) const { return stateIn<Live>(s).maxPenetration; }

 private:
  ContactSettings settings_;
  std::vector<SphereCollisionModel*> spheres_;
  std::vector<SurfaceCollisionModel*> surfaces_;
  std::set<const MechanicalObject*> lines_;   // surfaces with a LineCollisionModel (edge-edge contacts)
  std::set<const MechanicalObject*> points_;  // surfaces with a PointCollisionModel (LocalMinDistance)
  std::vector<NodeSphereCollisionModel*> nodeSpheres_;  // alone in the scene: they may not touch
};

// Applies the contact constraints after the free motion (FreeMotionAnimationLoop): the role of
// GenericConstraintSolver / LCPConstraintSolver.
class ConstraintSolver {
 public:
  virtual ~ConstraintSolver() = default;
  // Corrects the states of the bodies in contact (pipeline: null in a scene without one) and of
  // those held by bilateral constraints; a failure stops the run like a divergence.
  virtual std::optional<Diverged> solve(State& s, const CollisionPipeline* pipeline, double dt, int stepIndex,
                                        double time) const = 0;
  virtual int lastIterations(const State& s) const = 0;
  virtual double lastResidual(const State& s) const = 0;
  // From now on in `s`, each step's Gauss-Seidel sweeps visit the constraints in an order drawn
  // from `seed` and the step (0: the order they were built in). Where the solve stops before it
  // converges, the result depends on that order, which SOFA sets by its own bookkeeping; this
  // measures how much (viscera sofa-suite --order-spread).
  virtual void shuffleOrder(State& s, std::uint64_t seed) const = 0;
};

}  // namespace viscera
