// `viscera register icp`: camera -> scene by ICP of a rest-state cloud to the tissue's surface;
// `viscera register points`: robot -> scene from corresponding points. Both write a transform file
// that scenes reference (TrajectoryDriver.transform) and, on request, a JSON report.
#include "apps/viscera/RegisterCommand.h"
#include "core/Files.h"
#include "apps/viscera/CliText.h"

#include <CLI/CLI.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "core/Error.h"
#include "observation/Registration.h"
#include "observation/SurfaceIndex.h"
#include "io/mesh/Mesh.h"
#include "io/pointcloud/CloudIo.h"
#include "io/scene/Transform.h"

namespace viscera {
namespace {

using cli::jsonString;

namespace fs = std::filesystem;

struct IcpCommandOptions {
  std::string cloud, mesh, init, initTranslation, initRotation, out, report, aligned;
  obs::IcpOptions icp;
};

struct PointsCommandOptions {
  std::string source, target, out, report;
};

// ---------------------------------------------------------------------------------------------
// Parsing and formatting of option values, summaries and JSON

// Three finite numbers "a b c" (blanks or commas between) given to `option`.
Eigen::Vector3d parseVector3(const std::string& text, const std::string& option, const char* meaning) {
  const auto v = cli::finiteNumbers(text, option, 3, meaning);
  return {v[0], v[1], v[2]};
}

std::string number(double v, int digits = 6) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

// A JSON number (null for infinities and NaN, which JSON cannot hold).
std::string jsonNumber(double v, int digits = 10) { return std::isfinite(v) ? number(v, digits) : "null"; }

std::string jsonVector(const Eigen::Ref<const Eigen::VectorXd>& v, int digits = 10) {
  std::string o = "[";
  for (Eigen::Index i = 0; i < v.size(); ++i) o += (i ? ", " : "") + jsonNumber(v(i), digits);
  return o + "]";
}

std::string jsonMatrix(const RigidTransform& T) {
  const Eigen::Matrix4d M = T.matrix();
  std::string o = "[";
  for (int r = 0; r < 4; ++r) o += std::string(r ? ",\n    " : "\n    ") + jsonVector(M.row(r).transpose(), 17);
  return o + "\n  ]";
}

// Rotation angle (degrees) of T and its axis, for the summaries.
std::string describeRotation(const RigidTransform& T) {
  const Eigen::AngleAxisd aa(T.linear());
  const Eigen::Vector3d axis = aa.angle() > 0 ? aa.axis() : Eigen::Vector3d::UnitZ();
  return number(aa.angle() * 180 / M_PI, 4) + " deg about (" + number(axis.x(), 3) + ", " + number(axis.y(), 3) + ", " +
         number(axis.z(), 3) + ")";
}

std::string describeTranslation(const Eigen::Vector3d& t) {
  return "(" + number(t.x(), 6) + ", " + number(t.y(), 6) + ", " + number(t.z(), 6) + ")";
}

// The outputs are checked before any work so that a bad path cannot leave some written and others
// not: the folder must exist and the path must not be a folder; no two outputs may coincide.
void checkOutputs(const std::vector<std::pair<std::string, std::string>>& outputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const auto& [option, path] = outputs[i];
    if (path.empty()) continue;
    const fs::path p(path);
    const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) throw Error(option + ": the folder '" + dir.string() + "' does not exist");
    if (fs::is_directory(p, ec)) throw Error(option + ": '" + path + "' is a folder, expected a file name");
    for (size_t j = 0; j < i; ++j)
      if (!outputs[j].second.empty() && fs::weakly_canonical(outputs[j].second, ec) == fs::weakly_canonical(p, ec))
        throw Error(option + ": '" + path + "' is also given to " + outputs[j].first);
  }
}

// ---------------------------------------------------------------------------------------------
// icp

// The triangle surface of a mesh file: the boundary of its tetrahedra, or its triangles when it
// has no tetrahedra (a surface mesh).
obs::SurfaceIndex loadSurface(const std::string& path) {
  const io::VolumeMesh mesh = io::readVolumeMesh(path);
  if (mesh.tets.cols() > 0) {
    io::checkTetMesh(mesh, path);
    return obs::SurfaceIndex(mesh.points, obs::boundaryTriangles(mesh.tets, mesh.points));
  }
  if (mesh.triangles.cols() > 0) return obs::SurfaceIndex(mesh.points, mesh.triangles);
  throw Error(SourceLoc{path}, "the mesh has neither tetrahedra nor triangles: no surface to register to");
}

RigidTransform initialTransform(const IcpCommandOptions& o) {
  if (!o.init.empty()) return readTransform(o.init);
  RigidTransform T = RigidTransform::Identity();
  if (!o.initRotation.empty()) {
    // As the scenes' `rotation`: degrees about x, then y, then z.
    const Eigen::Vector3d r = parseVector3(o.initRotation, "--init-rotation", "rx ry rz") * (M_PI / 180);
    T.linear() = (Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
  }
  if (!o.initTranslation.empty()) T.translation() = parseVector3(o.initTranslation, "--init-translation", "x y z");
  return T;
}

void checkIcpOptions(const obs::IcpOptions& o) {
  if (!(o.maxDistance > 0)) throw Error("--max-distance: must be > 0, got " + number(o.maxDistance));
  if (!(o.trim > 0 && o.trim <= 1)) throw Error("--trim: must be in (0, 1], got " + number(o.trim));
  if (o.maxIterations < 1) throw Error("--iterations: must be >= 1, got " + std::to_string(o.maxIterations));
  if (!(o.shrinkFactor >= 0) || std::isinf(o.shrinkFactor)) throw Error("--shrink: must be a finite number >= 0, got " + number(o.shrinkFactor));
}

std::string icpCommandLine(const IcpCommandOptions& o) {
  std::string c = "viscera register icp --cloud " + o.cloud + " --mesh " + o.mesh;
  if (!o.init.empty()) c += " --init " + o.init;
  if (!o.initTranslation.empty()) c += " --init-translation \"" + o.initTranslation + "\"";
  if (!o.initRotation.empty()) c += " --init-rotation \"" + o.initRotation + "\"";
  if (std::isfinite(o.icp.maxDistance)) c += " --max-distance " + number(o.icp.maxDistance);
  c += " --trim " + number(o.icp.trim) + " --shrink " + number(o.icp.shrinkFactor) + " --iterations " + std::to_string(o.icp.maxIterations);
  return c;
}

std::string icpReport(const IcpCommandOptions& o, const RigidTransform& initial, const obs::IcpResult& r, int cloudPoints) {
  std::ostringstream j;
  j << "{\n  \"method\": \"icp\",\n";
  j << "  \"cloud\": " << jsonString(o.cloud) << ",\n  \"mesh\": " << jsonString(o.mesh) << ",\n";
  j << "  \"transform\": " << jsonMatrix(r.transform) << ",\n";
  j << "  \"initial\": " << jsonMatrix(initial) << ",\n";
  j << "  \"iterations\": " << r.iterations << ",\n  \"converged\": " << (r.converged ? "true" : "false") << ",\n";
  j << "  \"point_to_point_iterations\": " << r.pointToPointIterations << ",\n";
  j << "  \"cloud_points\": " << cloudPoints << ",\n  \"pairs\": " << r.pairs << ",\n";
  j << "  \"kept_fraction\": " << jsonNumber(r.keptFraction) << ",\n";
  j << "  \"max_distance\": " << jsonNumber(r.finalMaxDistance) << ",\n";
  j << "  \"rms\": " << jsonNumber(r.rms) << ",\n  \"mean\": " << jsonNumber(r.mean) << ",\n  \"max\": " << jsonNumber(r.max) << ",\n";
  j << "  \"condition_ratio\": " << jsonNumber(r.conditionRatio) << ",\n";
  j << "  \"eigenvalues\": " << jsonVector(r.eigenvalues) << ",\n";
  j << "  \"degenerate\": " << (r.degenerate ? "true" : "false") << ",\n";
  j << "  \"centroid\": " << jsonVector(r.centroid) << ",\n";
  j << "  \"weak_directions\": [";
  for (size_t k = 0; k < r.weakDirections.size(); ++k) {
    const auto& d = r.weakDirections[k];
    j << (k ? "," : "") << "\n    {\"rotation\": " << jsonVector(d.rotation) << ", \"translation\": " << jsonVector(d.translation)
      << ", \"ratio\": " << jsonNumber(d.ratio) << ", \"description\": " << jsonString(d.describe()) << "}";
  }
  j << (r.weakDirections.empty() ? "]" : "\n  ]") << ",\n";
  j << "  \"options\": {\"trim\": " << jsonNumber(o.icp.trim) << ", \"max_distance\": " << jsonNumber(o.icp.maxDistance)
    << ", \"shrink\": " << jsonNumber(o.icp.shrinkFactor) << ", \"iterations\": " << o.icp.maxIterations
    << ", \"tolerance\": " << jsonNumber(o.icp.tolerance) << ", \"degeneracy_ratio\": " << jsonNumber(o.icp.degeneracyRatio) << "}\n";
  j << "}\n";
  return j.str();
}

int runIcp(const IcpCommandOptions& o) {
  checkIcpOptions(o.icp);
  checkOutputs({{"--out", o.out}, {"--report", o.report}, {"--aligned", o.aligned}});
  const RigidTransform initial = initialTransform(o);
  const obs::SurfaceIndex surface = loadSurface(o.mesh);
  const cloud::PointCloud pc = cloud::readCloud(o.cloud);
  const obs::IcpResult r = obs::registerIcp(pc.points, surface, initial, o.icp, o.cloud);

  std::ostringstream summary;
  summary << "ICP " << (r.converged ? "converged" : "did NOT converge") << " after " << r.iterations << " iteration"
          << (r.iterations == 1 ? "" : "s");
  if (r.pointToPointIterations > 0) summary << " (" << r.pointToPointIterations << " point-to-point)";
  summary << "\n  pairs kept: " << r.pairs << " of " << pc.size() << " (" << number(100 * r.keptFraction, 4)
          << " %), max distance " << number(r.finalMaxDistance, 4) << "\n";
  summary << "  residual distance: RMS " << number(r.rms, 4) << ", mean " << number(r.mean, 4) << ", max " << number(r.max, 4) << "\n";
  summary << "  condition: " << number(r.conditionRatio, 3) << " (smallest / largest eigenvalue of the point-to-plane system)\n";
  summary << "  camera -> scene: rotation " << describeRotation(r.transform) << ", translation "
          << describeTranslation(r.transform.translation()) << "\n";
  std::cout << summary.str();
  if (!r.converged)
    std::cerr << "warning: ICP stopped at --iterations " << o.icp.maxIterations << " before the steps fell below the tolerance\n";
  if (r.degenerate) {
    std::cerr << "warning: the registration is under-constrained (condition " << number(r.conditionRatio, 3) << " < "
              << number(o.icp.degeneracyRatio, 3) << "): along these directions the result comes from the initial transform:\n";
    for (const auto& d : r.weakDirections) std::cerr << "  " << d.describe() << "\n";
  }

  std::string comment = "camera -> scene by ICP: " + icpCommandLine(o) + "\n" + "residual distance over " + std::to_string(r.pairs) +
                        " kept pairs: RMS " + number(r.rms) + ", mean " + number(r.mean) + ", max " + number(r.max) + "; " +
                        std::to_string(r.iterations) + " iterations, " + (r.converged ? "converged" : "not converged") +
                        ", condition " + number(r.conditionRatio, 3) + (r.degenerate ? " (under-constrained)" : "");
  writeTransform(o.out, r.transform, comment);
  if (!o.report.empty()) writeFileAtomic(o.report, icpReport(o, initial, r, pc.size()));
  if (!o.aligned.empty()) {
    io::DataArray residual{"residual", 1, std::vector<double>(r.distances.data(), r.distances.data() + r.distances.size())};
    io::DataArray kept{"kept", 1, std::vector<double>(r.kept.begin(), r.kept.end())};
    const Eigen::Matrix3Xd aligned = r.transform * pc.points;
    io::writeVtp(o.aligned, aligned, Eigen::Matrix<int, 3, Eigen::Dynamic>(3, 0), true, {residual, kept});
  }
  std::cerr << "wrote " << o.out << (o.report.empty() ? "" : ", " + o.report) << (o.aligned.empty() ? "" : ", " + o.aligned) << "\n";
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// points

std::string pointsReport(const PointsCommandOptions& o, const obs::PointRegistration& r, const std::vector<std::string>& labels,
                         const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target) {
  std::ostringstream j;
  j << "{\n  \"method\": \"points\",\n";
  j << "  \"source\": " << jsonString(o.source) << ",\n  \"target\": " << jsonString(o.target) << ",\n";
  j << "  \"transform\": " << jsonMatrix(r.transform) << ",\n";
  j << "  \"rms\": " << jsonNumber(r.rms) << ",\n  \"max\": " << jsonNumber(r.max) << ",\n";
  j << "  \"points\": [";
  for (Eigen::Index i = 0; i < source.cols(); ++i)
    j << (i ? "," : "") << "\n    {\"name\": " << jsonString(labels[static_cast<size_t>(i)]) << ", \"source\": "
      << jsonVector(source.col(i)) << ", \"target\": " << jsonVector(target.col(i)) << ", \"residual\": "
      << jsonVector(r.residuals.col(i)) << ", \"norm\": " << jsonNumber(r.norms(i)) << "}";
  j << "\n  ]\n}\n";
  return j.str();
}

int runPoints(const PointsCommandOptions& o) {
  checkOutputs({{"--out", o.out}, {"--report", o.report}});
  const obs::PointList src = obs::readPointList(o.source);
  const obs::PointList dst = obs::readPointList(o.target);
  Eigen::Matrix3Xd S, D;
  std::vector<std::string> labels;
  obs::pairPoints(src, dst, S, D, labels);
  const obs::PointRegistration r = obs::registerPoints(S, D, o.source, o.target);

  // The residual table: T source_i - target_i per pair.
  size_t width = 5;
  for (const auto& l : labels) width = std::max(width, l.size());
  std::ostringstream table;
  char buf[160];
  std::snprintf(buf, sizeof buf, "%-*s %12s %12s %12s %12s\n", static_cast<int>(width), "point", "dx", "dy", "dz", "|r|");
  table << buf;
  for (Eigen::Index i = 0; i < S.cols(); ++i) {
    std::snprintf(buf, sizeof buf, "%-*s %12.6g %12.6g %12.6g %12.6g\n", static_cast<int>(width), labels[static_cast<size_t>(i)].c_str(),
                  r.residuals(0, i), r.residuals(1, i), r.residuals(2, i), r.norms(i));
    table << buf;
  }
  table << "RMS " << number(r.rms) << ", max " << number(r.max) << " over " << S.cols() << " points\n";
  table << "source -> target: rotation " << describeRotation(r.transform) << ", translation "
        << describeTranslation(r.transform.translation()) << "\n";
  std::cout << table.str();

  std::string comment = "robot -> scene from " + std::to_string(S.cols()) + " corresponding points: viscera register points --source " +
                        o.source + " --target " + o.target + "\nresidual |T source - target|: RMS " + number(r.rms) + ", max " +
                        number(r.max) + "; per point:";
  for (Eigen::Index i = 0; i < S.cols(); ++i) comment += " " + labels[static_cast<size_t>(i)] + " " + number(r.norms(i));
  writeTransform(o.out, r.transform, comment);
  if (!o.report.empty()) writeFileAtomic(o.report, pointsReport(o, r, labels, S, D));
  std::cerr << "wrote " << o.out << (o.report.empty() ? "" : ", " + o.report) << "\n";
  return kExitOk;
}

}  // namespace

void addRegisterCommand(CLI::App& app, std::function<int()>& action) {
  auto* cmd = app.add_subcommand("register", "rigid registration: camera -> scene (ICP) or robot -> scene (points)");
  cmd->require_subcommand(1);

  auto io = std::make_shared<IcpCommandOptions>();
  auto* icp = cmd->add_subcommand("icp", "register a rest-state point cloud to the surface of a mesh (camera -> scene)");
  icp->footer(
      "Point-to-plane ICP against the exact closest points of the mesh's surface (the boundary of its tetrahedra),\n"
      "trimmed, from an initial camera -> scene transform. The cloud and the mesh must use the same length unit.\n"
      "A flat, featureless view (one face) leaves directions unconstrained: they keep the initial guess, and a\n"
      "warning names them.");
  icp->add_option("--cloud", io->cloud, "rest-state point cloud, camera frame (.pcd or .ply)")->required();
  icp->add_option("--mesh", io->mesh, "the tissue mesh, scene frame (.vtu, .vtk, .msh, or an .exo series' first frame; tetrahedra or triangles)")->required();
  auto* init = icp->add_option("--init", io->init, "initial camera -> scene transform file");
  icp->add_option("--init-translation", io->initTranslation, "initial translation \"x y z\" (instead of --init)")->excludes(init);
  icp->add_option("--init-rotation", io->initRotation, "initial rotation \"rx ry rz\", degrees about x, then y, then z (instead of --init)")
      ->excludes(init);
  icp->add_option("--max-distance", io->icp.maxDistance, "ignore points farther than this from the surface (default: no limit)");
  icp->add_option("--trim", io->icp.trim, "fraction of the pairs kept, the closest ones, in (0, 1]")->capture_default_str();
  icp->add_option("--shrink", io->icp.shrinkFactor, "after each iteration the max distance becomes at most this x the RMS residual (0: fixed)")
      ->capture_default_str();
  icp->add_option("--iterations", io->icp.maxIterations, "maximum number of iterations")->capture_default_str();
  icp->add_option("--out", io->out, "transform file to write (camera -> scene)")->required();
  icp->add_option("--report", io->report, "write a JSON report (residuals, conditioning, weak directions)");
  icp->add_option("--aligned", io->aligned, "write the transformed cloud as .vtp with point fields residual and kept");
  icp->callback([io, &action] { action = [io] { return runIcp(*io); }; });

  auto po = std::make_shared<PointsCommandOptions>();
  auto* points = cmd->add_subcommand("points", "rigid transform from corresponding points (robot -> scene)");
  points->footer(
      "CSV files: an optional header, then x,y,z or name,x,y,z per line ('#' comments). With names in both files the\n"
      "points pair by name, otherwise by order. At least 3 points, not on one line.");
  points->add_option("--source", po->source, "points in the source frame, e.g. the robot's (CSV)")->required();
  points->add_option("--target", po->target, "the same points in the target frame, e.g. the scene's (CSV)")->required();
  points->add_option("--out", po->out, "transform file to write (source -> target)")->required();
  points->add_option("--report", po->report, "write a JSON report (per-point residuals)");
  points->callback([po, &action] { action = [po] { return runPoints(*po); }; });
}

}  // namespace viscera
