// Contact geometry: the closest point on a triangle (every Voronoi region, against independent
// references), the refitted bounding-volume hierarchy (against brute force), sphere/surface
// detection on a grid block (faces, edges, vertices counted once, gaps and normals) and the
// penalty force field's derivatives (finite differences, assembled matrix).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "engine/collision/Collision.h"
#include "engine/collision/Geometry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "solvers/linear/BlockSparseMatrix.h"

using namespace viscera;
using Eigen::Vector3d;

namespace {

// ---------------------------------------------------------------------------------------------
// closestOnTriangle

// Closest point of segment [a, b] to p.
Vector3d closestOnSegment(const Vector3d& p, const Vector3d& a, const Vector3d& b) {
  const Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return a + t * ab;
}

// An independent exact reference: the projection onto the plane if it falls inside the triangle
// (barycentric coordinates by areas), else the best of the three clamped segment projections.
Vector3d referenceClosest(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const Vector3d n = (b - a).cross(c - a);
  const Vector3d q = p - n * (n.dot(p - a) / n.squaredNorm());
  const double la = n.dot((b - q).cross(c - q)), lb = n.dot((c - q).cross(a - q)), lc = n.dot((a - q).cross(b - q));
  if (la >= 0 && lb >= 0 && lc >= 0) return q;
  Vector3d best = closestOnSegment(p, a, b);
  for (const Vector3d& s : {closestOnSegment(p, b, c), closestOnSegment(p, c, a)})
    if ((p - s).squaredNorm() < (p - best).squaredNorm()) best = s;
  return best;
}

// Smallest distance from p to the points i/N a + j/N b + k/N c (i + j + k = N).
double sampledDistance(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c, int N) {
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= N; ++i)
    for (int j = 0; i + j <= N; ++j) {
      const int k = N - i - j;
      const Vector3d s = (i * a + j * b + k * c) / N;
      best = std::min(best, (p - s).norm());
    }
  return best;
}

// Any point of the triangle is within this distance of a sample of the N-grid: it lies in a
// sub-triangle of edges (edge / N) whose corners are samples, and a point of a triangle is within
// the longest edge of each corner.
double samplingSpacing(const Vector3d& a, const Vector3d& b, const Vector3d& c, int N) {
  return std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()}) / N;
}

void checkWeights(const geom::TriangleClosest& r, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const double scale = std::max({a.norm(), b.norm(), c.norm(), 1.0});
  EXPECT_NEAR(r.w[0] + r.w[1] + r.w[2], 1.0, 1e-14);
  for (double w : r.w) {
    EXPECT_GE(w, 0.0);
    EXPECT_LE(w, 1.0);
  }
  EXPECT_LE((r.w[0] * a + r.w[1] * b + r.w[2] * c - r.point).norm(), 1e-13 * scale);
}

// A scalene, obtuse triangle out of the coordinate planes, so that no region is special.
struct Tri {
  Vector3d a{0.3, -0.2, 0.1}, b{2.1, 0.4, -0.3}, c{-0.4, 1.3, 0.8};
  Vector3d normal() const { return (b - a).cross(c - a).normalized(); }
  // In-plane unit vector perpendicular to edge (u, v), pointing away from the third corner w.
  Vector3d outward(const Vector3d& u, const Vector3d& v, const Vector3d& w) const {
    Vector3d e = normal().cross(v - u).normalized();
    return e.dot(w - u) > 0 ? Vector3d(-e) : e;
  }
};

TEST(CollisionClosestOnTriangle, EveryRegionMatchesTheAnalyticAnswer) {
  const Tri T;
  const Vector3d& a = T.a;
  const Vector3d& b = T.b;
  const Vector3d& c = T.c;
  const Vector3d n = T.normal();
  struct Case {
    const char* what;
    Vector3d p, expected;
    int region;
    std::array<double, 3> w;
  };
  std::vector<Case> cases;
  for (double h : {0.0, 0.7, -1.3}) {  // on the plane, above, below
    const Vector3d g = (a + b + c) / 3;
    cases.push_back({"interior", g + h * n, g, 0, {1.0 / 3, 1.0 / 3, 1.0 / 3}});
    const Vector3d bary = 0.5 * a + 0.3 * b + 0.2 * c;
    cases.push_back({"interior off-centre", bary + h * n, bary, 0, {0.5, 0.3, 0.2}});
    // Edges: a point of the edge (not its middle) moved out of the triangle, perpendicular to it.
    cases.push_back({"edge ab", 0.75 * a + 0.25 * b + 0.6 * T.outward(a, b, c) + h * n, 0.75 * a + 0.25 * b, 1, {0.75, 0.25, 0}});
    cases.push_back({"edge bc", 0.4 * b + 0.6 * c + 0.9 * T.outward(b, c, a) + h * n, 0.4 * b + 0.6 * c, 2, {0, 0.4, 0.6}});
    cases.push_back({"edge ca", 0.3 * c + 0.7 * a + 0.2 * T.outward(c, a, b) + h * n, 0.3 * c + 0.7 * a, 3, {0.7, 0, 0.3}});
    // Vertices: away along minus the sum of the unit edge directions leaving the vertex.
    auto away = [](const Vector3d& v, const Vector3d& u, const Vector3d& w) {
      return Vector3d(-((u - v).normalized() + (w - v).normalized()).normalized());
    };
    cases.push_back({"vertex a", a + 0.5 * away(a, b, c) + h * n, a, 4, {1, 0, 0}});
    cases.push_back({"vertex b", b + 0.8 * away(b, c, a) + h * n, b, 5, {0, 1, 0}});
    cases.push_back({"vertex c", c + 1.1 * away(c, a, b) + h * n, c, 6, {0, 0, 1}});
  }
  const int N = 400;
  for (const Case& k : cases) {
    SCOPED_TRACE(k.what);
    const geom::TriangleClosest r = geom::closestOnTriangle(k.p, a, b, c);
    EXPECT_EQ(r.region, k.region);
    EXPECT_LE((r.point - k.expected).norm(), 1e-12);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(r.w[i], k.w[i], 1e-12);
    checkWeights(r, a, b, c);
    // The brute-force minimum over a fine barycentric sampling agrees to within the spacing.
    const double d = (k.p - r.point).norm(), ds = sampledDistance(k.p, a, b, c, N);
    EXPECT_LE(d, ds + 1e-12);
    EXPECT_LE(ds, d + samplingSpacing(a, b, c, N));
  }
}

TEST(CollisionClosestOnTriangle, RandomPointsMinimiseTheDistance) {
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::array<int, 7> regions{};
  const int N = 120;
  for (int trial = 0; trial < 300; ++trial) {
    // Random triangles (some obtuse, some slender), random points around them.
    const Vector3d a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    if ((b - a).cross(c - a).norm() < 1e-3) continue;
    const Vector3d p = (a + b + c) / 3 + 1.5 * Vector3d(u(rng), u(rng), u(rng));
    const geom::TriangleClosest r = geom::closestOnTriangle(p, a, b, c);
    SCOPED_TRACE(trial);
    ASSERT_GE(r.region, 0);
    ASSERT_LE(r.region, 6);
    ++regions[r.region];
    checkWeights(r, a, b, c);
    // The weights say which feature holds the point.
    const std::array<std::array<bool, 3>, 7> zero = {{{false, false, false},
                                                      {false, false, true},
                                                      {true, false, false},
                                                      {false, true, false},
                                                      {false, true, true},
                                                      {true, false, true},
                                                      {true, true, false}}};
    for (int i = 0; i < 3; ++i) {
      if (zero[r.region][i]) EXPECT_EQ(r.w[i], 0.0) << "weight " << i << " in region " << r.region;
      else EXPECT_GT(r.w[i], 0.0) << "weight " << i << " in region " << r.region;
    }
    // The exact reference: the closest point of a convex set is unique, and for any point q of the
    // triangle |p - q|^2 >= |p - q*|^2 + |q - q*|^2, so two answers exact to rounding (~1e-15)
    // coincide to ~1e-7 at worst; in practice to ~1e-14.
    const Vector3d ref = referenceClosest(p, a, b, c);
    const double d = (p - r.point).norm();
    EXPECT_NEAR(d, (p - ref).norm(), 1e-12);
    EXPECT_LE((r.point - ref).norm(), 1e-9);
    // No sample of the triangle is closer (up to rounding), and the sampled minimum exceeds the
    // true one by at most the sampling spacing (the distance is 1-Lipschitz).
    const double ds = sampledDistance(p, a, b, c, N);
    EXPECT_LE(d, ds + 1e-12);
    EXPECT_LE(ds, d + samplingSpacing(a, b, c, N));
  }
  for (int k = 0; k < 7; ++k) EXPECT_GT(regions[k], 0) << "region " << k << " never reached";
}

// ---------------------------------------------------------------------------------------------
// AabbTree

using Box = geom::AabbTree::Box;

Box randomBox(std::mt19937& rng, double extent, double maxSize) {
  std::uniform_real_distribution<double> pos(-extent, extent), size(0.0, maxSize);
  const Vector3d lo(pos(rng), pos(rng), pos(rng));
  return Box(lo, lo + Vector3d(size(rng), size(rng), size(rng)));
}

std::vector<int> treeHits(const geom::AabbTree& tree, const Box& q) {
  std::vector<int> hits;
  tree.query(q, [&](int i) { hits.push_back(i); });
  std::sort(hits.begin(), hits.end());
  return hits;  // duplicates kept: each primitive must be reported once
}

std::vector<int> bruteHits(const std::vector<Box>& boxes, const Box& q) {
  std::vector<int> hits;
  for (size_t i = 0; i < boxes.size(); ++i)
    if (boxes[i].intersects(q)) hits.push_back(static_cast<int>(i));
  return hits;
}

TEST(CollisionAabbTree, QueriesMatchBruteForceBeforeAndAfterRefit) {
  std::mt19937 rng(12345);
  for (int n : {1, 3, 4, 5, 17, 600}) {
    SCOPED_TRACE("n = " + std::to_string(n));
    std::vector<Box> boxes(n);
    for (Box& b : boxes) b = randomBox(rng, 10, 2);
    geom::AabbTree tree;
    tree.build(boxes);
    EXPECT_EQ(tree.size(), n);
    int nonEmpty = 0;
    for (int k = 0; k < 200; ++k) {
      const Box q = randomBox(rng, 11, 6);
      const auto expected = bruteHits(boxes, q);
      nonEmpty += !expected.empty();
      ASSERT_EQ(treeHits(tree, q), expected);
    }
    if (n > 100) {
      EXPECT_GT(nonEmpty, 100);
    }
    // Every box finds itself (and a box touching another only at a face counts: closed boxes).
    for (int i = 0; i < n; ++i) ASSERT_EQ(treeHits(tree, boxes[i]), bruteHits(boxes, boxes[i]));
    // Move and resize the boxes (far from where they were at build), refit, query again.
    std::uniform_real_distribution<double> shift(-8, 8), grow(0.5, 2.0);
    for (Box& b : boxes) {
      const Vector3d d(shift(rng), shift(rng), shift(rng));
      const Vector3d centre = b.center() + d, half = 0.5 * grow(rng) * b.sizes();
      b = Box(centre - half, centre + half);
    }
    tree.refit(boxes);
    for (int k = 0; k < 200; ++k) {
      const Box q = randomBox(rng, 15, 6);
      ASSERT_EQ(treeHits(tree, q), bruteHits(boxes, q));
    }
  }
}

// What detection relies on (it filters candidates by distance): every intersecting box is
// reported, and none twice. Holds whether or not the query is exact.
TEST(CollisionAabbTree, QueryReportsEveryIntersectingBoxOnce) {
  std::mt19937 rng(777);
  std::vector<Box> boxes(400);
  for (Box& b : boxes) b = randomBox(rng, 10, 2);
  geom::AabbTree tree;
  tree.build(boxes);
  for (int k = 0; k < 300; ++k) {
    const Box q = randomBox(rng, 11, 4);
    const auto hits = treeHits(tree, q);
    EXPECT_TRUE(std::adjacent_find(hits.begin(), hits.end()) == hits.end()) << "a primitive reported twice";
    const auto expected = bruteHits(boxes, q);
    EXPECT_TRUE(std::includes(hits.begin(), hits.end(), expected.begin(), expected.end())) << "query " << k;
  }
}

TEST(CollisionAabbTree, DegenerateInputs) {
  geom::AabbTree tree;
  tree.build({});
  EXPECT_EQ(tree.size(), 0);
  EXPECT_TRUE(treeHits(tree, Box(Vector3d::Constant(-1e9), Vector3d::Constant(1e9))).empty());
  // Many coincident boxes and points (zero-size boxes): median splits on equal keys.
  std::vector<Box> boxes;
  for (int i = 0; i < 300; ++i) boxes.emplace_back(Vector3d(1, 2, 3), Vector3d(1, 2, 3) + Vector3d::Constant(i % 3 == 0 ? 0.0 : 1.0));
  tree.build(boxes);
  std::vector<int> all(300);
  for (int i = 0; i < 300; ++i) all[i] = i;
  EXPECT_EQ(treeHits(tree, Box(Vector3d(1, 2, 3), Vector3d(1, 2, 3))), all);  // touching at a point
  EXPECT_EQ(treeHits(tree, Box(Vector3d(1.5, 2.5, 3.5), Vector3d(4, 4, 4))), bruteHits(boxes, Box(Vector3d(1.5, 2.5, 3.5), Vector3d(4, 4, 4))));
  EXPECT_TRUE(treeHits(tree, Box(Vector3d(2.01, 0, 0), Vector3d(5, 5, 5))).empty());
}

// ---------------------------------------------------------------------------------------------
// Detection on a grid block

// A block [0, nx-1] x [0, ny-1] x [0, nz-1] (unit cells) and `spheres` rigid spheres of radius R.
std::string blockScene(std::array<int, 3> n, int spheres, double R, double alarm, double contact,
                       const std::string& response = "") {
  std::string s = R"(<Node name="root" gravity="0 0 0" dt="0.01">
  <CollisionPipeline/>
  <MinProximityIntersection alarmDistance=")" + std::to_string(alarm) + R"(" contactDistance=")" + std::to_string(contact) + R"("/>
  <CollisionResponse)" + response + R"(/>
)";
  for (int k = 0; k < spheres; ++k)
    s += "  <Node name=\"instrument" + std::to_string(k) + "\">\n"
         "    <MechanicalObject name=\"tool" + std::to_string(k) + "\" template=\"Rigid3d\" position=\"" +
         std::to_string(0.5 + k) + " 0.5 100 0 0 0 1\"/>\n"
         "    <SphereCollisionModel name=\"tip" + std::to_string(k) + "\" radius=\"" + std::to_string(R) + "\"/>\n"
         "  </Node>\n";
  s += R"(  <Node name="block">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="50" tolerance="1e-12" threshold="1e-30"/>
    <RegularGridTopology name="grid" n=")" + std::to_string(n[0]) + " " + std::to_string(n[1]) + " " + std::to_string(n[2]) +
       R"(" min="0 0 0" max=")" + std::to_string(n[0] - 1) + " " + std::to_string(n[1] - 1) + " " + std::to_string(n[2] - 1) + R"("/>
    <MechanicalObject name="dofs"/>
    <TetrahedronSetTopologyContainer name="tetra"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tetra"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField youngModulus="1000" poissonRatio="0.3"/>
    <TriangleCollisionModel name="surface" contactStiffness="1"/>
  </Node>
</Node>
)";
  return s;
}

struct Block {
  std::unique_ptr<Scene> scene;
  std::unique_ptr<Simulation> sim;
  SurfaceCollisionModel* surface = nullptr;
  std::vector<RigidObject*> tools;
  double R = 0, alarm = 0, contact = 0;
  Eigen::Vector3d top{0, 0, 0};  // upper corner of the block

  Block(std::array<int, 3> n, int spheres, double R_, double alarm_, double contact_) : R(R_), alarm(alarm_), contact(contact_) {
    scene = buildScene(io::parseSceneText(blockScene(n, spheres, R, alarm, contact), "collision_block.xml"));
    sim = std::make_unique<Simulation>(*scene);
    auto surfaces = scene->all<SurfaceCollisionModel>();
    EXPECT_EQ(surfaces.size(), 1u);
    surface = surfaces.at(0);
    tools = scene->all<RigidObject>();
    top = Vector3d(n[0] - 1, n[1] - 1, n[2] - 1);
  }
  State& state() const { return sim->state(); }
  const Eigen::Matrix3Xd& x() const { return surface->mstate().x(state()); }
  int node(const Vector3d& at) const {
    for (int i = 0; i < x().cols(); ++i)
      if ((x().col(i) - at).norm() < 1e-12) return i;
    ADD_FAILURE() << "no node at " << at.transpose();
    return -1;
  }
  // Contacts with the first sphere centred at c.
  const std::vector<Contact>& detectAt(const Vector3d& c) {
    tools[0]->live(state()).p = c;
    for (size_t k = 1; k < tools.size(); ++k) tools[k]->live(state()).p = Vector3d(0, 0, 1e3 * (k + 1));  // out of reach
    sim->pipeline()->detect(state());
    return surface->contacts(state());
  }
};

// Weights sum to one and reproduce the detection point; normal is unit.
void checkContactInvariants(const Contact& ct, const Eigen::Matrix3Xd& x) {
  double sum = 0;
  for (int k = 0; k < ct.count; ++k) {
    sum += ct.w[k];
    EXPECT_GE(ct.w[k], 0.0);
  }
  EXPECT_NEAR(sum, 1.0, 1e-14);
  EXPECT_LE((ct.point(x) - ct.p0).norm(), 1e-13);
  EXPECT_NEAR(ct.n.norm(), 1.0, 1e-14);
  EXPECT_NEAR(ct.gap(x), ct.gap0, 1e-14);
  const int expectedCount = ct.feature == Feature::Face ? 3 : ct.feature == Feature::Edge ? 2 : 1;
  EXPECT_EQ(ct.count, expectedCount);
}

TEST(CollisionDetection, BoundaryTrianglesCountAndOrientation) {
  for (std::array<int, 3> n : {std::array<int, 3>{2, 2, 2}, std::array<int, 3>{3, 3, 3}, std::array<int, 3>{4, 3, 5}}) {
    Block b(n, 1, 0.3, 0.5, 0.1);
    const int cx = n[0] - 1, cy = n[1] - 1, cz = n[2] - 1;
    const auto& tris = b.surface->triangles();
    EXPECT_EQ(static_cast<int>(tris.size()), 4 * (cx * cy + cy * cz + cx * cz));
    const Vector3d centre = b.top / 2;
    const Eigen::Matrix3Xd& X = b.x();
    std::set<std::array<int, 3>> unique;
    for (const auto& t : tris) {
      const Vector3d p0 = X.col(t[0]), p1 = X.col(t[1]), p2 = X.col(t[2]);
      const Vector3d nrm = (p1 - p0).cross(p2 - p0);
      const Vector3d g = (p0 + p1 + p2) / 3;
      EXPECT_GT(nrm.dot(g - centre), 0.0) << "inward triangle " << t[0] << " " << t[1] << " " << t[2];
      // Each triangle lies in one face of the block, its normal along that face's axis.
      int axis;
      nrm.cwiseAbs().maxCoeff(&axis);
      EXPECT_NEAR(std::abs(nrm[axis]), nrm.norm(), 1e-12);
      EXPECT_TRUE(g[axis] == 0 || g[axis] == b.top[axis]);
      EXPECT_NEAR(nrm.norm(), 1.0, 1e-12);  // half a unit square
      std::array<int, 3> key = t;
      std::sort(key.begin(), key.end());
      EXPECT_TRUE(unique.insert(key).second);
    }
    // Surface vertices: the grid nodes on the boundary.
    const int all = n[0] * n[1] * n[2];
    const int inner = std::max(0, n[0] - 2) * std::max(0, n[1] - 2) * std::max(0, n[2] - 2);
    EXPECT_EQ(static_cast<int>(b.surface->vertices().size()), all - inner);
  }
}

TEST(CollisionDetection, SphereAboveAFaceInterior) {
  Block b({4, 4, 3}, 1, 0.3, 0.5, 0.1);
  const double z = b.top.z();
  int checked = 0;
  for (const auto& t : b.surface->triangles()) {
    const Vector3d p0 = b.x().col(t[0]), p1 = b.x().col(t[1]), p2 = b.x().col(t[2]);
    if (!(p0.z() == z && p1.z() == z && p2.z() == z)) continue;
    // Above a point of the triangle with weights (0.5, 0.3, 0.2), at height h.
    const Vector3d q = 0.5 * p0 + 0.3 * p1 + 0.2 * p2;
    for (double h : {0.35, 0.6, 0.79}) {  // within R + alarm = 0.8 (0.35: inside the contact distance)
      const auto& cs = b.detectAt(q + Vector3d(0, 0, h));
      ASSERT_EQ(cs.size(), 1u) << "h = " << h;
      const Contact& ct = cs[0];
      EXPECT_EQ(ct.feature, Feature::Face);
      ASSERT_EQ(ct.count, 3);
      EXPECT_EQ((std::array<int, 3>{ct.nodes[0], ct.nodes[1], ct.nodes[2]}), t);
      EXPECT_NEAR(ct.w[0], 0.5, 1e-14);
      EXPECT_NEAR(ct.w[1], 0.3, 1e-14);
      EXPECT_NEAR(ct.w[2], 0.2, 1e-14);
      EXPECT_LE((ct.n - Vector3d::UnitZ()).norm(), 1e-15);
      EXPECT_NEAR(ct.gap0, h - b.R - b.contact, 1e-14);
      EXPECT_LE((ct.p0 - q).norm(), 1e-14);
      EXPECT_EQ(ct.sphere, b.scene->all<SphereCollisionModel>()[0]);
      EXPECT_EQ(ct.surface, b.surface);
      checkContactInvariants(ct, b.x());
    }
    ++checked;
  }
  EXPECT_EQ(checked, 2 * 3 * 3);
}

// Over the whole top face, on a lattice that hits vertices, grid edges, diagonals and interiors
// exactly: one contact, normal +z, gap = height - R - contactDistance. At a vertex and on an
// edge several triangles share the closest point; the contact must still be counted once.
TEST(CollisionDetection, FlatTopFaceGivesExactlyOneContactEverywhere) {
  Block b({4, 4, 3}, 1, 0.3, 0.5, 0.1);
  const double z = b.top.z(), h = 0.5;
  std::map<Feature, int> features;
  std::vector<std::string> failures;
  for (int i = 1; i < 12; ++i)
    for (int j = 1; j < 12; ++j) {
      const Vector3d foot(0.25 * i, 0.25 * j, z);
      const auto& cs = b.detectAt(foot + Vector3d(0, 0, h));
      char buf[64];
      std::snprintf(buf, sizeof buf, "(%g, %g)", foot.x(), foot.y());
      const std::string where = buf;
      if (cs.size() != 1) {
        std::string kinds;
        for (const auto& c : cs) kinds += c.feature == Feature::Face ? " face" : c.feature == Feature::Edge ? " edge" : " vertex";
        failures.push_back(where + ": " + std::to_string(cs.size()) + " contacts:" + kinds);
        continue;
      }
      const Contact& ct = cs[0];
      ++features[ct.feature];
      EXPECT_LE((ct.n - Vector3d::UnitZ()).norm(), 1e-12) << where;
      EXPECT_NEAR(ct.gap0, h - b.R - b.contact, 1e-12) << where;
      EXPECT_LE((ct.p0 - foot).norm(), 1e-12) << where;
      checkContactInvariants(ct, b.x());
      // On a lattice vertex of the grid, the feature is the vertex itself.
      const bool atNode = i % 4 == 0 && j % 4 == 0;
      if (atNode) {
        EXPECT_EQ(ct.feature, Feature::Vertex) << where;
        EXPECT_EQ(ct.nodes[0], b.node(foot)) << where;
      }
    }
  for (const auto& f : failures) ADD_FAILURE() << f;
  // The lattice hits every kind of feature.
  EXPECT_GT(features[Feature::Face], 0);
  EXPECT_GT(features[Feature::Edge], 0);
  EXPECT_EQ(features[Feature::Vertex], 4);  // the four interior nodes of the 3 x 3 top face
}

TEST(CollisionDetection, SphereAboveASharedVertexAndEdge) {
  Block b({3, 3, 3}, 1, 0.3, 0.5, 0.1);
  const double h = 0.45;
  // The centre node of the top face is shared by six or eight triangles.
  const Vector3d v(1, 1, 2);
  int sharing = 0;
  const int iv = b.node(v);
  for (const auto& t : b.surface->triangles()) sharing += std::count(t.begin(), t.end(), iv);
  EXPECT_GE(sharing, 6);
  {
    const auto& cs = b.detectAt(v + Vector3d(0, 0, h));
    ASSERT_EQ(cs.size(), 1u);
    EXPECT_EQ(cs[0].feature, Feature::Vertex);
    EXPECT_EQ(cs[0].nodes[0], iv);
    EXPECT_EQ(cs[0].w[0], 1.0);
    EXPECT_LE((cs[0].n - Vector3d::UnitZ()).norm(), 1e-15);
    EXPECT_NEAR(cs[0].gap0, h - b.R - b.contact, 1e-15);
    checkContactInvariants(cs[0], b.x());
  }
  // Every edge of the top face inside it (both triangles on the top face), at a quarter of its
  // length and at its middle.
  const auto& tris = b.surface->triangles();
  std::map<std::pair<int, int>, int> topEdges;
  for (const auto& t : tris) {
    bool onTop = true;
    for (int k : t) onTop = onTop && b.x()(2, k) == 2.0;
    if (!onTop) continue;
    for (int k = 0; k < 3; ++k) ++topEdges[std::minmax(t[k], t[(k + 1) % 3])];
  }
  int inner = 0;
  for (const auto& [e, count] : topEdges) {
    if (count != 2) continue;
    ++inner;
    for (double s : {0.25, 0.5}) {
      const Vector3d foot = (1 - s) * b.x().col(e.first) + s * b.x().col(e.second);
      SCOPED_TRACE("edge " + std::to_string(e.first) + "-" + std::to_string(e.second) + " at " + std::to_string(s));
      const auto& cs = b.detectAt(foot + Vector3d(0, 0, h));
      ASSERT_EQ(cs.size(), 1u);
      const Contact& ct = cs[0];
      EXPECT_LE((ct.n - Vector3d::UnitZ()).norm(), 1e-12);
      EXPECT_NEAR(ct.gap0, h - b.R - b.contact, 1e-12);
      EXPECT_LE((ct.p0 - foot).norm(), 1e-12);
      checkContactInvariants(ct, b.x());
    }
  }
  EXPECT_GE(inner, 8);  // 4 grid edges from the centre node, 4 quad diagonals, ...
}

TEST(CollisionDetection, ConvexEdgeAndCornerOfTheBlock) {
  Block b({4, 4, 3}, 1, 0.3, 0.5, 0.1);
  // Beside and above the top edge y = 0, z = 2, over the middle of the grid edge x in [1, 2].
  {
    const Vector3d foot(1.5, 0, 2), c = foot + Vector3d(0, -0.3, 0.4);
    const auto& cs = b.detectAt(c);
    ASSERT_EQ(cs.size(), 1u);
    const Contact& ct = cs[0];
    EXPECT_EQ(ct.feature, Feature::Edge);
    std::array<int, 2> nodes = {ct.nodes[0], ct.nodes[1]};
    std::sort(nodes.begin(), nodes.end());
    std::array<int, 2> expected = {b.node(Vector3d(1, 0, 2)), b.node(Vector3d(2, 0, 2))};
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(nodes, expected);
    EXPECT_NEAR(ct.w[0], 0.5, 1e-14);
    EXPECT_NEAR(ct.w[1], 0.5, 1e-14);
    EXPECT_LE((ct.n - (c - foot).normalized()).norm(), 1e-14);
    EXPECT_NEAR(ct.gap0, 0.5 - b.R - b.contact, 1e-14);
    EXPECT_LE((ct.p0 - foot).norm(), 1e-14);
    checkContactInvariants(ct, b.x());
  }
  // The same along a vertical edge (x = 3, y = 3), between two nodes.
  {
    const Vector3d foot(3, 3, 0.7), c = foot + Vector3d(0.2, 0.15, 0);
    const auto& cs = b.detectAt(c);
    ASSERT_EQ(cs.size(), 1u);
    EXPECT_EQ(cs[0].feature, Feature::Edge);
    EXPECT_LE((cs[0].n - (c - foot).normalized()).norm(), 1e-14);
    EXPECT_NEAR(cs[0].gap0, 0.25 - b.R - b.contact, 1e-14);
    EXPECT_NEAR(cs[0].w[0] * b.x()(2, cs[0].nodes[0]) + cs[0].w[1] * b.x()(2, cs[0].nodes[1]), 0.7, 1e-14);
    checkContactInvariants(cs[0], b.x());
  }
  // Near the corner (3, 3, 2), outside all three faces' regions.
  {
    const Vector3d corner(3, 3, 2), c = corner + Vector3d(0.2, 0.3, 0.25);
    const auto& cs = b.detectAt(c);
    ASSERT_EQ(cs.size(), 1u);
    const Contact& ct = cs[0];
    EXPECT_EQ(ct.feature, Feature::Vertex);
    EXPECT_EQ(ct.nodes[0], b.node(corner));
    EXPECT_LE((ct.n - (c - corner).normalized()).norm(), 1e-14);
    EXPECT_NEAR(ct.gap0, (c - corner).norm() - b.R - b.contact, 1e-14);
    checkContactInvariants(ct, b.x());
  }
  // The lower corner (0, 0, 0).
  {
    const Vector3d c(-0.1, -0.2, -0.3);
    const auto& cs = b.detectAt(c);
    ASSERT_EQ(cs.size(), 1u);
    EXPECT_EQ(cs[0].feature, Feature::Vertex);
    EXPECT_EQ(cs[0].nodes[0], b.node(Vector3d::Zero()));
    EXPECT_LE((cs[0].n - c.normalized()).norm(), 1e-14);
  }
}

TEST(CollisionDetection, NothingBeyondTheAlarmDistance) {
  Block b({4, 4, 3}, 1, 0.3, 0.5, 0.1);
  // Distance - R just above alarmDistance: above a face, beside an edge, off a corner.
  const double d = b.R + b.alarm + 1e-9;
  EXPECT_TRUE(b.detectAt(Vector3d(1.3, 1.6, 2 + d)).empty());
  EXPECT_TRUE(b.detectAt(Vector3d(1.5, 0, 2) + d * Vector3d(0, -0.6, 0.8)).empty());
  EXPECT_TRUE(b.detectAt(Vector3d(3, 3, 2) + d * Vector3d(1, 1, 1).normalized()).empty());
  EXPECT_TRUE(b.detectAt(Vector3d(20, 20, 20)).empty());
  // Just inside: one contact each.
  const double in = b.R + b.alarm - 1e-9;
  EXPECT_EQ(b.detectAt(Vector3d(1.3, 1.6, 2 + in)).size(), 1u);
  EXPECT_EQ(b.detectAt(Vector3d(1.5, 0, 2) + in * Vector3d(0, -0.6, 0.8)).size(), 1u);
  EXPECT_EQ(b.detectAt(Vector3d(3, 3, 2) + in * Vector3d(1, 1, 1).normalized()).size(), 1u);
}

TEST(CollisionDetection, StepRunsTheSameDetection) {
  Block b({3, 3, 3}, 1, 0.3, 0.5, 0.1);
  b.tools[0]->live(b.state()).p = Vector3d(0.7, 1.2, 2.5);  // no driver: the body stays where it is put
  ASSERT_FALSE(b.sim->step().has_value());
  const auto& cs = b.surface->contacts(b.state());
  ASSERT_EQ(cs.size(), 1u);
  EXPECT_EQ(cs[0].feature, Feature::Face);
  // Detection uses the tissue at the step start (the rest shape here).
  EXPECT_NEAR(cs[0].gap0, 0.5 - b.R - b.contact, 1e-14);
  EXPECT_FALSE(cs[0].active);  // gap > 0: no force
  EXPECT_EQ(b.sim->pipeline()->contactCount(b.state()), 0);
}

// ---------------------------------------------------------------------------------------------
// Penalty force field

TEST(CollisionPenalty, DerivativesMatchFiniteDifferencesAndAssembledMatrix) {
  // Three spheres pressed into a face, an edge and a corner (gap < 0: active contacts).
  Block b({3, 3, 3}, 3, 0.3, 0.5, 0.1);
  ASSERT_EQ(b.tools.size(), 3u);
  State& st = b.state();
  b.tools[0]->live(st).p = Vector3d(0.6, 1.3, 2.35);                                 // face, gap -0.05
  b.tools[1]->live(st).p = Vector3d(1.5, 0, 2) + 0.3 * Vector3d(0, -0.6, 0.8);       // edge, gap -0.1
  b.tools[2]->live(st).p = Vector3d(2, 2, 0) + 0.2 * Vector3d(1, 1, -1).normalized();  // corner, gap -0.2
  b.sim->pipeline()->detect(st);
  SurfaceCollisionModel& s = *b.surface;
  ASSERT_EQ(s.contacts(st).size(), 3u);
  std::set<Feature> kinds;
  for (const Contact& c : s.contacts(st)) kinds.insert(c.feature);
  EXPECT_EQ(kinds.size(), 3u);
  // SOFA's per-contact stiffness: the sphere's factor (10, the default) times the surface's (1),
  // over contactDistance plus the radius.
  const double k = 10 * 1.0 / (b.contact + b.R);
  for (const Contact& c : s.contacts(st)) EXPECT_DOUBLE_EQ(c.k, k);

  const int n = b.x().cols();
  std::mt19937 rng(99);
  std::normal_distribution<double> g;
  Eigen::Matrix3Xd x = b.x();
  for (int i = 0; i < n; ++i) x.col(i) += 1e-3 * Vector3d(g(rng), g(rng), g(rng));
  const Eigen::Matrix3Xd v = Eigen::Matrix3Xd::Zero(3, n);
  auto force = [&](const Eigen::Matrix3Xd& at) {
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, n);
    s.addForce(st, at, v, f);
    return f;
  };
  const Eigen::Matrix3Xd f0 = force(x);
  for (const Contact& c : s.contacts(st)) EXPECT_TRUE(c.active);
  EXPECT_GT(f0.norm(), 0.0);
  // The force is k g n per contact (on the tissue: along -n when penetrating), spread by weights.
  Vector3d total = Vector3d::Zero();
  for (const Contact& c : s.contacts(st)) total += k * c.gap(x) * c.n;
  EXPECT_LE((f0.rowwise().sum() - total).norm(), 1e-15);

  // The force is affine in x while the active set holds (gaps stay < -0.04 for steps of 1e-4),
  // so the central difference is exact but for rounding: |f| ~ 0.1 with errors ~1e-17 divided
  // by 2h = 2e-4 gives ~1e-13; 1e-10 leaves a wide margin yet catches any wrong entry (>= k w^2 / 9).
  const double h = 1e-4;
  Eigen::MatrixXd J(3 * n, 3 * n);
  for (int j = 0; j < 3 * n; ++j) {
    Eigen::Matrix3Xd xp = x, xm = x;
    xp(j % 3, j / 3) += h;
    xm(j % 3, j / 3) -= h;
    const Eigen::Matrix3Xd d = (force(xp) - force(xm)) / (2 * h);
    J.col(j) = Eigen::Map<const Eigen::VectorXd>(d.data(), 3 * n);
  }
  force(x);  // back to the linearisation at x
  for (const Contact& c : s.contacts(st)) ASSERT_TRUE(c.active);

  // addDForce: df += kFactor K dx, for random directions and kFactors.
  for (double kFactor : {1.0, -0.37}) {
    for (int trial = 0; trial < 5; ++trial) {
      Eigen::Matrix3Xd dx(3, n);
      for (int i = 0; i < n; ++i) dx.col(i) = Vector3d(g(rng), g(rng), g(rng));
      Eigen::Matrix3Xd df = Eigen::Matrix3Xd::Zero(3, n);
      s.addDForce(st, dx, df, kFactor);
      const Eigen::VectorXd expected = kFactor * J * Eigen::Map<const Eigen::VectorXd>(dx.data(), 3 * n);
      EXPECT_LE((Eigen::Map<const Eigen::VectorXd>(df.data(), 3 * n) - expected).norm(), 1e-10 * dx.norm());
      // The central difference along dx itself (the dense directional derivative).
      const Eigen::Matrix3Xd dir = (force(x + h * dx) - force(x - h * dx)) / (2 * h);
      force(x);
      EXPECT_LE((df - kFactor * dir).norm(), 1e-10 * dx.norm());
    }
  }

  // addStiffness into the pattern built from stiffnessPattern equals the Jacobian.
  std::vector<std::pair<int, int>> pairs;
  s.stiffnessPattern(pairs);
  BlockSparseMatrix K;
  K.setPattern(n, pairs);
  for (double kFactor : {1.0, 2.5}) {
    K.setZero();
    s.addStiffness(st, K, kFactor);
    const Eigen::MatrixXd dense = K.toDense();
    EXPECT_LE((dense - kFactor * J).norm(), 1e-10 * kFactor);
    EXPECT_LE((dense - dense.transpose()).norm(), 1e-15 * k * kFactor);  // round-off of entries ~k
    // K y computed by the sparse product matches the dense one.
    Eigen::VectorXd y = Eigen::VectorXd::Random(3 * n), Ky(3 * n);
    K.multiply(y, Ky);
    EXPECT_LE((Ky - dense * y).norm(), 1e-13);
  }
  // The Jacobian is -k sum_c (w w^T) (x) n n^T: negative semi-definite, rank 3 (one per contact).
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (J + J.transpose()));
  EXPECT_LE(eig.eigenvalues().maxCoeff(), 1e-10);
  int rank = 0;
  for (int i = 0; i < 3 * n; ++i) rank += eig.eigenvalues()[i] < -1e-8;
  EXPECT_EQ(rank, 3);

  // Contacts with positive gap exert nothing and add no stiffness.
  b.tools[0]->live(st).p.z() += 0.2;
  b.tools[1]->live(st).p += Vector3d(0, -0.3, 0.3);
  b.tools[2]->live(st).p += Vector3d(0.3, 0.3, -0.3);
  b.sim->pipeline()->detect(st);
  ASSERT_EQ(s.contacts(st).size(), 3u);
  EXPECT_EQ(force(b.x()).norm(), 0.0);
  K.setZero();
  s.addStiffness(st, K, 1.0);
  EXPECT_EQ(K.toDense().norm(), 0.0);
}

}  // namespace
