#pragma once

/// The IMU beside each simulated LiDAR, as far as the front-end uses it: the
/// direction up (against gravity) in the sensor frame, read with every scan.
/// LiDAR-inertial front-ends (LIO-SAM, FAST-LIO2) level their poses with it;
/// without it a LiDAR odometry drifts in roll and pitch, and its height with them.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>

namespace dcl::sim {

/// How well the IMU reads up. Its error is the unit's fixed tilt (accelerometer
/// bias and the IMU's mounting against the LiDAR) plus noise on every reading.
/// The defaults are those of KITTI's OXTS RT3003: roll and pitch to 0.03 deg (1 sigma).
struct ImuModel {
  double tilt_sigma_deg = 0.03;   ///< a unit's fixed tilt about the sensor's x and y axes, 1 sigma
  double noise_sigma_deg = 0.02;  ///< a reading's own error about each of those axes, 1 sigma

  /// rad, 1 sigma: a reading's whole error about each axis (tilt and noise),
  /// what a message carrying the reading gives as its roll and pitch covariance.
  [[nodiscard]] double readingSigma() const {
    return std::hypot(tilt_sigma_deg, noise_sigma_deg) * M_PI / 180.0;
  }
};

/// A unit's fixed tilt (rad, about the sensor's x and y axes), drawn from `seed`.
Eigen::Vector2d drawImuTilt(const ImuModel& model, std::uint64_t seed);

/// The IMU's reading of up, a unit vector in the sensor frame, for a sensor
/// oriented `R_world_sensor` in a world whose z points up: the truth turned by
/// the unit's `tilt` and by a reading error drawn from `seed`.
Eigen::Vector3d readUp(const ImuModel& model, const Eigen::Matrix3d& R_world_sensor,
                       const Eigen::Vector2d& tilt, std::uint64_t seed);

}  // namespace dcl::sim
