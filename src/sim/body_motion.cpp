/// The vehicle body rocking on its suspension (rockBody): two damped springs,
/// pitch and roll, driven by the trajectory's own accelerations and by the
/// road's roughness.

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <dcl/core/se3.hpp>
#include <dcl/sim/routes.hpp>

#include "world_detail.hpp"

namespace dcl::sim {
namespace {

using core::deg2rad;

constexpr double kSubstep = 1e-3;  ///< s, the springs' integration step

/// What drives the body at one pose: the tilt its accelerations ask for
/// (rad, pitch about y and roll about x) and its speed, by which the road
/// shakes it.
struct Drive {
  Eigen::Vector2d equilibrium = Eigen::Vector2d::Zero();
  double speed = 0.0;  ///< m/s, horizontal
};

/// How hard the road shakes a body moving at `speed` (0-1).
double shakeAt(double speed, const BodyMotion& motion) {
  return motion.full_speed > 0.0 ? std::min(1.0, speed / motion.full_speed) : 1.0;
}

double bodyHeading(const Eigen::Isometry3d& T) {
  const Eigen::Vector3d x = T.linear().col(0);
  return std::atan2(x.y(), x.x());
}

double wrappedAngle(double angle) {
  return std::remainder(angle, 2.0 * M_PI);
}

/// The drive at every pose, from central differences of the trajectory (one-sided at its ends).
std::vector<Drive> drives(const core::Trajectory& T, const BodyMotion& motion) {
  const std::size_t n = T.size();
  const auto neighbours = [n](std::size_t i) {
    return std::array<std::size_t, 2>{i == 0 ? 0 : i - 1, i + 1 == n ? i : i + 1};
  };
  std::vector<double> speed(n), yaw_rate(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto [a, b] = neighbours(i);
    const double dt = T.stamp(b) - T.stamp(a);
    if (dt <= 0.0) continue;
    const Eigen::Vector3d d = T.pose(b).translation() - T.pose(a).translation();
    speed[i] = d.head<2>().norm() / dt;
    yaw_rate[i] = wrappedAngle(bodyHeading(T.pose(b)) - bodyHeading(T.pose(a))) / dt;
  }
  std::vector<Drive> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto [a, b] = neighbours(i);
    const double dt = T.stamp(b) - T.stamp(a);
    const double along = dt > 0.0 ? (speed[b] - speed[a]) / dt : 0.0;
    const double across = speed[i] * yaw_rate[i];
    // Braking (along < 0) dips the nose: a positive turn about y (y to the
    // left) takes x down. A left turn (across > 0) rolls the body out to the
    // right: a positive turn about x raises the left side.
    out[i].equilibrium << -deg2rad(motion.pitch_per_accel_deg) * along,
        deg2rad(motion.roll_per_accel_deg) * across;
    out[i].speed = speed[i];
  }
  return out;
}

/// The body's pitch and roll (rad) at every pose: both springs integrated
/// from rest through the drives, the equilibrium and the shake interpolated
/// linearly between poses.
std::vector<Eigen::Vector2d> integrate(const core::Trajectory& T, const std::vector<Drive>& drive,
                                       const BodyMotion& motion, std::uint64_t seed) {
  const double omega = 2.0 * M_PI * motion.frequency_hz;
  const double zeta = motion.damping;
  // White noise of two-sided density S through x'' + 2 zeta omega x' +
  // omega^2 x = f leaves x with variance S / (4 zeta omega^3); a force held
  // for a step of dt has density sigma_f^2 dt.
  const double sigma = deg2rad(motion.road_sigma_deg);
  const double force_sigma =
      std::sqrt(4.0 * zeta * omega * omega * omega * sigma * sigma / kSubstep);
  detail::Rng rng(seed * 0x9E3779B97F4A7C15ull + 0xB0D1ull);
  // Bumps (a joint, a pothole, a kerb) every `bump_spacing` metres on
  // average, each a kick to both springs' rates that swings the body by
  // about `bump_deg` (a kicked spring peaks near 0.7 of kick / omega).
  const auto next_bump = [&] {
    return motion.bump_spacing > 0.0 ? -std::log(1.0 - rng.uniform()) * motion.bump_spacing
                                     : INFINITY;
  };
  const double kick_sigma = deg2rad(motion.bump_deg) * omega / 0.7;
  double to_bump = next_bump();
  Eigen::Vector2d angle = drive.front().equilibrium;
  Eigen::Vector2d rate = Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector2d> out(T.size());
  out[0] = angle;
  for (std::size_t i = 1; i < T.size(); ++i) {
    const double span = T.stamp(i) - T.stamp(i - 1);
    const auto steps = static_cast<std::size_t>(std::ceil(std::max(span, 0.0) / kSubstep));
    for (std::size_t k = 0; k < steps; ++k) {
      const double w = (static_cast<double>(k) + 1.0) / static_cast<double>(steps);
      const Eigen::Vector2d target =
          (1.0 - w) * drive[i - 1].equilibrium + w * drive[i].equilibrium;
      const double shake =
          (1.0 - w) * shakeAt(drive[i - 1].speed, motion) + w * shakeAt(drive[i].speed, motion);
      const double dt = span / static_cast<double>(steps);
      to_bump -= ((1.0 - w) * drive[i - 1].speed + w * drive[i].speed) * dt;
      if (to_bump <= 0.0) {
        rate += kick_sigma * Eigen::Vector2d(rng.gaussian(), rng.gaussian());
        to_bump = next_bump();
      }
      const Eigen::Vector2d force(shake * force_sigma * rng.gaussian(),
                                  shake * force_sigma * rng.gaussian());
      rate += (force - 2.0 * zeta * omega * rate - omega * omega * (angle - target)) * dt;
      angle += rate * dt;
    }
    out[i] = angle;
  }
  return out;
}

}  // namespace

core::Trajectory rockBody(const core::Trajectory& T_world_sensor, double mount_height,
                          std::uint64_t seed, const BodyMotion& motion) {
  if (T_world_sensor.size() < 3) return T_world_sensor;
  const std::vector<Eigen::Vector2d> tilt =
      integrate(T_world_sensor, drives(T_world_sensor, motion), motion, seed);
  const Eigen::Vector3d up(0.0, 0.0, mount_height);
  core::Trajectory out = T_world_sensor;
  for (std::size_t i = 0; i < out.size(); ++i) {
    const Eigen::Matrix3d rock = (Eigen::AngleAxisd(tilt[i].x(), Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(tilt[i].y(), Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix();
    Eigen::Isometry3d& T = out.pose(i);
    // Pivoting on the ground under the sensor: the sensor's place moves by the
    // turn of the mast that holds it.
    T.translation() += T.linear() * (rock * up - up);
    T.linear() = T.linear() * rock;
  }
  return out;
}

}  // namespace dcl::sim
