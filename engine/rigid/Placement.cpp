#include "engine/rigid/Placement.h"

#include <cmath>

#include "core/Component.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "io/scene/InputCache.h"
#include "io/scene/Transform.h"

namespace viscera {

void addPlacementAttributes(ComponentSpec& s, const std::string& what) {
  s.add(AttrSpec::file("transform").help("rigid transform file (4 x 4 matrix, robot -> scene, translation in the scene's "
                                          "length unit) applied to " + what + " first, before `rotation` and `translation`"));
  s.add(AttrSpec::reals("translation", 3).def("0 0 0").unit(Dimension::length()).help("translation applied to " + what + ", after the rotation"));
  s.add(AttrSpec::reals("rotation", 3).def("0 0 0").help("rotation in degrees about x, then y, then z, applied to " + what + " after `transform`"));
}

Placement readPlacement(const Component& c) {
  const Attributes& attrs = c.attrs();
  const auto& r = attrs.reals("rotation");
  const auto& t = attrs.reals("translation");
  const Eigen::Quaterniond placeR = Eigen::AngleAxisd(r[2] * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(r[1] * M_PI / 180, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(r[0] * M_PI / 180, Eigen::Vector3d::UnitX());
  RigidTransform file = RigidTransform::Identity();
  if (attrs.isSet("transform")) {
    const std::string path = c.scene().resolvePath(attrs.str("transform"));
    try {
      file = *io::cachedRead<RigidTransform>(path, readTransform);
    } catch (const Error& e) {
      throw fileErrorFor(e, c, "transform");
    }
  }
  Placement p;
  p.R = placeR * Eigen::Quaterniond(file.linear());
  p.T = placeR * file.translation() + Eigen::Vector3d(t[0], t[1], t[2]);
  return p;
}

Error fileErrorFor(const Error& e, const Component& c, const std::string& attr) {
  const std::string what = std::string(e.what()).substr(e.where().known() ? e.where().str().size() + 2 : 0);
  return Error(e.where(), what + " (read for " + c.attrs().loc(attr).str() + ": " + c.typeName() + "." + attr + ")");
}

Eigen::Vector3d rotationVector(const Eigen::Quaterniond& from, const Eigen::Quaterniond& to) {
  Eigen::Quaterniond dq = to * from.conjugate();
  if (dq.w() < 0) dq.coeffs() *= -1;
  const double s = dq.vec().norm();
  if (!(s > 1e-12)) return dq.vec() * (2 / dq.w());  // small angle: angle / s -> 2 / w
  return dq.vec() * (2 * std::atan2(s, dq.w()) / s);
}

}  // namespace viscera
