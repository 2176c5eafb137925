// The simulated IMU's reading of up: the truth turned by the unit's fixed
// tilt and by each reading's noise, each of the model's spread, from seeds.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>

#include <gtest/gtest.h>

#include <dcl/core/se3.hpp>
#include <dcl/sim/imu_model.hpp>

namespace dcl::sim {
namespace {

/// The angle (deg) between two directions.
double angleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return core::rad2deg(std::atan2(a.cross(b).norm(), a.dot(b)));
}

/// A sensor rolled, pitched and turned on the spot.
Eigen::Matrix3d someAttitude() {
  return (Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(-0.03, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

TEST(ImuModel, APerfectUnitReadsTheTrueUpInTheSensorFrame) {
  const Eigen::Matrix3d R = someAttitude();
  const Eigen::Vector3d up =
      readUp({.tilt_sigma_deg = 0.0, .noise_sigma_deg = 0.0}, R, Eigen::Vector2d::Zero(), 5);
  EXPECT_LT((R * up - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
}

TEST(ImuModel, AUnitsTiltAndItsReadingsNoiseHaveTheModelsSpread) {
  const ImuModel model;  // KITTI's OXTS: 0.03 deg per axis
  const Eigen::Matrix3d R = someAttitude();
  const Eigen::Vector3d truth = R.transpose() * Eigen::Vector3d::UnitZ();
  constexpr int kDraws = 4000;
  double tilt_x2 = 0.0, tilt_y2 = 0.0, noise2 = 0.0;
  for (int i = 0; i < kDraws; ++i) {
    const Eigen::Vector2d tilt = drawImuTilt(model, 1000 + static_cast<std::uint64_t>(i));
    tilt_x2 += tilt.x() * tilt.x();
    tilt_y2 += tilt.y() * tilt.y();
    // A unit without tilt: what is left is the reading's own noise, two axes.
    const Eigen::Vector3d up =
        readUp(model, R, Eigen::Vector2d::Zero(), static_cast<std::uint64_t>(i));
    EXPECT_NEAR(up.norm(), 1.0, 1e-12);
    noise2 += std::pow(angleDeg(up, truth), 2);
  }
  // Sample standard deviations of 4000 draws: within 5 % of the model's.
  EXPECT_NEAR(core::rad2deg(std::sqrt(tilt_x2 / kDraws)), model.tilt_sigma_deg, 0.0015);
  EXPECT_NEAR(core::rad2deg(std::sqrt(tilt_y2 / kDraws)), model.tilt_sigma_deg, 0.0015);
  EXPECT_NEAR(std::sqrt(noise2 / (2 * kDraws)), model.noise_sigma_deg, 0.001);
}

TEST(ImuModel, AFixedTiltTurnsEveryReadingAlikeInTheSensorFrame) {
  const ImuModel still{.tilt_sigma_deg = 0.03, .noise_sigma_deg = 0.0};
  const Eigen::Vector2d tilt(core::deg2rad(0.05), 0.0);  // about the sensor's x axis
  for (const double yaw : {0.0, 1.0, 2.5}) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d up = readUp(still, R, tilt, 3);
    // Whichever way the vehicle heads, the reading leans 0.05 deg toward -y
    // of the sensor (a turn about +x takes z toward -y).
    EXPECT_NEAR(angleDeg(up, Eigen::Vector3d::UnitZ()), 0.05, 1e-9);
    EXPECT_LT(up.y(), 0.0);
    EXPECT_NEAR(up.x(), 0.0, 1e-12);
  }
  // The same seed gives the same reading; another seed another.
  const ImuModel model;
  EXPECT_EQ(readUp(model, someAttitude(), tilt, 9), readUp(model, someAttitude(), tilt, 9));
  EXPECT_NE(readUp(model, someAttitude(), tilt, 9), readUp(model, someAttitude(), tilt, 10));
}

}  // namespace
}  // namespace dcl::sim
