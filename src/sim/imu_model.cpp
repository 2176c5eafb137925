#include <Eigen/Geometry>
#include <cmath>

#include <dcl/sim/imu_model.hpp>

#include "world_detail.hpp"

namespace dcl::sim {
namespace {

constexpr double kRadPerDeg = M_PI / 180.0;

/// Two independent normals of `sigma_deg` degrees, in radians.
Eigen::Vector2d tiltOf(double sigma_deg, std::uint64_t seed) {
  detail::Rng random(seed);
  const double x = random.gaussian();
  const double y = random.gaussian();
  return sigma_deg * kRadPerDeg * Eigen::Vector2d(x, y);
}

}  // namespace

Eigen::Vector2d drawImuTilt(const ImuModel& model, std::uint64_t seed) {
  return tiltOf(model.tilt_sigma_deg, seed);
}

Eigen::Vector3d readUp(const ImuModel& model, const Eigen::Matrix3d& R_world_sensor,
                       const Eigen::Vector2d& tilt, std::uint64_t seed) {
  const Eigen::Vector2d error = tilt + tiltOf(model.noise_sigma_deg, seed);
  const Eigen::Vector3d axis(error.x(), error.y(), 0.0);
  const Eigen::Vector3d up = R_world_sensor.transpose() * Eigen::Vector3d::UnitZ();
  const double angle = axis.norm();
  if (angle == 0.0) return up;
  return (Eigen::AngleAxisd(angle, axis / angle) * up).normalized();
}

}  // namespace dcl::sim
