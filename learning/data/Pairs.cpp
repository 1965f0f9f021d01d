#include "learning/data/Pairs.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/Error.h"
#include "core/Files.h"

namespace viscera::learning {

namespace fs = std::filesystem;

GridShape checkGrid(const RestMesh& mesh, const GridShape& g, const std::string& what) {
  if (g.nx < 2 || g.ny < 2 || g.nz < 2) throw Error(what + ": a grid needs at least 2 nodes along each axis");
  if (g.nodes() != mesh.points.cols())
    throw Error(what + ": a " + std::to_string(g.nx) + " x " + std::to_string(g.ny) + " x " + std::to_string(g.nz) + " grid has " +
                std::to_string(g.nodes()) + " nodes, the body " + std::to_string(mesh.points.cols()));
  const Eigen::Vector3d o = mesh.points.col(0);
  const Eigen::Vector3d h((mesh.points.col(g.index(g.nx - 1, 0, 0)) - o).x() / (g.nx - 1),
                          (mesh.points.col(g.index(0, g.ny - 1, 0)) - o).y() / (g.ny - 1),
                          (mesh.points.col(g.index(0, 0, g.nz - 1)) - o).z() / (g.nz - 1));
  const double tol = 1e-6 * h.cwiseAbs().maxCoeff();
  for (int k = 0; k < g.nz; ++k)
    for (int j = 0; j < g.ny; ++j)
      for (int i = 0; i < g.nx; ++i)
        if ((mesh.points.col(g.index(i, j, k)) - (o + Eigen::Vector3d(i * h.x(), j * h.y(), k * h.z()))).norm() > tol)
          throw Error(what + ": node " + std::to_string(g.index(i, j, k)) + " is not at grid place (" + std::to_string(i) + ", " +
                      std::to_string(j) + ", " + std::to_string(k) + "): the body's nodes are not a regular grid in SOFA's order");
  return g;
}

std::optional<GridShape> gridOf(const RestMesh& mesh) {
  if (mesh.points.cols() < 8) return std::nullopt;
  int counts[3];
  for (int a = 0; a < 3; ++a) {
    std::vector<double> v(mesh.points.cols());
    for (Eigen::Index i = 0; i < mesh.points.cols(); ++i) v[i] = mesh.points(a, i);
    std::sort(v.begin(), v.end());
    const double tol = 1e-9 * std::max(1.0, std::abs(v.back() - v.front()));
    counts[a] = 1;
    for (size_t i = 1; i < v.size(); ++i) counts[a] += v[i] - v[i - 1] > tol;
  }
  const GridShape g{counts[0], counts[1], counts[2]};
  try {
    checkGrid(mesh, g, "grid");
  } catch (const Error&) {
    return std::nullopt;
  }
  return g;
}

void writePairSet(const std::string& folder, const PairSet& p) {
  const fs::path dir(folder);
  writeRestMesh((dir / "mesh.bin").string(), p.mesh);
  {
    RolloutWriter w((dir / "states.bin").string(), static_cast<int>(p.mesh.points.cols()));
    for (const RolloutFrame& f : p.states) w.add(f);
    w.close();
  }
  writeCloudFrames((dir / "clouds.bin").string(), p.clouds);
  nlohmann::ordered_json j;
  j["format"] = "viscera correction pairs";
  j["version"] = 1;
  j["scene"] = p.scene;
  j["dataset"] = p.dataset;
  j["units"] = p.units;
  j["grid"] = {p.grid.nx, p.grid.ny, p.grid.nz};
  j["viewDirection"] = {p.viewDirection.x(), p.viewDirection.y(), p.viewDirection.z()};
  j["frames"] = p.states.size();
  j["files"] = {{"mesh", "mesh.bin"}, {"states", "states.bin"}, {"clouds", "clouds.bin"}};
  writeFileAtomic((dir / "pairs.json").string(), j.dump(2) + "\n");
}

bool isPairFolder(const std::string& folder) { return fs::exists(fs::path(folder) / "pairs.json"); }

PairSet readPairSet(const std::string& folder) {
  const std::string indexPath = (fs::path(folder) / "pairs.json").string();
  PairSet p;
  p.folder = folder;
  try {
    const auto j = nlohmann::json::parse(readInputFile(indexPath, "pair index"));
    if (j.at("format").get<std::string>() != "viscera correction pairs")
      throw Error(SourceLoc{indexPath}, "format is not \"viscera correction pairs\"");
    p.scene = j.at("scene").get<std::string>();
    p.dataset = j.at("dataset").get<std::string>();
    p.units = j.at("units").get<std::string>();
    const auto& g = j.at("grid");
    p.grid = {g.at(0).get<int>(), g.at(1).get<int>(), g.at(2).get<int>()};
    const auto& v = j.at("viewDirection");
    p.viewDirection = Eigen::Vector3d(v.at(0).get<double>(), v.at(1).get<double>(), v.at(2).get<double>());
    if (!(p.viewDirection.norm() > 0)) throw Error(SourceLoc{indexPath}, "viewDirection must not be zero");
    p.viewDirection.normalize();
  } catch (const nlohmann::json::exception& e) {
    throw Error(SourceLoc{indexPath}, std::string("malformed pair index: ") + e.what());
  }
  p.mesh = readRestMesh((fs::path(folder) / "mesh.bin").string());
  checkGrid(p.mesh, p.grid, indexPath);
  p.states = readRollout((fs::path(folder) / "states.bin").string(), static_cast<int>(p.mesh.points.cols()));
  p.clouds = readCloudFrames((fs::path(folder) / "clouds.bin").string());
  if (p.clouds.size() != p.states.size())
    throw Error(SourceLoc{folder}, "clouds.bin holds " + std::to_string(p.clouds.size()) + " frames, states.bin " +
                                       std::to_string(p.states.size()));
  return p;
}

}  // namespace viscera::learning
