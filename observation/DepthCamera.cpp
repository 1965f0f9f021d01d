#include "observation/DepthCamera.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace viscera::obs {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string str(double v) {
  std::ostringstream o;
  o << v;
  return o.str();
}

// First and last pixel whose centre lies in [lo, hi] of image coordinates, clamped to [0, n - 1]
// (first > last when none does). The bounds are widened by a millionth of a pixel so that a
// pixel centre on the boundary, which the exact per-pixel test decides, is never cut off by the
// rounding of the projection.
void pixelSpan(double lo, double hi, int n, int& first, int& last) {
  constexpr double kPad = 1e-6;
  const double f = std::ceil(std::max(lo - kPad, -1.0));
  const double l = std::floor(std::min(hi + kPad, static_cast<double>(n)));
  first = static_cast<int>(std::max(f, 0.0));
  last = static_cast<int>(std::min(l, static_cast<double>(n - 1)));
}

// SplitMix64's finaliser: a bijective 64-bit mix whose outputs for consecutive inputs pass
// statistical test suites; hashing (key + counter * golden ratio) is SplitMix64 itself, used as a
// counter-based generator.
std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

constexpr std::uint64_t kGolden = 0x9e3779b97f4a7c15ULL;

std::uint64_t frameKey(std::uint64_t seed, std::uint64_t frame) {
  return mix64(mix64(seed + kGolden) ^ (frame * 0xd1b54a32d192ed03ULL + 0x8cb92ba72f3d8dd7ULL));
}

// A uniform number in the open interval (0, 1), 53 random bits.
double uniform(std::uint64_t key, std::uint64_t counter) {
  const std::uint64_t h = mix64(key + (counter + 1) * kGolden);
  return (static_cast<double>(h >> 11) + 0.5) * 0x1.0p-53;
}

// A standard normal number (Box-Muller on two uniforms).
double gaussian(std::uint64_t key, std::uint64_t counter1, std::uint64_t counter2) {
  const double r = std::sqrt(-2.0 * std::log(uniform(key, counter1)));
  return r * std::cos(2.0 * M_PI * uniform(key, counter2));
}

}  // namespace

CameraIntrinsics CameraIntrinsics::fromFov(int width, int height, double horizontalFovDegrees) {
  if (!(horizontalFovDegrees > 0 && horizontalFovDegrees < 180))
    throw std::invalid_argument("fov: " + str(horizontalFovDegrees) + " degrees is not in (0, 180)");
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  k.fx = k.fy = 0.5 * width / std::tan(0.5 * horizontalFovDegrees * M_PI / 180.0);
  k.cx = 0.5 * (width - 1);
  k.cy = 0.5 * (height - 1);
  return k;
}

void CameraIntrinsics::validate() const {
  if (width < 1) throw std::invalid_argument("width: " + std::to_string(width) + " pixels; needs at least 1");
  if (height < 1) throw std::invalid_argument("height: " + std::to_string(height) + " pixels; needs at least 1");
  if (!(fx > 0) || !std::isfinite(fx)) throw std::invalid_argument("fx: " + str(fx) + " is not a positive focal length");
  if (!(fy > 0) || !std::isfinite(fy)) throw std::invalid_argument("fy: " + str(fy) + " is not a positive focal length");
  // The principal point must lie on the image (pixel centres run from 0 to width - 1).
  if (!(cx >= -0.5 && cx <= width - 0.5))
    throw std::invalid_argument("cx: " + str(cx) + " is outside the image [-0.5, " + str(width - 0.5) + "]");
  if (!(cy >= -0.5 && cy <= height - 0.5))
    throw std::invalid_argument("cy: " + str(cy) + " is outside the image [-0.5, " + str(height - 0.5) + "]");
}

RigidTransform lookAtPose(const Eigen::Vector3d& position, const Eigen::Vector3d& target, const Eigen::Vector3d& up) {
  const Eigen::Vector3d view = target - position;
  if (!(view.norm() > 0)) throw std::invalid_argument("lookAt: is the camera position; the camera needs a direction");
  const Eigen::Vector3d z = view.normalized();
  if (!(up.norm() > 0)) throw std::invalid_argument("up: is the zero vector");
  // The image's up is -y; y is `up` without its component along the view, negated.
  const Eigen::Vector3d upInPlane = up.normalized() - up.normalized().dot(z) * z;
  if (upInPlane.norm() < 1e-6)
    throw std::invalid_argument("up: is parallel to the viewing direction (the camera looks straight along it); "
                                "give an `up` that is not");
  const Eigen::Vector3d y = -upInPlane.normalized();
  const Eigen::Vector3d x = y.cross(z);
  RigidTransform T = RigidTransform::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = y;
  T.linear().col(2) = z;
  T.translation() = position;
  return T;
}

int DepthImage::count(int l) const { return static_cast<int>(std::count(label.begin(), label.end(), l)); }

void DepthNoise::validate() const {
  if (!(sigma0 >= 0) || !std::isfinite(sigma0)) throw std::invalid_argument("sigma0: " + str(sigma0) + " must be >= 0");
  if (!(z0 > 0) || !std::isfinite(z0)) throw std::invalid_argument("z0: " + str(z0) + " must be > 0");
  if (!(dropout >= 0 && dropout < 1)) throw std::invalid_argument("dropout: " + str(dropout) + " is not in [0, 1)");
  if (!(grazingAngleDeg > 0 && grazingAngleDeg <= 90))
    throw std::invalid_argument("grazingAngle: " + str(grazingAngleDeg) + " degrees is not in (0, 90]");
  if (!(depthUnit >= 0) || !std::isfinite(depthUnit))
    throw std::invalid_argument("depthUnit: " + str(depthUnit) + " must be >= 0");
}

DepthCamera::DepthCamera(const CameraIntrinsics& intrinsics, const RigidTransform& cameraToScene, double minDepth,
                         double maxDepth)
    : k_(intrinsics), pose_(cameraToScene), sceneToCamera_(cameraToScene.inverse()), minDepth_(minDepth),
      maxDepth_(maxDepth) {
  k_.validate();
  if (!(minDepth > 0) || !std::isfinite(minDepth)) throw std::invalid_argument("near: " + str(minDepth) + " must be > 0");
  if (!(maxDepth > minDepth))
    throw std::invalid_argument("far: " + str(maxDepth) + " must be beyond near (" + str(minDepth) + ")");
  xs_.resize(static_cast<size_t>(k_.width));
  ys_.resize(static_cast<size_t>(k_.height));
  for (int i = 0; i < k_.width; ++i) xs_[static_cast<size_t>(i)] = (i - k_.cx) / k_.fx;
  for (int j = 0; j < k_.height; ++j) ys_[static_cast<size_t>(j)] = (j - k_.cy) / k_.fy;
}

void DepthCamera::render(const RenderInput& input, DepthImage& image) const {
  const size_t n = static_cast<size_t>(k_.width) * static_cast<size_t>(k_.height);
  image.width = k_.width;
  image.height = k_.height;
  image.depth.assign(n, kInf);
  image.label.assign(n, -1);
  image.cosIncidence.assign(n, 0.0f);
  for (const SurfaceInput& s : input.surfaces) rasteriseSurface(s, image);
  for (const SphereInput& s : input.spheres) rasteriseSphere(s, image);
  if (input.plane) rasterisePlane(*input.plane, image);
  // The first surface along a ray decides: out of range, it hides what is behind it but gives no depth.
  for (size_t p = 0; p < n; ++p)
    if (image.label[p] >= 0 && (image.depth[p] < minDepth_ || image.depth[p] > maxDepth_)) image.label[p] = -1;
}

void DepthCamera::rasteriseSurface(const SurfaceInput& s, DepthImage& image) const {
  const TriangleList& tris = *s.triangles;
  // The surface's points in the camera frame, 3 x #points.
  const Eigen::Matrix3Xd pts = (sceneToCamera_.linear() * *s.points).colwise() + sceneToCamera_.translation();
  const int w = k_.width;
  for (Eigen::Index t = 0; t < tris.cols(); ++t) {
    const Eigen::Vector3d a = pts.col(tris(0, t)), b = pts.col(tris(1, t)), c = pts.col(tris(2, t));
    if (a.z() <= 0 && b.z() <= 0 && c.z() <= 0) continue;  // behind the camera
    const Eigen::Vector3d normal = (b - a).cross(c - a);
    const double area2 = normal.norm();
    if (!(area2 > 0) || !std::isfinite(area2)) continue;  // degenerate: covers no pixel
    // For the ray r of a pixel, r . (b x c), r . (c x a) and r . (a x b) are proportional to the
    // barycentric coordinates of the ray's intersection with the triangle's plane: the ray's line
    // crosses the triangle when the three have the same sign, whichever way it is oriented.
    // Neighbouring triangles compute exactly opposite values on their shared edge, so no pixel
    // falls between them.
    const Eigen::Vector3d e0 = b.cross(c), e1 = c.cross(a), e2 = a.cross(b);
    const double planeOffset = a.dot(normal);  // the plane is normal . x = planeOffset
    const Eigen::Vector3d unitNormal = normal / area2;

    int i0 = 0, i1 = w - 1, j0 = 0, j1 = k_.height - 1;
    if (a.z() > 0 && b.z() > 0 && c.z() > 0) {
      // Entirely in front of the camera: the projected bounding box. (A triangle that crosses the
      // camera's plane z = 0 projects without bound; it is tested over the whole image.)
      const double u[3] = {a.x() / a.z(), b.x() / b.z(), c.x() / c.z()};
      const double v[3] = {a.y() / a.z(), b.y() / b.z(), c.y() / c.z()};
      pixelSpan(k_.fx * std::min({u[0], u[1], u[2]}) + k_.cx, k_.fx * std::max({u[0], u[1], u[2]}) + k_.cx, w, i0, i1);
      pixelSpan(k_.fy * std::min({v[0], v[1], v[2]}) + k_.cy, k_.fy * std::max({v[0], v[1], v[2]}) + k_.cy, k_.height,
                j0, j1);
    }
    for (int j = j0; j <= j1; ++j) {
      const double y = ys_[static_cast<size_t>(j)];
      const double r0 = e0.y() * y + e0.z(), r1 = e1.y() * y + e1.z(), r2 = e2.y() * y + e2.z();
      const double rn = normal.y() * y + normal.z();
      for (int i = i0; i <= i1; ++i) {
        const double x = xs_[static_cast<size_t>(i)];
        const double w0 = e0.x() * x + r0, w1 = e1.x() * x + r1, w2 = e2.x() * x + r2;
        if (!((w0 >= 0 && w1 >= 0 && w2 >= 0) || (w0 <= 0 && w1 <= 0 && w2 <= 0))) continue;
        const double den = normal.x() * x + rn;  // normal . ray
        if (den == 0) continue;                  // the ray runs in the triangle's plane
        const double z = planeOffset / den;
        const size_t p = static_cast<size_t>(j) * static_cast<size_t>(w) + static_cast<size_t>(i);
        if (!(z > 0) || z >= image.depth[p]) continue;
        image.depth[p] = z;
        image.label[p] = s.label;
        image.cosIncidence[p] =
            static_cast<float>(std::abs(unitNormal.x() * x + unitNormal.y() * y + unitNormal.z()) / std::sqrt(x * x + y * y + 1));
      }
    }
  }
}

void DepthCamera::rasteriseSphere(const SphereInput& s, DepthImage& image) const {
  const Eigen::Vector3d c = sceneToCamera_ * s.centre;
  const double r = s.radius;
  if (!(r > 0) || !c.allFinite() || c.z() + r <= 0) return;  // nothing, or wholly behind the camera
  int i0 = 0, i1 = k_.width - 1, j0 = 0, j1 = k_.height - 1;
  if (c.z() - r > 0) {
    // Wholly in front: the extremes of x / z over the sphere are the planes through the camera's
    // y axis tangent to it, at angles atan2(cx, cz) +- asin(r / |(cx, cz)|) in the xz plane (and
    // likewise for y / z). That is the exact bounding rectangle of the projected ellipse.
    const auto range = [&](double lateral, double& lo, double& hi) {
      const double d = std::hypot(lateral, c.z());
      const double mid = std::atan2(lateral, c.z()), half = std::asin(r / d);
      lo = std::tan(mid - half);
      hi = std::tan(mid + half);
    };
    double xlo, xhi, ylo, yhi;
    range(c.x(), xlo, xhi);
    range(c.y(), ylo, yhi);
    pixelSpan(k_.fx * xlo + k_.cx, k_.fx * xhi + k_.cx, k_.width, i0, i1);
    pixelSpan(k_.fy * ylo + k_.cy, k_.fy * yhi + k_.cy, k_.height, j0, j1);
  }
  const double cc = c.squaredNorm() - r * r;
  for (int j = j0; j <= j1; ++j) {
    const double y = ys_[static_cast<size_t>(j)];
    for (int i = i0; i <= i1; ++i) {
      const double x = xs_[static_cast<size_t>(i)];
      // |t ray - c|^2 = r^2 with ray = (x, y, 1): a t^2 - 2 b t + cc = 0; t is the depth z.
      const double a = x * x + y * y + 1, b = x * c.x() + y * c.y() + c.z();
      const double disc = b * b - a * cc;
      if (disc < 0) continue;
      const double root = std::sqrt(disc);
      double z = (b - root) / a;
      if (!(z > 0)) z = (b + root) / a;  // the camera is inside the sphere: the far side
      const size_t p = static_cast<size_t>(j) * static_cast<size_t>(k_.width) + static_cast<size_t>(i);
      if (!(z > 0) || z >= image.depth[p]) continue;
      image.depth[p] = z;
      image.label[p] = s.label;
      const Eigen::Vector3d ray(x, y, 1.0);
      image.cosIncidence[p] = static_cast<float>(std::abs((z * ray - c).dot(ray)) / (r * std::sqrt(a)));
    }
  }
}

void DepthCamera::rasterisePlane(const PlaneInput& plane, DepthImage& image) const {
  const double len = plane.normal.norm();
  if (!(len > 0)) return;
  // normal . (R x_c + t) = offset  <=>  (R^T normal) . x_c = offset - normal . t
  const Eigen::Vector3d n = pose_.linear().transpose() * plane.normal / len;
  const double offset = (plane.offset - plane.normal.dot(pose_.translation())) / len;
  for (int j = 0; j < k_.height; ++j) {
    const double y = ys_[static_cast<size_t>(j)];
    for (int i = 0; i < k_.width; ++i) {
      const double x = xs_[static_cast<size_t>(i)];
      const double den = n.x() * x + n.y() * y + n.z();
      if (den == 0) continue;
      const double z = offset / den;
      const size_t p = static_cast<size_t>(j) * static_cast<size_t>(k_.width) + static_cast<size_t>(i);
      if (!(z > 0) || z >= image.depth[p]) continue;
      image.depth[p] = z;
      image.label[p] = plane.label;
      image.cosIncidence[p] = static_cast<float>(std::abs(den) / std::sqrt(x * x + y * y + 1));
    }
  }
}

Capture DepthCamera::capture(const DepthImage& image, const DepthNoise& noise, std::uint64_t frameIndex,
                             const CaptureOptions& options) const {
  noise.validate();
  if (options.stride < 1) throw std::invalid_argument("stride: " + std::to_string(options.stride) + " must be >= 1");
  if (image.width != k_.width || image.height != k_.height)
    throw std::invalid_argument("image: " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                " was not rendered by this camera (" + std::to_string(k_.width) + " x " +
                                std::to_string(k_.height) + ")");
  const double cosGrazing = noise.grazingAngleDeg >= 90 ? -1.0 : std::cos(noise.grazingAngleDeg * M_PI / 180.0);
  const std::uint64_t key = frameKey(noise.seed, frameIndex);
  const int stride = options.stride;

  std::vector<Eigen::Vector3d> points;
  Capture out;
  for (int j = 0; j < k_.height; j += stride)
    for (int i = 0; i < k_.width; i += stride) {
      const int p = image.index(i, j);
      const int l = image.label[static_cast<size_t>(p)];
      if (l < 0) continue;
      if (!options.labels.empty() && std::find(options.labels.begin(), options.labels.end(), l) == options.labels.end())
        continue;
      if (image.cosIncidence[static_cast<size_t>(p)] < cosGrazing) continue;
      // Three random numbers per pixel: dropout, and the two of the Gaussian.
      const std::uint64_t counter = 3 * static_cast<std::uint64_t>(p);
      if (noise.dropout > 0 && uniform(key, counter) < noise.dropout) continue;
      double z = image.depth[static_cast<size_t>(p)];
      if (noise.sigma0 > 0) z += noise.sigma(z) * gaussian(key, counter + 1, counter + 2);
      if (noise.depthUnit > 0) z = std::round(z / noise.depthUnit) * noise.depthUnit;
      if (!(z > 0)) continue;  // a sensor reports no depth at or behind itself
      Eigen::Vector3d point = z * ray(i, j);
      if (options.frame == PointFrame::Scene) point = pose_ * point;
      points.push_back(point);
      out.labels.push_back(l);
      out.pixels.push_back(p);
    }
  out.cloud.points.resize(3, static_cast<Eigen::Index>(points.size()));
  for (size_t k = 0; k < points.size(); ++k) out.cloud.points.col(static_cast<Eigen::Index>(k)) = points[k];
  return out;
}

double windingNumber(const Eigen::Matrix3Xd& points, const TriangleList& triangles, const Eigen::Vector3d& p) {
  double total = 0;
  for (Eigen::Index t = 0; t < triangles.cols(); ++t) {
    const Eigen::Vector3d a = points.col(triangles(0, t)) - p, b = points.col(triangles(1, t)) - p,
                          c = points.col(triangles(2, t)) - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    // Van Oosterom and Strackee: tan(omega / 2) = a . (b x c) / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|).
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    total += 2 * std::atan2(num, den);
  }
  return total / (4 * M_PI);
}

}  // namespace viscera::obs
