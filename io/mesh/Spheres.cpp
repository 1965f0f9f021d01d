#include "io/mesh/Spheres.h"

#include <cmath>
#include <sstream>

#include "core/Error.h"
#include "core/Files.h"
#include "core/Text.h"

namespace viscera::io {

SphereSet readSpheres(const std::string& path) {
  const std::string text = plainText(readInputFile(path, "sphere file"));
  std::istringstream in(text);
  std::string line;
  int lineNo = 0;
  long long announced = -1;
  std::vector<double> xyz;
  SphereSet s;
  auto fail = [&](const std::string& why) { return Error(SourceLoc{path, lineNo, 0}, why); };
  bool header = false;
  while (std::getline(in, line)) {
    ++lineNo;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (const size_t hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream words(line);
    std::string key;
    if (!(words >> key)) continue;
    if (!header) {
      if (key != "sph") throw fail("not a sphere file: the first line must be \"sph 1.0\", got '" + printable(key, 40) + "'");
      header = true;
      continue;
    }
    std::vector<std::string> rest;
    for (std::string w; words >> w;) rest.push_back(w);
    if (key == "nums") {
      if (rest.size() != 1 || !parseInteger(rest[0], announced) || announced < 0)
        throw fail("\"nums\" takes one whole number, the sphere count");
      if (announced > 100000000) throw fail("\"nums\" announces more than 100 million spheres");
    } else if (key == "sphe") {
      if (rest.size() != 5) throw fail("\"sphe\" takes an index, the centre x y z and the radius (5 numbers), got " + std::to_string(rest.size()));
      double v[4];
      for (int k = 0; k < 4; ++k)
        if (!parseNumber(rest[k + 1], v[k]) || !std::isfinite(v[k]))
          throw fail("'" + printable(rest[k + 1], 40) + "' is not a finite number");
      if (!(v[3] > 0)) throw fail("a sphere radius must be positive, got " + rest[4]);
      xyz.insert(xyz.end(), v, v + 3);
      s.radii.push_back(v[3]);
    } else {
      throw fail("unknown keyword '" + printable(key, 40) + "' (a sphere file has sph, nums and sphe lines)");
    }
  }
  if (!header) throw Error(SourceLoc{path, 0, 0}, "empty sphere file");
  if (s.radii.empty()) throw Error(SourceLoc{path, 0, 0}, "the sphere file has no \"sphe\" lines");
  if (announced >= 0 && announced != static_cast<long long>(s.radii.size()))
    throw Error(SourceLoc{path, 0, 0}, "\"nums\" announces " + std::to_string(announced) + " spheres but the file has " +
                                           std::to_string(s.radii.size()));
  s.centres = Eigen::Map<const Eigen::Matrix3Xd>(xyz.data(), 3, static_cast<Eigen::Index>(s.radii.size()));
  return s;
}

}  // namespace viscera::io
