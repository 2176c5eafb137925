#pragma once

/// The front-end interface (paper §III-A): scans in, poses out. The built-in
/// LiDAR odometry and external odometry (poses from a file or bag) both
/// implement it, so the rest of the system does not care which runs.

#include <Eigen/Geometry>
#include <cstddef>
#include <optional>
#include <string>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::odometry {

/// How one frame went: enough for a user to see why a pose is poor.
struct FrameHealth {
  bool accepted = false;    ///< the frame updated the pose (false: skipped, see `problem`)
  bool converged = false;   ///< the registration met its convergence criterion
  bool degenerate = false;  ///< the registration is poorly constrained in some direction
  /// The sweep's motion changed sharply (braking, a turn's onset, a jolt):
  /// its own twist was estimated with its pose instead of the last velocity.
  bool sharp_motion = false;
  int iterations = 0;               ///< registration iterations used
  std::size_t correspondences = 0;  ///< inlier correspondences at the last iteration
  double residual = 0.0;  ///< m, RMS point-to-point (or point-to-plane) residual of inliers
  std::string problem;    ///< empty when all is well; else what was wrong (skipped frames)
};

/// The result of one frame.
struct OdometryResult {
  double stamp = 0.0;  ///< s, the frame's time
  /// The sensor's pose at `stamp` in the odometry frame (the first frame's sensor pose).
  Eigen::Isometry3d T_odom_sensor = Eigen::Isometry3d::Identity();
  /// Covariance of the motion since the previous frame, tangent [rho; phi] (see core/se3.hpp).
  core::Matrix6d covariance = core::Matrix6d::Identity() * 1e-4;
  FrameHealth health;
  /// The frame's scan as registered: deskewed to `stamp`, in the sensor frame,
  /// downsampled as the odometry keeps it (empty for external odometry).
  core::PointCloud registered;
  /// The first frame went out with no velocity to deskew it by: the frame
  /// that measures the first velocity carries the first frame's `registered`
  /// again, deskewed with it, and that frame's stamp (empty otherwise). At
  /// 10 m/s the first sweep is smeared by a metre, enough to put a loop to
  /// the route's first keyframe decimetres off.
  struct Redone {
    double stamp = 0.0;
    core::PointCloud registered;
  };
  std::optional<Redone> first_frame_redone;
};

/// A front-end: call `process` once per scan, in time order.
class Odometry {
 public:
  virtual ~Odometry() = default;

  /// Processes the scan taken at `stamp` (per-point `time` relative to `stamp`
  /// when the cloud has it). Never throws on bad data: a frame it cannot use is
  /// reported with health.accepted = false and the pose predicted or held.
  virtual OdometryResult process(double stamp, const core::PointCloud& scan) = 0;

  /// The robot's IMU reading of up (against gravity; a unit vector in the
  /// sensor frame) at the stamp of the scan processed next. A front-end that
  /// levels its poses with it keeps it for that scan; the default ignores it.
  virtual void observeUp(const Eigen::Vector3d& /*up_sensor*/) {}

  /// The latest pose, T_odom_sensor.
  [[nodiscard]] virtual Eigen::Isometry3d pose() const = 0;

  /// A short name for logs and metrics ("lidar", "external").
  [[nodiscard]] virtual std::string name() const = 0;
};

}  // namespace dcl::odometry
