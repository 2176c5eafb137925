// The paper's keyframe selector: thresholds, stored clouds, and the odometry
// factor's relative pose and covariance (checked against Monte Carlo).

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/odometry/keyframe_selector.hpp>

namespace dcl::odometry {
namespace {

OdometryResult frame(double stamp, const Eigen::Isometry3d& T, bool accepted = true) {
  OdometryResult r;
  r.stamp = stamp;
  r.T_odom_sensor = T;
  r.health.accepted = accepted;
  return r;
}

Eigen::Isometry3d step(double forward, double yaw) {
  return core::makePose2d(forward, 0.0, yaw);
}

TEST(KeyframeSelector, TranslationThresholdMakesKeyframes) {
  KeyframeSelector selector(core::RobotId(2));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  std::vector<int> keyframe_frames;
  std::optional<core::Keyframe> last;
  for (int i = 0; i < 20; ++i) {
    if (auto kf = selector.add(frame(0.1 * i, T))) {
      keyframe_frames.push_back(i);
      EXPECT_EQ(kf->robot, core::RobotId(2));
      EXPECT_EQ(kf->id, core::KeyframeId(keyframe_frames.size() - 1));
      EXPECT_TRUE(kf->T_odom_keyframe.isApprox(T));
      if (last) {
        EXPECT_TRUE(kf->T_previous_keyframe.isApprox(last->T_odom_keyframe.inverse() * T));
      }
      last = kf;
    }
    T = T * step(0.3, 0.0);
  }
  // 0.3 m a frame: past 1.0 m after 4 frames (1.2 m).
  EXPECT_EQ(keyframe_frames, (std::vector<int>{0, 4, 8, 12, 16}));
  EXPECT_EQ(selector.count(), 5u);
}

TEST(KeyframeSelector, RotationThresholdMakesKeyframes) {
  KeyframeSelector selector(core::RobotId(0));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  std::vector<int> keyframe_frames;
  for (int i = 0; i < 10; ++i) {
    if (selector.add(frame(i, T))) keyframe_frames.push_back(i);
    T = T * step(0.0, 0.06);  // turning on the spot: 0.24 rad after 4 frames
  }
  EXPECT_EQ(keyframe_frames, (std::vector<int>{0, 4, 8}));
}

TEST(KeyframeSelector, SkippedFramesAndBadPosesAreNeverKeyframes) {
  KeyframeSelector selector(core::RobotId(0));
  EXPECT_FALSE(selector.add(frame(0, Eigen::Isometry3d::Identity(), false)));
  EXPECT_TRUE(selector.add(frame(1, Eigen::Isometry3d::Identity())));  // the first accepted frame
  EXPECT_FALSE(selector.add(frame(2, step(5.0, 0.0), false)));         // held, not measured
  Eigen::Isometry3d nan = step(5.0, 0.0);
  nan.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(selector.add(frame(3, nan)));
  const auto kf = selector.add(frame(4, step(5.0, 0.0)));
  ASSERT_TRUE(kf);
  EXPECT_TRUE(kf->covariance.allFinite());
  EXPECT_EQ(kf->id, core::KeyframeId(1));
}

TEST(KeyframeSelector, StoresTheScanVoxelFiltered) {
  KeyframeConfig config;
  config.voxel_size = 1.0;
  KeyframeSelector selector(core::RobotId(0), config);
  core::PointCloud scan;
  for (int i = 0; i < 1000; ++i) scan.points.emplace_back(0.01f * i, 0.5f, 0.5f);  // 10 m line
  scan.points.emplace_back(std::numeric_limits<float>::quiet_NaN(), 0.f, 0.f);
  const auto kf = selector.add(frame(0, Eigen::Isometry3d::Identity()), scan);
  ASSERT_TRUE(kf);
  EXPECT_EQ(kf->cloud.size(), 10u);  // one point per 1 m voxel, the NaN dropped
  EXPECT_EQ(kf->covariance, core::Matrix6d::Zero());
}

/// The covariance of log(T_hat^-1 T) over samples of noisy composed steps.
core::Matrix6d monteCarloCovariance(const std::vector<Eigen::Isometry3d>& steps,
                                    const core::Matrix6d& step_covariance, int samples) {
  std::mt19937 rng(42);
  std::normal_distribution<double> normal;
  const Eigen::LLT<core::Matrix6d> llt(step_covariance);
  Eigen::Isometry3d T_hat = Eigen::Isometry3d::Identity();
  for (const auto& s : steps) T_hat = T_hat * s;
  core::Matrix6d sum = core::Matrix6d::Zero();
  for (int n = 0; n < samples; ++n) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (const auto& s : steps) {
      core::Vector6d z;
      for (int j = 0; j < 6; ++j) z[j] = normal(rng);
      T = T * s * core::expSE3(llt.matrixL() * z);  // noise on the right, as OdometryResult says
    }
    const core::Vector6d xi = core::logSE3(T_hat.inverse() * T);
    sum += xi * xi.transpose();
  }
  return sum / samples;
}

TEST(KeyframeSelector, OdometryFactorCovarianceMatchesMonteCarlo) {
  // Ten frames of a curving drive with rotation noise: the lever arm of the
  // early heading errors shows in the late translation covariance.
  const core::Matrix6d step_covariance =
      core::Vector6d(1e-4, 4e-4, 1e-4, 1e-5, 2e-5, 4e-5).asDiagonal();
  std::vector<Eigen::Isometry3d> steps(10, step(0.12, 0.015));
  KeyframeConfig config;
  config.translation = 1.1;  // the keyframe after the tenth step (1.2 m)
  KeyframeSelector selector(core::RobotId(0), config);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  ASSERT_TRUE(selector.add(frame(0, T)));
  std::optional<core::Keyframe> kf;
  for (std::size_t i = 0; i < steps.size(); ++i) {
    T = T * steps[i];
    OdometryResult r = frame(1.0 + i, T);
    r.covariance = step_covariance;
    kf = selector.add(r);
    if (i + 1 < steps.size()) {
      ASSERT_FALSE(kf) << i;
    }
  }
  ASSERT_TRUE(kf);
  const core::Matrix6d expected = monteCarloCovariance(steps, step_covariance, 20000);
  const core::Matrix6d& got = kf->covariance;
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(got(i, i), expected(i, i), 0.05 * expected(i, i)) << i;
  }
  // Heading noise feeds the lateral translation: above ten steps' worth of its own noise.
  EXPECT_GT(got(1, 1), 10 * step_covariance(1, 1));
  EXPECT_NEAR(got(1, 5), expected(1, 5), 0.1 * std::abs(expected(1, 5)));
}

}  // namespace
}  // namespace dcl::odometry
