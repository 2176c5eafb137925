#pragma once

// A simulated external front-end: the ground truth as a LiDAR-inertial
// odometry would report it, drifting with the distance travelled, for runs that
// feed a swarm its robots' own odometry (dataset.yaml `odometry`) instead of
// the built-in one.

#include <cstdint>

#include <dcl/core/trajectory.hpp>

namespace dcl::sim {

/// How the front-end drifts: a systematic error proportional to the distance
/// travelled (a scale error of the motion, a heading that turns slowly), plus a
/// little jitter at each pose. The KITTI metric counts the turn in the
/// translation error too: 1 % and 0.01 deg/m measure about 2.2 % and
/// 0.01 deg/m on KITTI 05's streets.
struct OdometryDrift {
  double translation_percent = 1.0;  ///< % of each motion's length: a scale error
  double rotation_deg_per_m = 0.01;  ///< deg per m travelled, about an axis near the vertical
  double jitter_m = 0.002;           ///< m, standard deviation of each motion's own error
  double jitter_deg = 0.01;          ///< deg, the same for its rotation
  std::uint64_t seed = 1;            ///< the signs, the axis and the jitter derive from it
};

/// `truth` (T_world_sensor) as the drifting front-end reports it, in the same
/// world frame and at the same stamps: each motion between two poses scaled,
/// turned and jittered, then chained from the first pose. The same numbers on
/// every machine for the same seed. Throws core::Error when a field is negative
/// or not finite.
core::Trajectory driftingOdometry(const core::Trajectory& truth, const OdometryDrift& drift);

}  // namespace dcl::sim
