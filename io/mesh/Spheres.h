// Sphere sets in SOFA's .sph format: a collision or mass approximation of a body by spheres.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace viscera::io {

struct SphereSet {
  Eigen::Matrix3Xd centres;    // 3 x #spheres
  std::vector<double> radii;  // one per sphere
};

// Reads a .sph file: a "sph 1.0" first line, an optional "nums N" count, then one
// "sphe INDEX X Y Z RADIUS" line per sphere (in file order; SOFA ignores the index, and so do
// we); '#' starts a comment. Throws viscera::Error naming the file and line for anything else:
// unknown keywords, missing or non-finite numbers, radii that are not positive, a count that
// does not match the spheres given.
SphereSet readSpheres(const std::string& path);

}  // namespace viscera::io
