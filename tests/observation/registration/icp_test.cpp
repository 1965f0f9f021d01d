// ICP of a depth-camera cloud of the phantom (camera frame) to the phantom's mesh surface (scene
// frame): recovery of a known transform from noisy, partial clouds with outliers, exact recovery
// without noise, and the under-constrained diagnostic for a single flat face.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "core/Error.h"
#include "observation/Registration.h"
#include "tests/observation/registration/phantom.h"

using namespace registration_test;
using viscera::RigidTransform;
using viscera::obs::IcpOptions;
using viscera::obs::IcpResult;
using viscera::obs::registerIcp;

namespace {

TEST(Icp, RecoversTheCameraFromANoisyPartialCloudWithOutliers) {
  const auto surface = phantomSurface();
  const RigidTransform truth = cameraToScene();
  // 14700 surface points displaced by 2 mm RMS (sigma 1.15 mm per axis), and 735 outliers.
  const Eigen::Matrix3Xd sceneCloud = phantomCloud(CloudSpec{});
  const Eigen::Matrix3Xd cloud = truth.inverse() * sceneCloud;
  // Off by 6 degrees about a skew axis through the block and by (5, -4, 3) mm.
  const RigidTransform init = perturbed(truth, 6, Eigen::Vector3d(1, -2, 1), Eigen::Vector3d(5, -4, 3));
  ASSERT_GT(angleBetweenDeg(init, truth), 5.9);
  ASSERT_GT(cornerErrorMm(init, truth), 8.0);

  const IcpResult r = registerIcp(cloud, surface, init);
  EXPECT_TRUE(r.converged) << r.iterations << " iterations";
  EXPECT_EQ(r.pointToPointIterations, 0);
  // Why 0.5 degrees and 0.5 mm mean something here: only the noise along each face's normal
  // (sigma = 1.15 mm) informs the fit. A rotation about x is fixed by the top face (8000 points,
  // RMS lever arm 35.8 / sqrt(12) = 10.3 mm) and the front face (4400 points, lever 39.3 /
  // sqrt(12) = 11.3 mm): its standard error is 1.15 / sqrt(8000 * 10.3^2 + 4400 * 11.3^2) =
  // 1e-3 rad = 0.06 degrees; about y and z the levers are longer and the errors smaller. Trimming
  // costs some efficiency (about 1.5x), so the angle error is ~0.1 degrees (0.03-0.31 over seeds
  // 1-12): 0.5 degrees is a bound of over 4 sigma, against 6 degrees initially. The random part of
  // the translation is small (1.15 / sqrt(4000) = 0.02 mm), but closest points are biased near the
  // block's edges: a noisy point just inside an edge is nearer the other face, so each face loses
  // its most inward residuals and the fit pulls the cloud ~0.05 sigma (0.05-0.1 mm) into the block
  // along each visible face's normal. With the rotation error at the corners (up to 42 mm from the
  // centroid) the worst corner ends 0.13-0.27 mm off over those seeds, against 10 mm initially,
  // while a fit that lost a face or stopped in a wrong minimum would be millimetres off. (The
  // bias grows as sigma^2: with 2 mm per axis it is 0.2 mm per axis and the corners end
  // 0.35-0.65 mm off.)
  const double angle = angleBetweenDeg(r.transform, truth), corner = cornerErrorMm(r.transform, truth);
  EXPECT_LT(angle, 0.5);
  EXPECT_LT(corner, 0.5);
  std::printf("[ measured ] angle error %.4f deg, corner error %.4f mm, %d iterations, RMS %.3f mm, kept %.3f, condition %.3g\n",
              angle, corner, r.iterations, r.rms, r.keptFraction, r.conditionRatio);

  // The kept pairs: the closest 90 % of those within the shrinking limit, so at most 90 % of the
  // cloud and none of the residuals above the final limit. Their RMS distance is below the noise's
  // RMS normal component (1.15 mm) because the largest were trimmed, and above half of it.
  EXPECT_LE(r.keptFraction, 0.9 + 1e-12);
  EXPECT_GT(r.keptFraction, 0.8);
  EXPECT_LT(r.rms, 1.15);
  EXPECT_GT(r.rms, 0.58);
  EXPECT_LE(r.max, r.finalMaxDistance);
  EXPECT_LE(r.mean, r.rms);
  // Three mutually perpendicular faces constrain all six directions.
  EXPECT_FALSE(r.degenerate);
  EXPECT_TRUE(r.weakDirections.empty());
  EXPECT_GT(r.conditionRatio, 1e-2);
  ASSERT_EQ(r.distances.size(), cloud.cols());
  ASSERT_EQ(static_cast<Eigen::Index>(r.kept.size()), cloud.cols());
  int kept = 0;
  for (bool k : r.kept) kept += k;
  EXPECT_EQ(kept, r.pairs);
}

TEST(Icp, ExactWithoutNoise) {
  const auto surface = phantomSurface();
  const RigidTransform truth = cameraToScene();
  CloudSpec spec;
  spec.top = 1500, spec.front = 800, spec.left = 500, spec.noise = 0, spec.outlierFraction = 0;
  const Eigen::Matrix3Xd cloud = truth.inverse() * phantomCloud(spec);
  const RigidTransform init = perturbed(truth, 5, Eigen::Vector3d(2, 1, -1), Eigen::Vector3d(-3, 4, 2));
  const IcpResult r = registerIcp(cloud, surface, init);
  EXPECT_TRUE(r.converged);
  // Points exactly on the surface: the true transform is the exact optimum; convergence stops
  // when a step is below 1e-6 rad / 1e-6 of the cloud radius, and point-to-plane steps converge
  // quadratically on exact data, so the remaining error is far below that.
  EXPECT_LT(angleBetweenDeg(r.transform, truth), 1e-6);
  EXPECT_LT(cornerErrorMm(r.transform, truth), 1e-6);
  EXPECT_LT(r.rms, 1e-6);
}

TEST(Icp, SingleFlatFaceIsReportedAsUnderConstrained) {
  const auto surface = phantomSurface();
  // The top face only, 8 mm or more from its edges (more than the initial shift below plus 4
  // sigma): every closest point lies on the top plane.
  std::mt19937 rng(11);
  std::vector<Eigen::Vector3d> pts;
  sampleRectangle(rng, 6000, 2, kHi.z(), Eigen::Vector3d(8, 8, 0), Eigen::Vector3d(60.7, 27.8, 0), pts);
  std::normal_distribution<double> g(0, 0.5);
  Eigen::Matrix3Xd scene(3, static_cast<Eigen::Index>(pts.size()));
  for (size_t i = 0; i < pts.size(); ++i) scene.col(static_cast<Eigen::Index>(i)) = pts[i] + Eigen::Vector3d(g(rng), g(rng), g(rng));
  const RigidTransform truth = cameraToScene();
  const Eigen::Matrix3Xd cloud = truth.inverse() * scene;
  // Tilted by 4 degrees, turned 3 degrees about the vertical, shifted 3 mm along x, -2 along y, 4 up.
  const RigidTransform init = perturbed(perturbed(truth, 4, Eigen::Vector3d(1, 0.5, 0), Eigen::Vector3d::Zero()), 3,
                                        Eigen::Vector3d::UnitZ(), Eigen::Vector3d(3, -2, 4));
  const IcpResult r = registerIcp(cloud, surface, init);
  EXPECT_TRUE(r.converged);
  EXPECT_TRUE(r.degenerate);
  EXPECT_LT(r.conditionRatio, 1e-6);  // exactly 0 without rounding: all normals are +z
  EXPECT_EQ(r.pointToPointIterations, r.iterations);

  // The weak directions: the rotation about the vertical and the two horizontal translations.
  ASSERT_EQ(r.weakDirections.size(), 3u);
  EXPECT_GT(std::abs(r.weakDirections[0].rotation.normalized().z()), 0.999) << r.weakDirections[0].describe();
  EXPECT_LT(r.weakDirections[0].translation.norm(), 1e-6) << r.weakDirections[0].describe();
  EXPECT_EQ(r.weakDirections[0].describe().rfind("rotation about", 0), 0u);
  for (int k = 1; k < 3; ++k) {
    EXPECT_LT(r.weakDirections[k].rotation.norm(), 1e-6) << r.weakDirections[k].describe();
    EXPECT_LT(std::abs(r.weakDirections[k].translation.z()), 1e-6) << r.weakDirections[k].describe();
    EXPECT_EQ(r.weakDirections[k].describe().rfind("translation along", 0), 0u);
  }

  // What the face does fix: the tilt and the height. The scene's +z seen through the true camera
  // must come out vertical: the tilt's standard error is sigma / (sqrt(n) x RMS lever arm) =
  // 0.5 / (sqrt(6000) x 19.8 / sqrt(12)) = 1.1e-3 rad = 0.065 degrees about x (less about y);
  // trimming makes the fit less efficient than a plain plane fit (0.14 degrees here, 0.09
  // untrimmed), so 0.3 degrees is a 3 sigma bound, against 4 degrees initially. The cloud's
  // centroid must be at the top's height: standard error 0.5 / sqrt(6000) = 0.006 mm, against
  // 4 mm initially.
  const Eigen::Vector3d up = r.transform.linear() * truth.linear().transpose() * Eigen::Vector3d::UnitZ();
  const double tilt = std::acos(std::min(1.0, up.z())) * 180 / M_PI;
  EXPECT_LT(tilt, 0.3);
  const Eigen::Vector3d centre = r.transform * cloud.rowwise().mean();
  EXPECT_NEAR(centre.z(), kHi.z(), 0.05);
  std::printf("[ measured ] flat face: tilt error %.4f deg, height error %.4f mm, condition %.3g\n", tilt, centre.z() - kHi.z(),
              r.conditionRatio);
  // What it does not: the horizontal position stays where the initial guess put it (3, -2).
  const Eigen::Vector3d initCentre = init * cloud.rowwise().mean(), trueCentre = truth * cloud.rowwise().mean();
  EXPECT_NEAR(centre.x() - trueCentre.x(), initCentre.x() - trueCentre.x(), 0.5);
  EXPECT_NEAR(centre.y() - trueCentre.y(), initCentre.y() - trueCentre.y(), 0.5);
  EXPECT_GT(std::abs(centre.x() - trueCentre.x()), 2.0);
}

TEST(Icp, MaximumDistanceLimitsTheCorrespondences) {
  const auto surface = phantomSurface();
  CloudSpec spec;
  spec.top = 1000, spec.front = 500, spec.left = 300, spec.noise = 0.5;
  const Eigen::Matrix3Xd cloud = phantomCloud(spec);  // already in the scene frame
  IcpOptions o;
  o.maxDistance = 1.0;
  o.shrinkFactor = 0;  // a fixed limit
  o.trim = 1.0;
  const IcpResult r = registerIcp(cloud, surface, RigidTransform::Identity(), o);
  EXPECT_LE(r.max, 1.0);
  EXPECT_DOUBLE_EQ(r.finalMaxDistance, 1.0);
  // With trim = 1 every pair within the limit is kept: exactly the points nearer than 1 mm.
  int within = 0;
  for (Eigen::Index i = 0; i < cloud.cols(); ++i) within += r.distances(i) < 1.0;
  EXPECT_EQ(r.pairs, within);
}

TEST(Icp, RejectsUnusableInput) {
  const auto surface = phantomSurface();
  CloudSpec spec;
  spec.top = 200, spec.front = 0, spec.left = 0;
  const Eigen::Matrix3Xd cloud = phantomCloud(spec);
  auto message = [&](const Eigen::Matrix3Xd& c, const IcpOptions& o, const RigidTransform& T) -> std::string {
    try {
      registerIcp(c, surface, T, o, "rest.pcd");
    } catch (const viscera::Error& e) {
      return e.what();
    }
    return "";
  };
  const RigidTransform I = RigidTransform::Identity();
  EXPECT_NE(message(Eigen::Matrix3Xd(3, 0), {}, I).find("rest.pcd: ICP: the cloud has no points"), std::string::npos);
  Eigen::Matrix3Xd withNan = cloud;
  withNan(1, 17) = std::nan("");
  EXPECT_NE(message(withNan, {}, I).find("point 17 is not finite"), std::string::npos);
  IcpOptions bad;
  bad.trim = 0;
  EXPECT_NE(message(cloud, bad, I).find("trim"), std::string::npos);
  bad = {};
  bad.maxIterations = 0;
  EXPECT_NE(message(cloud, bad, I).find("iterations"), std::string::npos);
  bad = {};
  bad.maxDistance = -1;
  EXPECT_NE(message(cloud, bad, I).find("maximum distance"), std::string::npos);
  // An initial guess 1 m away with a 10 mm limit: no pairs.
  IcpOptions near;
  near.maxDistance = 10;
  RigidTransform far = I;
  far.translation() = Eigen::Vector3d(1000, 0, 0);
  EXPECT_NE(message(cloud, near, far).find("within the maximum distance"), std::string::npos);
}

}  // namespace
