// An IMU's readings of up by stamp: the nearest within a gap, in any order.
#include <gtest/gtest.h>

#include <dcl/ros/imu_readings.hpp>

#include "imu_test_messages.hpp"

namespace dcl::msg {
namespace {

Eigen::Vector3d tilted(double x) {
  return Eigen::Vector3d(x, 0.0, 1.0).normalized();
}

TEST(UpReadings, TheNearestReadingWithinTheGapWhateverOrderTheyCameIn) {
  UpReadings readings;
  for (const double t : {10.00, 10.02, 9.98, 10.04, 10.01}) readings.add(t, tilted(t - 10.0));
  EXPECT_EQ(readings.size(), 5u);
  EXPECT_LT((*readings.nearest(10.013, 0.05) - tilted(0.01)).norm(), 1e-15);
  EXPECT_LT((*readings.nearest(10.017, 0.05) - tilted(0.02)).norm(), 1e-15);
  EXPECT_LT((*readings.nearest(9.90, 0.1) - tilted(-0.02)).norm(), 1e-15);
  EXPECT_FALSE(readings.nearest(9.90, 0.05).has_value());
  EXPECT_FALSE(readings.nearest(10.2, 0.05).has_value());
  EXPECT_TRUE(readings.reaches(10.04));
  EXPECT_FALSE(readings.reaches(10.041));
  readings.dropBefore(10.015);
  EXPECT_EQ(readings.size(), 2u);
  EXPECT_LT((*readings.nearest(10.0, 0.05) - tilted(0.02)).norm(), 1e-15);
}

TEST(UpReadings, AnImuWithoutOrientationAddsNothing) {
  UpReadings readings;
  EXPECT_FALSE(readings.add(test::imuWithoutOrientation(100.0), Eigen::Matrix3d::Identity()));
  EXPECT_EQ(readings.size(), 0u);
  // An orientation is kept at its stamp plus the offset to the robot's clock.
  EXPECT_TRUE(readings.add(test::imuMessage(100.0), Eigen::Matrix3d::Identity(), -99.5));
  EXPECT_TRUE(readings.nearest(0.5, 1e-9).has_value());
}

TEST(UpReadings, RollPitchYawTurnAboutFixedAxes) {
  // Roll about the fixed x first, then yaw about the fixed z: y goes to z
  // and stays; x stays, then goes to y.
  const Eigen::Matrix3d R = rotationOfRpy(90.0, 0.0, 90.0);
  EXPECT_LT((R * Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_LT((R * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  EXPECT_LT((rotationOfRpy(0, 90, 0) * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitX()).norm(),
            1e-12);
}

}  // namespace
}  // namespace dcl::msg
