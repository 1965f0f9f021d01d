#include "io/scene/Transform.h"
#include "core/Files.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <vector>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "core/Text.h"

namespace viscera {

RigidTransform parseTransform(const std::string& raw, const std::string& source) {
  std::istringstream in(plainText(raw));
  std::string line;
  std::vector<double> v;
  std::vector<int> lineOf;
  int lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::string tok;
    while (ls >> tok) {
      double d = 0;
      if (!parseNumber(tok, d))
        throw Error(SourceLoc{source, lineNo, 0}, "transform: '" + tok + "' is not a number");
      if (!std::isfinite(d)) throw Error(SourceLoc{source, lineNo, 0}, "transform: '" + tok + "' is not finite");
      v.push_back(d);
      lineOf.push_back(lineNo);
    }
  }
  if (v.size() != 16)
    throw Error(SourceLoc{source, 0, 0}, "transform: expected 16 numbers (a 4 x 4 matrix, row by row), found " + std::to_string(v.size()));
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) M(r, c) = v[4 * r + c];
  if ((M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    throw Error(SourceLoc{source, lineOf[12], 0}, "transform: the last row must be 0 0 0 1");
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  const double orth = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orth > 1e-6 || R.determinant() < 0)
    throw Error(SourceLoc{source, lineOf[0], 0},
                "transform: the upper-left 3 x 3 block is not a rotation (|R^T R - I| = " + std::to_string(orth) +
                    ", det = " + std::to_string(R.determinant()) + "); only rigid transforms are accepted");
  RigidTransform T = RigidTransform::Identity();
  // Re-orthonormalise so that small rounding in hand-written files does not accumulate.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  T.linear() = orth == 0.0 ? R : Eigen::Matrix3d(svd.matrixU() * svd.matrixV().transpose());
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

RigidTransform readTransform(const std::string& path) {
  return parseTransform(readInputFile(path, "transform file"), path);
}

std::string formatTransform(const RigidTransform& T, const std::string& comment) {
  std::string out;
  std::istringstream cs(comment);
  std::string line;
  while (std::getline(cs, line)) out += "# " + line + "\n";
  const Eigen::Matrix4d M = T.matrix();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (c) out += ' ';
      out += formatNumber(r == 3 ? (c == 3 ? 1.0 : 0.0) : M(r, c));
    }
    out += "\n";
  }
  return out;
}

void writeTransform(const std::string& path, const RigidTransform& T, const std::string& comment) {
  writeFileAtomic(path, formatTransform(T, comment));
}

}  // namespace viscera
