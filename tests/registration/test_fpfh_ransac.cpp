// FPFH features and RANSAC, the guess-free global registration: invariance
// of the features, mutual matching, and the outdoor pair recovered from
// arbitrary headings without any hint.

#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/registration/fpfh.hpp>
#include <dcl/registration/ransac.hpp>
#include <dcl/registration/voxel_filter.hpp>

#include "registration_test_data.hpp"

namespace dcl::registration {
namespace {

using test::poseError;

/// Features of `points` filtered at 1 m, as the verification's fallback computes them.
struct Described {
  RegistrationCloud cloud;
  std::vector<FpfhFeature> features;
};

Described describe(const std::vector<Eigen::Vector3f>& points) {
  Described d{RegistrationCloud(voxelDownsample(points, 1.0)), {}};
  d.features = computeFpfh(d.cloud);
  return d;
}

TEST(Fpfh, FeaturesDoNotDependOnTheHeading) {
  const core::PointCloud scan = test::kittiScan(94);
  Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
  turn.linear() = Eigen::AngleAxisd(2.0, Eigen::Vector3d(0.1, 0.2, 1.0).normalized()).matrix();
  const std::vector<Eigen::Vector3d> filtered = voxelDownsample(scan.points, 1.0);
  std::vector<Eigen::Vector3d> turned;
  for (const Eigen::Vector3d& p : filtered) turned.push_back(turn * p);
  RegistrationCloud a(filtered);
  RegistrationCloud b(turned);
  const std::vector<FpfhFeature> fa = computeFpfh(a);
  const std::vector<FpfhFeature> fb = computeFpfh(b);
  ASSERT_EQ(fa.size(), fb.size());
  std::size_t nonzero = 0;
  for (const FpfhFeature& f : fa) {
    if (f.squaredNorm() == 0.0F) continue;
    ++nonzero;
    for (int part = 0; part < 3; ++part) EXPECT_NEAR(f.segment<11>(11 * part).sum(), 100.0F, 1e-3F);
  }
  EXPECT_GT(nonzero, fa.size() * 9 / 10);
  // Each point's feature is still its own best match in the turned cloud. A
  // few differ where rounding tips an angle over a bin edge, swaps the last of
  // the nearest neighbours, or flips a normal seen edge-on.
  std::size_t own = 0;
  for (const Correspondence& c : matchFeatures(fa, fb, 0.0)) own += c.source == c.target ? 1 : 0;
  std::printf("FPFH invariance: %zu of %zu features match themselves after the turn\n", own,
              nonzero);
  EXPECT_GT(own, nonzero * 97 / 100);
}

TEST(Fpfh, MatchesAreMutualNearestNeighbours) {
  const Described a = describe(test::kittiScan(198).points);
  const Described b = describe(test::kittiScan(199).points);
  const std::vector<Correspondence> exact = matchFeatures(a.features, b.features, 0.0);
  ASSERT_GT(exact.size(), 100U);
  auto nearest = [](const FpfhFeature& f, const std::vector<FpfhFeature>& in) {
    std::size_t best = 0;
    for (std::size_t i = 1; i < in.size(); ++i)
      if ((in[i] - f).squaredNorm() < (in[best] - f).squaredNorm()) best = i;
    return best;
  };
  for (std::size_t k = 0; k < exact.size(); k += 25) {
    EXPECT_EQ(nearest(a.features[exact[k].source], b.features), exact[k].target);
    EXPECT_EQ(nearest(b.features[exact[k].target], a.features), exact[k].source);
  }
  // Approximate search keeps most of them and stays mutual.
  const std::vector<Correspondence> fast = matchFeatures(a.features, b.features);
  EXPECT_GT(fast.size(), exact.size() * 8 / 10);
  EXPECT_TRUE(matchFeatures({}, b.features).empty());
}

/// The outdoor pair's source seen from a frame turned by `yaw` and shifted:
/// returns the turned source and the transform that now maps it to the target.
std::pair<core::PointCloud, Eigen::Isometry3d> turnedSource(const test::OutdoorPair& pair,
                                                            double yaw_deg) {
  const Eigen::Isometry3d D = core::makePose2d(1.0, 1.5, core::deg2rad(yaw_deg));
  return {core::transformed(pair.source, D), pair.T_target_source * D.inverse()};
}

TEST(Ransac, RecoversTheOutdoorPairFromAnyHeading) {
  const test::OutdoorPair pair = test::outdoorPairPly();
  const Described target = describe(pair.target.points);
  for (double yaw : {90.0, 180.0, -135.0}) {
    const auto [source_cloud, truth] = turnedSource(pair, yaw);
    const Described source = describe(source_cloud.points);
    const std::vector<Correspondence> matches = matchFeatures(source.features, target.features);
    const RansacResult result =
        ransacRegistration(source.cloud.points(), target.cloud.points(), matches);
    ASSERT_TRUE(result.found) << yaw;
    const auto error = poseError(result.T_target_source, truth);
    // Coarse (1 m voxels): close enough for GICP to take over.
    EXPECT_LT(error.translation, 0.5) << yaw;
    EXPECT_LT(error.rotation_deg, 2.0) << yaw;
    EXPECT_GT(result.inliers, 50U) << yaw;
  }
}

TEST(Ransac, IsReproducibleAndFindsNothingBetweenDifferentPlaces) {
  const Described a = describe(test::kittiScan(0).points);
  const Described b = describe(test::kittiScan(198).points);
  const std::vector<Correspondence> matches = matchFeatures(a.features, b.features);
  RansacConfig config;
  config.max_iterations = 20000;
  const RansacResult first =
      ransacRegistration(a.cloud.points(), b.cloud.points(), matches, config);
  EXPECT_FALSE(first.found);  // 0 and 198 are 100 m apart
  EXPECT_EQ(first.iterations, config.max_iterations);
  const Described c = describe(test::kittiScan(199).points);
  const std::vector<Correspondence> true_matches = matchFeatures(b.features, c.features);
  const RansacResult one = ransacRegistration(b.cloud.points(), c.cloud.points(), true_matches);
  const RansacResult two = ransacRegistration(b.cloud.points(), c.cloud.points(), true_matches);
  ASSERT_TRUE(one.found);
  EXPECT_TRUE(one.T_target_source.matrix() == two.T_target_source.matrix());
  EXPECT_EQ(one.inliers, two.inliers);
  EXPECT_LT(poseError(one.T_target_source, test::kittiTruth(198, 199)).translation, 0.5);
}

TEST(Ransac, IgnoresBadCorrespondencesInsteadOfCrashing) {
  const std::vector<Eigen::Vector3d> points = {{0, 0, 0}, {5, 0, 0}, {0, 5, 0}, {0, 0, 5}};
  const std::vector<Correspondence> bad = {{0, 0}, {1, 99}, {99, 1}, {7, 7}};
  EXPECT_FALSE(ransacRegistration(points, points, bad).found);  // one valid pair left
  EXPECT_FALSE(ransacRegistration({}, points, bad).found);
  std::vector<Correspondence> identity;
  for (std::uint32_t i = 0; i < 4; ++i) identity.push_back({i, i});
  RansacConfig config;
  config.min_inliers = 4;
  const RansacResult result = ransacRegistration(points, points, identity, config);
  ASSERT_TRUE(result.found);
  EXPECT_TRUE(result.T_target_source.isApprox(Eigen::Isometry3d::Identity(), 1e-9));
}

}  // namespace
}  // namespace dcl::registration
