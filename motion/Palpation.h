// Palpation sequences: a spherical instrument poking the top and the sides of a box-shaped
// specimen, as in the gel-phantom recordings (several distinct pokes, the tool lifted clear of
// the specimen between them).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "motion/Trajectory.h"

namespace viscera::motion {

enum class Face { Top, XMin, XMax, YMin, YMax };  // z is up; the bottom (z min) is never poked

struct PalpationSpec {
  Eigen::Vector3d boxMin = Eigen::Vector3d::Zero();  // the specimen's bounding box
  Eigen::Vector3d boxMax = Eigen::Vector3d::Zero();
  double radius = 5.0;      // instrument sphere radius
  double depth = 4.0;       // how far the sphere surface goes past the undeformed face
  double depthJitter = 0.25;  // each poke's depth is depth * (1 +- jitter), uniform
  double speed = 10.0;      // approach / press / retract speed
  double travelSpeed = 30.0;  // speed of moves between pokes, clear of the specimen
  double dwell = 1.0;       // hold at full depth
  double rest = 0.5;        // hold at the start of each approach
  double lift = 10.0;       // clearance between the sphere surface and the specimen when moving between pokes
  double margin = 0.2;      // poke centres keep this fraction of the face size away from its edges
  double duration = 80.0;   // total length; the last poke is completed (and the tool lifted) before it
  double rate = 30.0;       // samples per unit time
  std::vector<Face> faces = {Face::Top, Face::XMin, Face::XMax, Face::YMin, Face::YMax};
  uint64_t seed = 1;
};

struct PalpationResult {
  Trajectory trajectory;
  int pokes = 0;
  std::vector<Face> pokedFaces;  // one per poke
};

// Throws std::invalid_argument with a clear message for an inconsistent spec (empty box, no
// faces, non-positive speed/rate/radius, a duration too short for one poke, ...).
PalpationResult generatePalpation(const PalpationSpec& spec);

// "top", "x-", "x+", "y-", "y+" (also "xmin", "xmax", ...); throws std::invalid_argument.
Face parseFace(const std::string& s);
std::string faceName(Face f);

}  // namespace viscera::motion
