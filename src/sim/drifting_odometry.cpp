#include <cmath>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/sim/drifting_odometry.hpp>

#include "world_detail.hpp"

namespace dcl::sim {

namespace {

/// Uniform in [-1, 1) from draw `k` of `seed`.
double symmetric(std::uint64_t seed, std::uint64_t k) {
  return -1.0 +
         2.0 * static_cast<double>(detail::splitmix(detail::splitmix(seed) + k) >> 11) * 0x1.0p-53;
}

/// Zero-mean, unit-variance (the sum of three uniforms, scaled): no
/// standard-library distribution, whose numbers differ between libraries.
double jitter(std::uint64_t seed, std::uint64_t k) {
  return (symmetric(seed, 3 * k) + symmetric(seed, 3 * k + 1) + symmetric(seed, 3 * k + 2));
}

}  // namespace

core::Trajectory driftingOdometry(const core::Trajectory& truth, const OdometryDrift& drift) {
  for (const auto& [name, value] : {std::pair{"translation_percent", drift.translation_percent},
                                    {"rotation_deg_per_m", drift.rotation_deg_per_m},
                                    {"jitter_m", drift.jitter_m},
                                    {"jitter_deg", drift.jitter_deg}}) {
    if (!std::isfinite(value) || value < 0.0) {
      throw core::Error(
          fmt::format("odometry drift: {} must be finite and >= 0, not {}", name, value));
    }
  }
  if (truth.empty()) return truth;
  constexpr double kDeg = M_PI / 180.0;
  // The systematic part: the sign of the scale error and of the turn, and the
  // turn's axis, tilted up to 0.1 rad from the vertical.
  const double scale =
      1.0 + (symmetric(drift.seed, 0) < 0.0 ? -1.0 : 1.0) * drift.translation_percent / 100.0;
  const double turn =
      (symmetric(drift.seed, 1) < 0.0 ? -1.0 : 1.0) * drift.rotation_deg_per_m * kDeg;
  const double azimuth = M_PI * symmetric(drift.seed, 2);
  const Eigen::Vector3d axis =
      Eigen::Vector3d(0.1 * std::cos(azimuth), 0.1 * std::sin(azimuth), 1.0).normalized();
  const std::uint64_t noise_seed = detail::splitmix(drift.seed ^ 0x5DEECE66Dull);

  // Rotations as written to a few digits (a KITTI file's) are first made rotations.
  const auto pose = [&](std::size_t i) {
    Eigen::Isometry3d T = truth.pose(i);
    T.linear() = Eigen::Quaterniond(T.rotation()).normalized().toRotationMatrix();
    return T;
  };
  core::Trajectory out;
  Eigen::Isometry3d T = pose(0);
  out.push_back(truth.stamp(0), T);
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const Eigen::Isometry3d motion = pose(i - 1).inverse() * pose(i);
    const double length = motion.translation().norm();
    const std::uint64_t k = 2 * i;
    const Eigen::Vector3d dt(jitter(noise_seed, 3 * k), jitter(noise_seed, 3 * k + 1),
                             jitter(noise_seed, 3 * k + 2));
    const Eigen::Vector3d dr(jitter(noise_seed, 3 * k + 3), jitter(noise_seed, 3 * k + 4),
                             jitter(noise_seed, 3 * k + 5));
    Eigen::Isometry3d reported = Eigen::Isometry3d::Identity();
    reported.translation() = scale * motion.translation() + drift.jitter_m * dt;
    const Eigen::Vector3d rotation = turn * length * axis + drift.jitter_deg * kDeg * dr;
    const double angle = rotation.norm();
    const Eigen::Matrix3d R = angle > 0.0
                                  ? Eigen::AngleAxisd(angle, rotation / angle).toRotationMatrix()
                                  : Eigen::Matrix3d::Identity();
    reported.linear() = R * motion.rotation();
    T = T * reported;
    out.push_back(truth.stamp(i), T);
  }
  return out;
}

}  // namespace dcl::sim
