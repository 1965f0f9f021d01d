// Rigid transforms stored as files: camera -> scene from ICP, robot -> scene from corresponding
// points. Scenes and commands reference them by path.
//
// File format (text): optional '#' comment lines, then the 4 x 4 homogeneous matrix, row by row,
// that maps a point of the source frame into the target frame: x_target = R x_source + t. The
// last row must be 0 0 0 1 and R a rotation (orthonormal, det +1, to 1e-6). numpy.loadtxt reads it.
#pragma once

#include <Eigen/Geometry>
#include <string>

namespace viscera {

using RigidTransform = Eigen::Isometry3d;

// Reads a transform file. Throws viscera::Error "file:line: what" for unreadable files, a wrong
// count of numbers, non-finite values, a last row other than 0 0 0 1 or a matrix that is not a
// rotation.
RigidTransform readTransform(const std::string& path);
// Parses the text of a transform file; `source` names it in messages.
RigidTransform parseTransform(const std::string& text, const std::string& source);
// Writes `T` atomically, with `comment` (may hold several lines) as '#' lines before the matrix.
void writeTransform(const std::string& path, const RigidTransform& T, const std::string& comment = "");
// The file's text for `T` (17 significant digits, so it reads back bit-exact).
std::string formatTransform(const RigidTransform& T, const std::string& comment = "");

}  // namespace viscera
