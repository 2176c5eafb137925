// GICP: simulated scenes with a known answer (a closed corridor, an open one
// that leaves a slide free), real KITTI 00 pairs against ground truth, the
// covariance it reports, and empty input.

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/registration/gicp.hpp>
#include <dcl/registration/voxel_filter.hpp>

#include "registration_test_data.hpp"

namespace dcl::registration {
namespace {

using test::poseError;

/// `scene` as a sensor at `T_scene_sensor` sees it (in its own frame), with
/// Gaussian range noise of `sigma` metres on each coordinate.
std::vector<Eigen::Vector3d> observe(const core::PointCloud& scene,
                                     const Eigen::Isometry3d& T_scene_sensor, double sigma,
                                     unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  std::vector<Eigen::Vector3d> points;
  const Eigen::Isometry3d T_sensor_scene = T_scene_sensor.inverse();
  for (const Eigen::Vector3f& p : scene.points)
    points.push_back(T_sensor_scene * p.cast<double>() +
                     Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  return points;
}

GicpConfig fineConfig() {
  GicpConfig config;
  config.max_correspondence_distance = 1.0;
  config.kernel_scale = 0.5;
  return config;
}

/// Registers the scene seen from `T_target_source` (source) to the scene seen
/// from the origin (target), both voxel-filtered at 0.3 m, from `guess`.
GicpResult registerScene(const core::PointCloud& scene, const Eigen::Isometry3d& T_target_source,
                         const Eigen::Isometry3d& guess, unsigned seed) {
  RegistrationCloud target(
      voxelDownsample(observe(scene, Eigen::Isometry3d::Identity(), 0.01, seed), 0.3));
  RegistrationCloud source(voxelDownsample(observe(scene, T_target_source, 0.01, seed + 1), 0.3));
  return alignGicp(target, source, guess, fineConfig());
}

bool symmetricPositiveDefinite(const core::Matrix6d& m) {
  if (!m.isApprox(m.transpose(), 1e-12)) return false;
  return Eigen::SelfAdjointEigenSolver<core::Matrix6d>(m).eigenvalues().minCoeff() > 0.0;
}

TEST(Gicp, RecoversAKnownMotionInAClosedCorridor) {
  const core::PointCloud scene = test::corridor(true);
  const Eigen::Isometry3d truth = core::makePose2d(0.8, -0.3, core::deg2rad(4.0));
  const Eigen::Isometry3d guess = core::makePose2d(0.5, 0.0, core::deg2rad(2.0));
  const GicpResult result = registerScene(scene, truth, guess, 11);
  const auto error = poseError(result.T_target_source, truth);
  EXPECT_TRUE(result.converged);
  EXPECT_LT(error.translation, 0.01);
  EXPECT_LT(error.rotation_deg, 0.05);
  EXPECT_GT(result.inlier_share, 0.9);
  EXPECT_LT(result.fitness, 0.2);
  EXPECT_GT(result.degeneracy, 0.01);
  EXPECT_TRUE(symmetricPositiveDefinite(result.covariance));
}

TEST(Gicp, FlagsTheSlideOfAnOpenCorridorAndWidensItsCovariance) {
  const Eigen::Isometry3d truth = core::makePose2d(0.8, -0.3, core::deg2rad(4.0));
  const Eigen::Isometry3d guess = core::makePose2d(0.5, 0.0, core::deg2rad(2.0));
  const GicpResult open = registerScene(test::corridor(false), truth, guess, 21);
  const GicpResult closed = registerScene(test::corridor(true), truth, guess, 21);
  std::printf("degeneracy: open %.2e closed %.2e; sd along: open %.2e m closed %.2e m\n",
              open.degeneracy, closed.degeneracy, std::sqrt(open.covariance(0, 0)),
              std::sqrt(closed.covariance(0, 0)));
  EXPECT_LT(open.degeneracy, 1e-3);  // nothing fixes x
  EXPECT_GT(closed.degeneracy, 10.0 * open.degeneracy);
  ASSERT_TRUE(symmetricPositiveDefinite(open.covariance));
  // The free direction is x of the corridor, x of the source frame turned by the yaw.
  const Eigen::Vector3d along = truth.linear().transpose() * Eigen::Vector3d::UnitX();
  const Eigen::Vector3d across = truth.linear().transpose() * Eigen::Vector3d::UnitY();
  const Eigen::Matrix3d open_t = open.covariance.topLeftCorner<3, 3>();
  const Eigen::Matrix3d closed_t = closed.covariance.topLeftCorner<3, 3>();
  EXPECT_GT(along.dot(open_t * along), 100.0 * across.dot(open_t * across));
  EXPECT_GT(along.dot(open_t * along), 100.0 * along.dot(closed_t * along));
  // Across the corridor both are pinned by the walls alike.
  EXPECT_LT(across.dot(open_t * across), 3.0 * across.dot(closed_t * across));
}

TEST(Gicp, CovarianceMatchesTheScatterOfRepeatedRegistrations) {
  const core::PointCloud scene = test::corridor(true, 0.15);
  const Eigen::Isometry3d truth = core::makePose2d(0.8, -0.3, core::deg2rad(4.0));
  std::vector<core::Vector6d> errors;
  core::Matrix6d predicted = core::Matrix6d::Zero();
  const int runs = 12;
  for (int run = 0; run < runs; ++run) {
    // Noise of 3 cm, as a mid-range LiDAR; each run samples it anew.
    RegistrationCloud target(
        voxelDownsample(observe(scene, Eigen::Isometry3d::Identity(), 0.03, 100 + 2 * run), 0.3));
    RegistrationCloud source(voxelDownsample(observe(scene, truth, 0.03, 101 + 2 * run), 0.3));
    const GicpResult result = alignGicp(target, source, truth, fineConfig());
    ASSERT_TRUE(result.converged);
    errors.push_back(core::logSE3(truth.inverse() * result.T_target_source));
    predicted += result.covariance / runs;
  }
  // Translation along the corridor and yaw: the predicted standard deviation
  // is within a factor of four of the observed one (pairs are not quite
  // independent, so GICP's covariance is expected to be somewhat optimistic).
  for (int axis : {0, 5}) {
    double observed = 0.0;
    for (const core::Vector6d& e : errors) observed += e(axis) * e(axis) / runs;
    const double ratio = std::sqrt(observed / predicted(axis, axis));
    std::printf("axis %d: observed sd %.2e, predicted %.2e\n", axis, std::sqrt(observed),
                std::sqrt(predicted(axis, axis)));
    EXPECT_GT(ratio, 0.25) << "axis " << axis;
    EXPECT_LT(ratio, 4.0) << "axis " << axis;
  }
}

TEST(Gicp, AlignsConsecutiveKittiScansToGroundTruth) {
  for (auto [query, candidate] : {std::pair{95, 94}, std::pair{199, 198}}) {
    RegistrationCloud target(voxelDownsample(test::kittiScan(candidate).points, 0.6));
    RegistrationCloud source(voxelDownsample(test::kittiScan(query).points, 0.6));
    const GicpResult result =
        alignGicp(target, source, Eigen::Isometry3d::Identity(), fineConfig());
    const auto error = poseError(result.T_target_source, test::kittiTruth(query, candidate));
    EXPECT_TRUE(result.converged) << query;
    EXPECT_LT(error.translation, 0.03) << query;
    EXPECT_LT(error.rotation_deg, 0.1) << query;
    EXPECT_TRUE(symmetricPositiveDefinite(result.covariance));
    EXPECT_GT(result.degeneracy, 0.01);  // a street constrains every direction
  }
}

TEST(Gicp, EmptyCloudsGiveTheGuessBackUnconverged) {
  RegistrationCloud empty;
  RegistrationCloud scan(voxelDownsample(test::kittiScan(94).points, 0.6));
  const Eigen::Isometry3d guess = core::makePose2d(1.0, 2.0, 0.3);
  for (auto* pair : {&empty, &scan}) {
    const GicpResult result = alignGicp(*pair, empty, guess, fineConfig());
    EXPECT_FALSE(result.converged);
    EXPECT_TRUE(result.T_target_source.isApprox(guess));
  }
  const GicpResult result = alignGicp(empty, scan, guess, fineConfig());
  EXPECT_FALSE(result.converged);
  EXPECT_EQ(result.inliers, 0U);
}

}  // namespace
}  // namespace dcl::registration
