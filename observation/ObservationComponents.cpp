// Observation components: DepthCamera, a virtual RealSense-like depth camera that watches the
// scene (the tissue's boundary surfaces and the instrument spheres) and writes point-cloud frames.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "engine/Roles.h"
#include "engine/collision/Collision.h"
#include "core/Registry.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "observation/DepthCamera.h"
#include "observation/SurfaceIndex.h"
#include "observation/Tissue.h"
#include "engine/rigid/Placement.h"
#include "io/pointcloud/CloudIo.h"
#include "io/scene/Transform.h"

namespace viscera {

namespace {

std::string vecText(const Eigen::Vector3d& v) {
  std::ostringstream o;
  o << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return o.str();
}

class DepthCameraComponent : public Component, public Observer {
 public:
  using Component::Component;

  void init() override {
    const Eigen::Vector3d position = placeCamera();
    const obs::CameraIntrinsics k = intrinsics();
    near_ = attrs_.real("near");
    far_ = attrs_.real("far");
    asAttributeError([&] { camera_ = std::make_unique<obs::DepthCamera>(k, pose_, near_, far_); });

    noise_.sigma0 = attrs_.real("sigma0");
    noise_.z0 = attrs_.real("z0");
    noise_.dropout = attrs_.real("dropout");
    noise_.grazingAngleDeg = attrs_.real("grazingAngle");
    noise_.depthUnit = attrs_.real("depthUnit");
    noise_.seed = static_cast<std::uint64_t>(attrs_.integer("seed"));
    asAttributeError([&] { noise_.validate(); });
    options_.stride = static_cast<int>(attrs_.integer("stride"));
    options_.frame = attrs_.str("frame") == "scene" ? obs::PointFrame::Scene : obs::PointFrame::Camera;

    // Labels: the deformable bodies first (in scene order), then the spheres, then the table.
    for (obs::TissueSurface& b : obs::tissueSurfaces(scene())) {
      MechanicalObject* state = b.state;
      const double w = obs::windingNumber(state->xInit, b.triangles, position);
      if (std::abs(w) > 0.5)
        throw error(poseAttr(), "the camera at " + vecText(position) + " is inside the body of '" + state->name() +
                                    "' (" + state->node().path() + "); place it outside, looking at the tissue");
      bodies_.push_back(std::move(b));
      if (attrs_.boolean("tissueOnly")) options_.labels.push_back(static_cast<int>(bodies_.size()) - 1);
    }
    for (SphereCollisionModel* s : scene().all<SphereCollisionModel>()) {
      scene().initComponent(*s);
      spheres_.push_back(s);
    }
    if (attrs_.isSet("table")) {
      const auto& t = attrs_.reals("table");
      obs::PlaneInput plane;
      plane.normal = Eigen::Vector3d(t[0], t[1], t[2]);
      if (!(plane.normal.norm() > 0)) throw error("table", "the plane's normal (the first three numbers) is zero");
      plane.offset = t[3];
      plane.label = static_cast<int>(bodies_.size() + spheres_.size());
      table_ = plane;
    }
    if (bodies_.empty() && spheres_.empty() && !table_)
      throw error("has nothing to see: the scene has no deformable body with tetrahedra, no SphereCollisionModel "
                  "and no `table`");
    if (attrs_.boolean("tissueOnly") && bodies_.empty())
      throw error("tissueOnly", "the scene has no deformable body with tetrahedra, so every frame would be empty");
    checkInView();

    rate_ = attrs_.real("rate");
    if (1.0 / rate_ < scene().dt() * (1 - 1e-9))
      scene().addNote(loc().str() + ": note: DepthCamera '" + name() + "': the frame period 1/rate is shorter than " +
                      "the time step; frames are taken at most once per step");

    extension_ = attrs_.str("format");
    encoding_ = attrs_.boolean("binary") ? cloud::CloudEncoding::Binary : cloud::CloudEncoding::Ascii;
    folderName_ = attrs_.isSet("filename") ? attrs_.str("filename") : name();
    if (folderName_.empty()) throw error("filename", "is empty; name the folder the frames go to");
    if (scene().escapesOutputFolder(folderName_))
      throw error("filename", "'" + folderName_ + "' would be written outside the output folder (--out); give a name inside it");
    for (DepthCameraComponent* cam : scene().all<DepthCameraComponent>()) {
      if (cam == this || !cam->initialized()) continue;
      if (std::filesystem::path(cam->folderName_).lexically_normal() == std::filesystem::path(folderName_).lexically_normal())
        throw error("filename", "'" + folderName_ + "' is also the folder of DepthCamera '" + cam->name() + "' (" +
                                    cam->loc().str() + "); give each camera its own");
    }
  }

  void begin(const State& s, double t) override {
    // The writer creates the folder.
    writer_ = std::make_unique<cloud::CloudSequenceWriter>(scene().outputPath(folderName_), "frame", extension_, encoding_);
    t0_ = t;
    takeFrame(s, t, 0);
  }

  void observe(const State& s, double t, int) override {
    // Frame k is due at t0 + k / rate; it is taken at the first step time that reaches it. A
    // millionth of a step absorbs the rounding of the step times.
    const double slots = (t - t0_) * rate_ + 1e-6 * scene().dt() * rate_;
    if (slots < static_cast<double>(nextSlot_)) return;
    takeFrame(s, t, static_cast<std::uint64_t>(std::floor(slots)));
  }

  // "frames": the number of frames written; "points": the points of each; "emptyFrames": frames
  // that had no point (not written: a cloud file holds at least one); "cameraToScene": the pose
  // (16 numbers, row by row); "sceneFrame": 1 when the points are written in the scene frame.
  bool field(const std::string& n, FieldValue& out) const override {
    if (n == "frames") out.values = {static_cast<double>(pointCounts_.size())};
    else if (n == "points") out.values = pointCounts_;
    else if (n == "emptyFrames") out.values = {static_cast<double>(emptyFrames_)};
    else if (n == "cameraToScene") {  // the 4 x 4 pose, row by row
      out.values.clear();
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) out.values.push_back(pose_.matrix()(r, c));
    } else if (n == "sceneFrame") out.values = {options_.frame == obs::PointFrame::Scene ? 1.0 : 0.0};
    else return false;
    return true;
  }

 private:

  // The library reports "field: what is wrong"; the fields are named as this component's attributes.
  template <class F>
  void asAttributeError(F&& f) const {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      const std::string msg = e.what();
      const size_t colon = msg.find(": ");
      if (colon != std::string::npos && spec().find(msg.substr(0, colon)))
        throw error(msg.substr(0, colon), msg.substr(colon + 2));
      throw error(msg);
    }
  }

  const char* poseAttr() const { return attrs_.isSet("transform") ? "transform" : "position"; }

  // Sets pose_ from `transform` or from position, lookAt and up; returns the camera's position.
  Eigen::Vector3d placeCamera() {
    const bool byTransform = attrs_.isSet("transform");
    if (byTransform && (attrs_.isSet("position") || attrs_.isSet("lookAt") || attrs_.isSet("up")))
      throw error("transform", "give either `transform` or `position`, `lookAt` and `up`, not both");
    if (byTransform) {
      const std::string path = scene().resolvePath(attrs_.str("transform"));
      try {
        pose_ = readTransform(path);
      } catch (const Error& e) {
        throw fileErrorFor(e, *this, "transform");
      }
      return pose_.translation();
    }
    if (!attrs_.isSet("position") || !attrs_.isSet("lookAt"))
      throw error("needs `position` and `lookAt` (with `up`), or a `transform` file (camera -> scene)");
    const auto& p = attrs_.reals("position");
    const auto& l = attrs_.reals("lookAt");
    const auto& u = attrs_.reals("up");
    const Eigen::Vector3d position(p[0], p[1], p[2]);
    asAttributeError([&] { pose_ = obs::lookAtPose(position, Eigen::Vector3d(l[0], l[1], l[2]), Eigen::Vector3d(u[0], u[1], u[2])); });
    return position;
  }

  obs::CameraIntrinsics intrinsics() const {
    const bool byFocal = attrs_.isSet("fx") || attrs_.isSet("fy");
    if (byFocal && attrs_.isSet("fov")) throw error("fov", "give either `fov` or `fx`/`fy`, not both");
    const int width = static_cast<int>(attrs_.integer("width")), height = static_cast<int>(attrs_.integer("height"));
    obs::CameraIntrinsics k;
    asAttributeError([&] { k = obs::CameraIntrinsics::fromFov(width, height, attrs_.real("fov")); });
    if (byFocal) {
      k.fx = attrs_.isSet("fx") ? attrs_.real("fx") : attrs_.real("fy");
      k.fy = attrs_.isSet("fy") ? attrs_.real("fy") : attrs_.real("fx");
    }
    if (attrs_.isSet("cx")) k.cx = attrs_.real("cx");
    if (attrs_.isSet("cy")) k.cy = attrs_.real("cy");
    asAttributeError([&] { k.validate(); });
    return k;
  }

  // What the camera sees in state `st`, or at the start without one.
  obs::RenderInput renderInput(const State* st) const {
    obs::RenderInput in;
    for (size_t b = 0; b < bodies_.size(); ++b) {
      const MechanicalObject& m = *bodies_[b].state;
      in.surfaces.push_back({st ? &m.x(*st) : &m.xInit, &bodies_[b].triangles, static_cast<int>(b)});
    }
    if (st)
      for (size_t s = 0; s < spheres_.size(); ++s)
        in.spheres.push_back({spheres_[s]->centre(*st), spheres_[s]->radius(), static_cast<int>(bodies_.size() + s)});
    in.plane = table_;
    return in;
  }

  // A camera that sees none of the tissue (nor the table) at the start is misplaced: pointing
  // away, or with the tissue out of its range. The instruments are left out of this check: their
  // drivers may not have placed them yet.
  void checkInView() {
    if (bodies_.empty() && !table_) return;
    camera_->render(renderInput(nullptr), image_);
    if (std::any_of(image_.label.begin(), image_.label.end(), [](int l) { return l >= 0; })) return;
    const Eigen::Vector3d view = pose_.linear().col(2);
    std::ostringstream msg;
    msg << "nothing is in view at the start: the camera at " << vecText(pose_.translation()) << " looking along "
        << vecText(view) << " sees no tissue surface" << (table_ ? " and no table" : "") << " at depths between near = "
        << near_ << " and far = " << far_;
    throw error(poseAttr(), msg.str());
  }

  void takeFrame(const State& s, double t, std::uint64_t slot) {
    camera_->render(renderInput(&s), image_);
    obs::Capture c = camera_->capture(image_, noise_, slot, options_);
    nextSlot_ = slot + 1;
    if (c.cloud.empty()) {
      ++emptyFrames_;
      return;
    }
    const double seconds = t * scene().units().siOf(Dimension::time());
    c.cloud.time = seconds;
    writer_->add(c.cloud, seconds);
    pointCounts_.push_back(static_cast<double>(c.cloud.size()));
  }

  RigidTransform pose_ = RigidTransform::Identity();
  std::unique_ptr<obs::DepthCamera> camera_;
  double near_ = 0, far_ = 0;
  obs::DepthNoise noise_;
  obs::CaptureOptions options_;
  std::vector<obs::TissueSurface> bodies_;  // triangles outward at the start
  std::vector<SphereCollisionModel*> spheres_;
  std::optional<obs::PlaneInput> table_;
  double rate_ = 30, t0_ = 0;
  std::uint64_t nextSlot_ = 0;
  std::string folderName_, extension_;
  cloud::CloudEncoding encoding_ = cloud::CloudEncoding::Binary;
  std::unique_ptr<cloud::CloudSequenceWriter> writer_;
  obs::DepthImage image_;
  std::vector<double> pointCounts_;
  int emptyFrames_ = 0;
};

}  // namespace

void registerObservation(Registry& r) {
  ComponentSpec s;
  s.name = "DepthCamera";
  s.category = "sensor";
  s.doc =
      "A virtual depth camera (RealSense SR300-like) watching the scene: a pinhole camera that sees the boundary "
      "surface of every deformable body with tetrahedra at its current positions, every SphereCollisionModel (the "
      "instrument, which hides the tissue behind it) and optionally a table plane. Depth is exact per pixel (z-buffer "
      "with the exact ray intersection), then measured with noise: a pixel gives no point with probability `dropout` "
      "or when its ray meets the surface beyond `grazingAngle`; z gets Gaussian noise along the pixel's ray with "
      "sigma(z) = sigma0 (z / z0)^2 and is rounded to `depthUnit`. Frames are taken at the start and every 1/rate of "
      "simulated time (at the first step time that reaches each), and written as a cloud sequence: "
      "<filename>/frame_<k>.<format> and <filename>/index.csv (time in seconds, file) in the output folder (--out). "
      "Points are in the camera frame (x right, y down, z along the view) unless frame=\"scene\". The noise of frame "
      "k depends only on seed and k.";
  s.add(AttrSpec::reals("position", 3).unit(Dimension::length()).help("camera centre (scene frame); with lookAt and up"));
  s.add(AttrSpec::reals("lookAt", 3).unit(Dimension::length()).help("a point the camera looks at (on its optical axis)"));
  s.add(AttrSpec::reals("up", 3).def("0 0 1").help("scene direction that appears up in the image; must not be parallel to the view"));
  s.add(AttrSpec::file("transform").help(
      "camera -> scene transform file (4 x 4 matrix; camera looks along its +z, x right, y down), instead of "
      "position/lookAt/up"));
  s.add(AttrSpec::integer("width").def("640").atLeast(1).atMost(16384).help("image width in pixels"));
  s.add(AttrSpec::integer("height").def("480").atLeast(1).atMost(16384).help("image height in pixels"));
  s.add(AttrSpec::real("fov").def("60").above(0).below(180).help(
      "horizontal field of view in degrees (square pixels, principal point at the image centre)"));
  s.add(AttrSpec::real("fx").above(0).help("focal length in pixels, instead of fov (fy defaults to fx)"));
  s.add(AttrSpec::real("fy").above(0).help("vertical focal length in pixels (defaults to fx)"));
  s.add(AttrSpec::real("cx").help("principal point column in pixels (default (width - 1) / 2; pixel centres are integers)"));
  s.add(AttrSpec::real("cy").help("principal point row in pixels (default (height - 1) / 2)"));
  s.add(AttrSpec::real("near").def("0.2 m").above(0).unit(Dimension::length()).help(
      "nearest depth measured (SR300: 0.2 m); a nearer surface hides what is behind it but gives no point"));
  s.add(AttrSpec::real("far").def("1.5 m").above(0).unit(Dimension::length()).help("farthest depth measured (SR300: 1.5 m)"));
  s.add(AttrSpec::real("rate").def("30 Hz").above(0).unit(Dimension::frequency()).help(
      "frames per unit of simulated time, independent of the time step"));
  s.add(AttrSpec::real("sigma0").def("2 mm").atLeast(0).unit(Dimension::length()).help(
      "standard deviation of the depth at distance z0 (0: no noise); sigma(z) = sigma0 (z / z0)^2"));
  s.add(AttrSpec::real("z0").def("400 mm").above(0).unit(Dimension::length()).help("working distance at which the depth noise is sigma0"));
  s.add(AttrSpec::real("dropout").def("0.01").atLeast(0).below(1).help("probability that a pixel gives no point, independently per pixel"));
  s.add(AttrSpec::real("grazingAngle").def("80").above(0).atMost(90).help(
      "largest angle in degrees between a pixel's ray and the surface normal that still gives a point (90: no limit)"));
  s.add(AttrSpec::real("depthUnit").def("0.125 mm").atLeast(0).unit(Dimension::length()).help(
      "depth quantisation step, the sensor's depth unit (SR300: 1/8 mm; 0: none)"));
  s.add(AttrSpec::integer("seed").def("1").atLeast(0).help("random seed of the noise"));
  s.add(AttrSpec::integer("stride").def("1").atLeast(1).help("keep every stride-th pixel of every stride-th row (lighter clouds)"));
  s.add(AttrSpec::choice("frame", {"camera", "scene"}).def("camera").help(
      "frame of the points: the camera's (as a real sensor; registration needed) or the scene's"));
  s.add(AttrSpec::boolean("tissueOnly").def("false").help("keep only the points on deformable bodies (truth data without instrument or table)"));
  s.add(AttrSpec::reals("table", 4).unit(Dimension::length()).help(
      "optional infinite plane n . x = d, as \"nx ny nz d\" (the normal need not be unit; a unit scales all four, "
      "which leaves the plane unchanged)"));
  s.add(AttrSpec::string("filename").help("folder of the frames, relative to the output folder (default: the component's name)"));
  s.add(AttrSpec::choice("format", {"pcd", "ply"}).def("pcd").help("file format of the frames"));
  s.add(AttrSpec::boolean("binary").def("true").help("binary files (false: ASCII)"));
  s.factory = [](BuildContext& c) { return std::make_unique<DepthCameraComponent>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
