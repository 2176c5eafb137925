#pragma once

/// Scan preprocessing of the LiDAR odometry (KISS-ICP, Vizzo et al. 2023):
/// drop unusable points, undo the motion during the sweep, and thin the scan
/// to one point per voxel.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <span>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::odometry {

/// A scan reduced to its usable points.
struct CleanScan {
  core::PointCloud cloud;        ///< the kept points, every channel kept alongside
  std::size_t non_finite = 0;    ///< points dropped for a NaN or infinite coordinate
  std::size_t out_of_range = 0;  ///< points dropped outside [min_range, max_range]
  std::size_t bad_time = 0;      ///< points dropped for a non-finite per-point time
};

/// Keeps the points of `scan` with finite coordinates (and finite time, when the
/// scan has times) whose range lies in [min_range, max_range] (m). An
/// inconsistent cloud (a channel of the wrong length) loses that channel.
CleanScan cleanScan(const core::PointCloud& scan, double min_range, double max_range);

/// The points of `cloud` as double-precision vectors.
std::vector<Eigen::Vector3d> toPoints(const core::PointCloud& cloud);

/// A float cloud of `points` (no channels).
core::PointCloud toCloud(std::span<const Eigen::Vector3d> points);

/// Undoes the motion during a sweep under constant velocity (KISS-ICP's
/// deskewing). `velocity` is the sensor's twist [v; omega] in its own frame
/// (m/s, rad/s), so the sensor at time t sits at T_ref_t = exp((t - reference_time)
/// velocity) relative to its pose at `reference_time` (both in seconds after the
/// stamp). Each point, measured in the sensor frame at its firing time, is
/// mapped into the sensor frame at `reference_time`. A cloud without times is
/// returned unchanged.
std::vector<Eigen::Vector3d> deskew(const core::PointCloud& cloud, const core::Vector6d& velocity,
                                    double reference_time = 0.0);

/// The sensor's motion through a sweep under constant velocity, tabulated:
/// T_reference_sensor(t) = exp(t * velocity) for t (s from the reference
/// time) in [t_min, t_max], in `bins` steps (bins of 0.1 ms move a car at
/// 20 m/s by 2 mm), so a sweep's points need one table, not one exp each.
class SweepMotion {
 public:
  SweepMotion(const core::Vector6d& velocity, double t_min, double t_max, std::size_t bins = 1024);

  /// The pose at offset `t`, clamped to the span.
  [[nodiscard]] const Eigen::Isometry3d& at(double t) const;

 private:
  std::vector<Eigen::Isometry3d> poses_;
  double t_min_;
  double scale_;  ///< bins per second
};

/// The middle of the sweep, (min + max) / 2 of the per-point times (s after the
/// stamp); 0 for a cloud without times.
double sweepMidTime(const core::PointCloud& cloud);

/// How long the sweep took, max - min of the per-point times (s); 0 for a
/// cloud without times.
double sweepDuration(const core::PointCloud& cloud);

/// The indices of the first point of `points` in each occupied voxel of edge
/// `voxel_size` (m), in the order of first occurrence (deterministic).
std::vector<std::size_t> voxelDownsampleIndices(std::span<const Eigen::Vector3d> points,
                                                double voxel_size);

/// One point per occupied voxel of edge `voxel_size` (m): the first point of
/// `points` falling in it, in the order of first occurrence (deterministic).
std::vector<Eigen::Vector3d> voxelDownsample(std::span<const Eigen::Vector3d> points,
                                             double voxel_size);

}  // namespace dcl::odometry
