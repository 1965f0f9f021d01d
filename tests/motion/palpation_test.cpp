// Palpation sequences: reproducible for a seed, sampled uniformly, pokes straight along face
// normals to the requested depth, and the tool (and the chords between samples, which is what an
// interpolating consumer follows) kept `lift` clear of the specimen between pokes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "motion/Palpation.h"

using namespace viscera::motion;

namespace {

// The gel phantom of the recordings (mm).
PalpationSpec phantom(uint64_t seed = 1) {
  PalpationSpec s;
  s.boxMin = {0, 0, 0};
  s.boxMax = {68.7, 35.8, 39.3};
  s.seed = seed;
  return s;
}

// Signed distance from a point to the box (negative inside).
double boxDistance(const PalpationSpec& s, const Eigen::Vector3d& c) {
  const Eigen::Vector3d d = (s.boxMin - c).cwiseMax(c - s.boxMax);
  return d.cwiseMax(0.0).norm() + std::min(d.maxCoeff(), 0.0);
}

// Distance from the sphere's surface to the box (negative: how far the sphere is pressed in).
double clearance(const PalpationSpec& s, const Eigen::Vector3d& c) { return boxDistance(s, c) - s.radius; }

// Smallest clearance along the chord a-b (the distance to a convex set is convex along a line).
double chordClearance(const PalpationSpec& s, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  double lo = 0, hi = 1;
  auto f = [&](double u) { return clearance(s, a + u * (b - a)); };
  for (int i = 0; i < 100; ++i) {
    const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
    if (f(m1) < f(m2)) hi = m2;
    else lo = m1;
  }
  return std::min({f(0), f(1), f(0.5 * (lo + hi))});
}

struct FaceAxes {
  int normal;      // axis of the face normal
  double sign;     // direction of the outward normal
};

FaceAxes axesOf(Face f) {
  switch (f) {
    case Face::Top: return {2, +1};
    case Face::XMin: return {0, -1};
    case Face::XMax: return {0, +1};
    case Face::YMin: return {1, -1};
    case Face::YMax: return {1, +1};
  }
  return {-1, 0};
}

// A stretch of consecutive samples closer to the specimen than `lift`: a poke.
struct PokeRun {
  int first, last;        // sample indices, inclusive
  double penetration;     // deepest the sphere surface went past the face
};

std::vector<PokeRun> pokeRuns(const PalpationSpec& s, const Trajectory& tr) {
  std::vector<PokeRun> runs;
  for (int i = 0; i < tr.size(); ++i) {
    const double c = clearance(s, tr.p[i]);
    if (c >= s.lift * (1 - 1e-9)) continue;
    if (runs.empty() || runs.back().last != i - 1) runs.push_back({i, i, -c});
    runs.back().last = i;
    runs.back().penetration = std::max(runs.back().penetration, -c);
  }
  return runs;
}

// Every property of a generated palpation that does not depend on the random draws.
void checkPalpation(const PalpationSpec& s, const PalpationResult& r) {
  const Trajectory& tr = r.trajectory;
  ASSERT_GT(tr.size(), 1);

  // Uniform samples from 0 to (at most) the duration; identity orientation.
  EXPECT_EQ(tr.t.front(), 0.0);
  EXPECT_EQ(tr.size(), static_cast<int>(std::floor(s.duration * s.rate + 1e-9)) + 1);
  for (int i = 1; i < tr.size(); ++i) ASSERT_NEAR(tr.t[i] - tr.t[i - 1], 1 / s.rate, 1e-9) << i;
  EXPECT_LE(tr.end(), s.duration + 1e-9);
  for (const auto& q : tr.q) ASSERT_EQ(q.coeffs(), Eigen::Quaterniond::Identity().coeffs());

  // Starts at the first approach point, ends lifted clear at the safe height.
  EXPECT_NEAR(clearance(s, tr.p.front()), s.lift, 1e-9);
  EXPECT_GE(tr.p.back().z(), s.boxMax.z() + s.lift + s.radius - 1e-9);

  // One run of samples closer than `lift` per poke, straight along the poked face's normal,
  // through a point of the face inside the margins, to the requested depth.
  const auto runs = pokeRuns(s, tr);
  ASSERT_EQ(static_cast<int>(runs.size()), r.pokes);
  ASSERT_EQ(r.pokedFaces.size(), runs.size());
  const Eigen::Vector3d size = s.boxMax - s.boxMin;
  double deepest = 0;
  for (size_t k = 0; k < runs.size(); ++k) {
    const Face face = r.pokedFaces[k];
    EXPECT_NE(std::find(s.faces.begin(), s.faces.end(), face), s.faces.end()) << faceName(face) << " was not requested";
    const FaceAxes ax = axesOf(face);
    const Eigen::Vector3d& ref = tr.p[runs[k].first];
    for (int i = runs[k].first; i <= runs[k].last; ++i) {
      for (int a = 0; a < 3; ++a) {
        if (a == ax.normal) continue;
        ASSERT_NEAR(tr.p[i][a], ref[a], 1e-9) << "poke " << k << " sample " << i << " leaves the normal of face "
                                              << faceName(face);
        EXPECT_GE(tr.p[i][a], s.boxMin[a] + s.margin * size[a] - 1e-9);
        EXPECT_LE(tr.p[i][a], s.boxMax[a] - s.margin * size[a] + 1e-9);
      }
      // On the outer side of the poked face: the sphere's nearest point is on that face.
      const double faceCoord = ax.sign > 0 ? s.boxMax[ax.normal] : s.boxMin[ax.normal];
      EXPECT_NEAR(ax.sign * (tr.p[i][ax.normal] - faceCoord) - s.radius, clearance(s, tr.p[i]), 1e-9)
          << "poke " << k << " sample " << i;
    }
    if (s.dwell * s.rate >= 1) {  // a sample falls in the dwell
      EXPECT_GE(runs[k].penetration, s.depth * (1 - s.depthJitter) - 1e-9) << "poke " << k;
    }
    EXPECT_LE(runs[k].penetration, s.depth * (1 + s.depthJitter) + 1e-9) << "poke " << k;
    deepest = std::max(deepest, runs[k].penetration);
  }
  EXPECT_LE(deepest, s.depth * (1 + s.depthJitter) + 1e-9);

  // Between pokes neither the samples nor the chords joining them come closer than `lift`;
  // chords into and out of a poke do not cut into the specimen beside it.
  double closest = INFINITY;
  for (int i = 0; i + 1 < tr.size(); ++i) {
    const double ca = clearance(s, tr.p[i]), cb = clearance(s, tr.p[i + 1]);
    const double chord = chordClearance(s, tr.p[i], tr.p[i + 1]);
    if (std::min(ca, cb) >= s.lift * (1 - 1e-9)) {
      ASSERT_GE(chord, 0.99 * s.lift) << "chord " << i << " at t = " << tr.t[i];
      closest = std::min(closest, chord);
    } else {
      ASSERT_GE(chord, std::min(ca, cb) - 0.01 * s.lift) << "chord " << i << " at t = " << tr.t[i];
    }
  }
  EXPECT_GE(closest, s.lift * (1 - 1e-9));  // in fact no closer at all
}

TEST(Palpation, PhantomDefaults) {
  const PalpationSpec s = phantom();
  const PalpationResult r = generatePalpation(s);
  checkPalpation(s, r);
  EXPECT_EQ(r.trajectory.size(), 80 * 30 + 1);
  EXPECT_GE(r.pokes, 5);
  EXPECT_LE(r.pokes, 15);
}

TEST(Palpation, ManySeedsAndSettings) {
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    PalpationSpec s = phantom(seed);
    checkPalpation(s, generatePalpation(s));

    // Coarse sampling, fast moves (long chords), small lift, big tool, no margin, long dwell.
    s.rate = 7;
    s.travelSpeed = 80;
    s.lift = 2;
    s.radius = 12;
    s.margin = 0;
    s.dwell = 2;
    s.depth = 9;
    s.depthJitter = 0.3;  // deepest 11.7: the centre stays outside the box
    checkPalpation(s, generatePalpation(s));

    // Sampling far coarser than the moves (120 length units between samples): the chords skip
    // whole legs of the path and must still stay clear.
    PalpationSpec c = phantom(seed);
    c.rate = 1;
    c.travelSpeed = 120;
    c.lift = 1;
    c.rest = 2;  // a sample in every rest, so that pokes stay apart
    c.duration = 200;
    checkPalpation(c, generatePalpation(c));

    // Tiny box, a tool bigger than it, fine sampling.
    PalpationSpec t;
    t.boxMin = {-1, -2, 5};
    t.boxMax = {1, 2, 6};
    t.radius = 3;
    t.depth = 0.3;
    t.speed = 1;
    t.travelSpeed = 4;
    t.lift = 0.5;
    t.rate = 120;
    t.duration = 30;
    t.seed = seed;
    checkPalpation(t, generatePalpation(t));
  }
}

TEST(Palpation, SameSeedSameTrajectory) {
  const PalpationResult a = generatePalpation(phantom(42));
  const PalpationResult b = generatePalpation(phantom(42));
  EXPECT_EQ(formatTrajectoryCsv(a.trajectory), formatTrajectoryCsv(b.trajectory));
  EXPECT_EQ(a.pokedFaces, b.pokedFaces);
  const PalpationResult c = generatePalpation(phantom(43));
  EXPECT_NE(formatTrajectoryCsv(a.trajectory), formatTrajectoryCsv(c.trajectory));
}

TEST(Palpation, OnlyTheRequestedFaces) {
  PalpationSpec s = phantom(3);
  s.faces = {Face::XMin, Face::YMax};
  PalpationResult r = generatePalpation(s);
  checkPalpation(s, r);
  for (Face f : r.pokedFaces) EXPECT_TRUE(f == Face::XMin || f == Face::YMax) << faceName(f);

  s.faces = {Face::Top};
  r = generatePalpation(s);
  checkPalpation(s, r);
  EXPECT_EQ(std::count(r.pokedFaces.begin(), r.pokedFaces.end(), Face::Top), r.pokes);
}

TEST(Palpation, EveryFaceComesUp) {
  PalpationSpec s = phantom(7);
  s.duration = 600;
  const PalpationResult r = generatePalpation(s);
  std::map<Face, int> count;
  for (Face f : r.pokedFaces) ++count[f];
  for (Face f : s.faces) EXPECT_GE(count[f], 3) << faceName(f);
}

TEST(Palpation, WithoutJitterEveryPokeHasTheDepth) {
  PalpationSpec s = phantom(5);
  s.depthJitter = 0;
  const PalpationResult r = generatePalpation(s);
  checkPalpation(s, r);
  for (const auto& run : pokeRuns(s, r.trajectory)) EXPECT_NEAR(run.penetration, s.depth, 1e-9);
}

TEST(Palpation, JitterVariesTheDepth) {
  const PalpationSpec s = phantom(9);
  const auto runs = pokeRuns(s, generatePalpation(s).trajectory);
  ASSERT_GE(runs.size(), 3u);
  auto [lo, hi] = std::minmax_element(runs.begin(), runs.end(),
                                      [](const PokeRun& a, const PokeRun& b) { return a.penetration < b.penetration; });
  EXPECT_GT(hi->penetration - lo->penetration, 0.05 * s.depth);
}

TEST(Palpation, RestsAtTheFirstApproachPoint) {
  const PalpationSpec s = phantom();
  const Trajectory tr = generatePalpation(s).trajectory;
  for (int i = 1; tr.t[i] <= s.rest; ++i) EXPECT_EQ(tr.p[i], tr.p[0]) << i;
}

TEST(Palpation, ShortDurationsStillHoldOnePoke) {
  PalpationSpec s = phantom();
  s.duration = 5;  // one top poke needs 0.5 + 1.4 + 1 + 1.4 s plus a few frames; sides take longer
  s.faces = {Face::Top};
  const PalpationResult r = generatePalpation(s);
  EXPECT_EQ(r.pokes, 1);
  checkPalpation(s, r);
}

TEST(Palpation, InvalidSpecsThrow) {
  const std::vector<std::pair<std::string, std::function<void(PalpationSpec&)>>> cases = {
      {"box", [](PalpationSpec& s) { s.boxMax.y() = s.boxMin.y(); }},
      {"box", [](PalpationSpec& s) { s.boxMax.z() = -1; }},
      {"box", [](PalpationSpec& s) { s.boxMax.x() = NAN; }},
      {"radius", [](PalpationSpec& s) { s.radius = 0; }},
      {"speed", [](PalpationSpec& s) { s.speed = -1; }},
      {"travelSpeed", [](PalpationSpec& s) { s.travelSpeed = 0; }},
      {"rate", [](PalpationSpec& s) { s.rate = 0; }},
      {"rate", [](PalpationSpec& s) { s.rate = NAN; }},
      {"duration", [](PalpationSpec& s) { s.duration = 0; }},
      {"depth", [](PalpationSpec& s) { s.depth = 0; }},
      {"depth", [](PalpationSpec& s) { s.depth = 35.8 / 2; }},
      {"depthJitter", [](PalpationSpec& s) { s.depthJitter = 1; }},
      {"depthJitter", [](PalpationSpec& s) { s.depthJitter = -0.1; }},
      {"margin", [](PalpationSpec& s) { s.margin = 0.5; }},
      {"margin", [](PalpationSpec& s) { s.margin = -0.01; }},
      {"dwell", [](PalpationSpec& s) { s.dwell = -1; }},
      {"rest", [](PalpationSpec& s) { s.rest = -0.5; }},
      {"lift", [](PalpationSpec& s) { s.lift = -2; }},
      {"faces", [](PalpationSpec& s) { s.faces.clear(); }},
      {"duration", [](PalpationSpec& s) { s.duration = 2; }},  // too short for one poke
  };
  for (const auto& [field, breakIt] : cases) {
    PalpationSpec s = phantom();
    breakIt(s);
    try {
      generatePalpation(s);
      ADD_FAILURE() << field << ": no error";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(field + ": ", 0), 0u) << e.what();
    }
  }
  // The limits themselves are fine.
  PalpationSpec s = phantom();
  s.depthJitter = 0;
  s.margin = 0;
  s.dwell = s.rest = s.lift = 0;
  EXPECT_NO_THROW(generatePalpation(s));
}

TEST(Palpation, FaceNames) {
  for (Face f : {Face::Top, Face::XMin, Face::XMax, Face::YMin, Face::YMax}) EXPECT_EQ(parseFace(faceName(f)), f);
  EXPECT_EQ(faceName(Face::XMin), "x-");
  EXPECT_EQ(faceName(Face::YMax), "y+");
  EXPECT_EQ(parseFace("xmin"), Face::XMin);
  EXPECT_EQ(parseFace("XMax"), Face::XMax);
  EXPECT_EQ(parseFace("ymin"), Face::YMin);
  EXPECT_EQ(parseFace("ymax"), Face::YMax);
  EXPECT_EQ(parseFace(" TOP "), Face::Top);
  EXPECT_THROW(parseFace("bottom"), std::invalid_argument);
  EXPECT_THROW(parseFace("z-"), std::invalid_argument);
  EXPECT_THROW(parseFace("x"), std::invalid_argument);
  EXPECT_THROW(parseFace(""), std::invalid_argument);
}

}  // namespace
