// Palpation sequences: random pokes of a spherical tool into the faces of a box, joined by
// moves that keep the tool clear of the box, sampled at a fixed rate like camera frames.
//
// The path of the sphere centre is piecewise linear. Each poke runs along the face normal
// through a random point of the face:
//   approach point A (surface `lift` off the face) -> rest -> press to the poke depth -> dwell
//   -> retract to A.
// Between pokes the tool backs off along the normal to A' (clearance lift + delta), rises to
// the safe height (box top + lift + delta + radius), moves horizontally to above the next A',
// descends and moves in along the normal to the next A. For a top poke A' is already at the
// safe height. The trajectory starts at the first A; pokes are added while the next one, with
// its moves, is over by `duration`, and the tool then holds at the safe height.
//
// Why delta: the output is the path sampled at `rate`, and a consumer interpolates linearly
// between samples, so corners of the path are cut by chords. At ordinary rates that is harmless,
// but when samples lie far apart compared with lift + radius a chord can skip a corner and pass
// through the specimen. A chord between two path points h apart along the path (h <=
// travelSpeed / rate for moves) stays within h/2 of the path, so raising the clearance of every
// move by delta = h/2 keeps the chords `lift` clear of the box at any rate. Near A, where the
// clearance is between lift and lift + delta, the path only runs along the face normal and
// straight along the face, so chords there stay on the outer side of the face's plane at
// clearance >= lift.
#include "motion/Palpation.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

namespace viscera::motion {
namespace {

// A face as an outward normal +-e_axis.
struct FaceFrame {
  int axis;     // 0, 1, 2 for x, y, z
  double sign;  // +1 for the max face, -1 for the min face
};

FaceFrame frameOf(Face f) {
  switch (f) {
    case Face::Top: return {2, +1};
    case Face::XMin: return {0, -1};
    case Face::XMax: return {0, +1};
    case Face::YMin: return {1, -1};
    case Face::YMax: return {1, +1};
  }
  return {2, +1};
}

std::string num(double v) {
  std::ostringstream o;
  o << v;
  return o.str();
}

[[noreturn]] void invalid(const std::string& field, const std::string& what) {
  throw std::invalid_argument(field + ": " + what);
}

void validate(const PalpationSpec& s) {
  const char* axes[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(s.boxMin[a]) || !std::isfinite(s.boxMax[a]))
      invalid("box", std::string("the ") + axes[a] + " bounds are not finite");
    if (!(s.boxMax[a] > s.boxMin[a]))
      invalid("box", std::string("empty in ") + axes[a] + " (min " + num(s.boxMin[a]) + ", max " + num(s.boxMax[a]) + ")");
  }
  auto positive = [](const char* field, double v) {
    if (!(v > 0) || !std::isfinite(v)) invalid(field, "must be a positive number (got " + num(v) + ")");
  };
  auto nonNegative = [](const char* field, double v) {
    if (!(v >= 0) || !std::isfinite(v)) invalid(field, "must be zero or positive (got " + num(v) + ")");
  };
  positive("radius", s.radius);
  positive("speed", s.speed);
  positive("travelSpeed", s.travelSpeed);
  positive("rate", s.rate);
  positive("duration", s.duration);
  positive("depth", s.depth);
  const double halfSize = 0.5 * (s.boxMax - s.boxMin).minCoeff();
  if (!(s.depth < halfSize))
    invalid("depth", "must be less than half the box's smallest size, " + num(halfSize) + " (got " + num(s.depth) + ")");
  if (!(s.depthJitter >= 0 && s.depthJitter < 1)) invalid("depthJitter", "must be in [0, 1) (got " + num(s.depthJitter) + ")");
  if (!(s.margin >= 0 && s.margin < 0.5)) invalid("margin", "must be in [0, 0.5) (got " + num(s.margin) + ")");
  nonNegative("dwell", s.dwell);
  nonNegative("rest", s.rest);
  nonNegative("lift", s.lift);
  if (s.faces.empty()) invalid("faces", "no faces to poke");
  constexpr double kMaxSamples = 1e8;
  if (s.duration * s.rate > kMaxSamples)
    invalid("rate", "duration * rate is " + num(s.duration * s.rate) + " samples, more than " + num(kMaxSamples));
}

// Uniform in [0, 1) straight from the engine's bits: std::uniform_real_distribution is
// implementation-defined, and the same seed must give the same file with every standard library.
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// The piecewise-linear path of the sphere centre, as (time, position) corners.
class PathBuilder {
 public:
  PathBuilder(double t0, const Eigen::Vector3d& p0) { keys_.add(t0, p0); }

  double time() const { return keys_.end(); }
  const Eigen::Vector3d& position() const { return keys_.p.back(); }
  const Trajectory& keys() const { return keys_; }

  void moveTo(const Eigen::Vector3d& target, double speed) {
    const double d = (target - position()).norm();
    if (d > 1e-12 * (1 + target.norm())) keys_.add(time() + d / speed, target);
  }
  void hold(double dt) {
    if (dt > 0) keys_.add(time() + dt, position());
  }
  void append(const PathBuilder& more) {
    for (int i = 1; i < more.keys_.size(); ++i) keys_.add(more.keys_.t[i], more.keys_.p[i]);
  }

 private:
  Trajectory keys_;
};

struct Poke {
  Face face;
  Eigen::Vector3d location;  // point on the face's plane
  double depth;
};

}  // namespace

PalpationResult generatePalpation(const PalpationSpec& spec) {
  validate(spec);
  const Eigen::Vector3d size = spec.boxMax - spec.boxMin;
  const double r = spec.radius;
  const double delta = 0.5 * spec.travelSpeed / spec.rate;   // see the top of the file
  const double safeZ = spec.boxMax.z() + spec.lift + delta + r;
  std::mt19937_64 rng(spec.seed);

  auto drawPoke = [&]() {
    Poke k;
    k.face = spec.faces[static_cast<size_t>(uniform01(rng) * static_cast<double>(spec.faces.size()))];
    const FaceFrame f = frameOf(k.face);
    for (int a = 0; a < 3; ++a) {
      if (a == f.axis) {
        k.location[a] = f.sign > 0 ? spec.boxMax[a] : spec.boxMin[a];
      } else {
        const double lo = spec.boxMin[a] + spec.margin * size[a];
        const double hi = spec.boxMax[a] - spec.margin * size[a];
        k.location[a] = lo + uniform01(rng) * (hi - lo);
      }
    }
    k.depth = spec.depth * (1 + spec.depthJitter * (2 * uniform01(rng) - 1));
    return k;
  };
  // Centre on the poke's line with the sphere surface `clearance` off the face (negative: inside).
  auto onLine = [&](const Poke& k, double clearance) {
    const FaceFrame f = frameOf(k.face);
    Eigen::Vector3d c = k.location;
    c[f.axis] += f.sign * (r + clearance);
    return c;
  };

  // One poke from the tool's current position (`first`: it is already at A, at time 0): the
  // move in, the poke, and the way out to the safe height.
  auto pokeSegment = [&](const PathBuilder& from, const Poke& k, bool first) {
    const Eigen::Vector3d a = onLine(k, spec.lift);
    const Eigen::Vector3d aOut = onLine(k, spec.lift + delta);
    PathBuilder seg(from.time(), from.position());
    if (!first) {
      seg.moveTo({aOut.x(), aOut.y(), safeZ}, spec.travelSpeed);
      seg.moveTo(aOut, spec.travelSpeed);
      seg.moveTo(a, spec.travelSpeed);
    }
    seg.hold(spec.rest);
    seg.moveTo(onLine(k, -k.depth), spec.speed);
    seg.hold(spec.dwell);
    seg.moveTo(a, spec.speed);
    seg.moveTo(aOut, spec.travelSpeed);
    seg.moveTo({aOut.x(), aOut.y(), safeZ}, spec.travelSpeed);
    return seg;
  };

  PalpationResult result;
  Poke next = drawPoke();
  PathBuilder path(0.0, onLine(next, spec.lift));
  const double slack = 1e-9 * spec.duration;
  for (bool first = true;; first = false) {
    PathBuilder seg = pokeSegment(path, next, first);
    if (seg.time() > spec.duration + slack) {
      if (first)
        invalid("duration", num(spec.duration) + " is too short for one poke (the first takes " + num(seg.time()) + ")");
      break;
    }
    path.append(seg);
    ++result.pokes;
    result.pokedFaces.push_back(next.face);
    next = drawPoke();
  }
  path.hold(spec.duration - path.time());  // at the safe height until the end

  // Uniform samples t = k / rate, k = 0..N, none after `duration`.
  const long long n = static_cast<long long>(std::floor(spec.duration * spec.rate + 1e-9));
  for (long long i = 0; i <= n; ++i) {
    const double t = static_cast<double>(i) / spec.rate;
    result.trajectory.add(t, path.keys().sample(t).p);
  }
  return result;
}

Face parseFace(const std::string& text) {
  std::string s;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) s += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (s == "top" || s == "z+" || s == "zmax") return Face::Top;
  if (s == "x-" || s == "xmin") return Face::XMin;
  if (s == "x+" || s == "xmax") return Face::XMax;
  if (s == "y-" || s == "ymin") return Face::YMin;
  if (s == "y+" || s == "ymax") return Face::YMax;
  if (s == "bottom" || s == "z-" || s == "zmin")
    throw std::invalid_argument("face '" + text + "': the bottom rests on the support and cannot be poked");
  throw std::invalid_argument("unknown face '" + text + "' (expected top, x-, x+, y-, y+)");
}

std::string faceName(Face f) {
  switch (f) {
    case Face::Top: return "top";
    case Face::XMin: return "x-";
    case Face::XMax: return "x+";
    case Face::YMin: return "y-";
    case Face::YMax: return "y+";
  }
  return "?";
}

}  // namespace viscera::motion
