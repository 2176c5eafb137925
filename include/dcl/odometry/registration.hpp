#pragma once

/// Robust ICP of a scan against a voxel map (KISS-ICP, Vizzo et al. 2023):
/// Gauss-Newton on SE(3) with a Geman-McClure kernel, correspondences from
/// the voxel map's 27-voxel neighbourhood, point-to-plane residuals by default
/// (point-to-point as KISS-ICP on request), and KISS-ICP's adaptive
/// correspondence threshold estimated from the recent model deviation.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <span>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/odometry/voxel_map.hpp>

namespace dcl::odometry {

/// How ICP runs.
struct IcpConfig {
  static constexpr int kMaxNormalNeighbors = 16;  ///< map points of a normal at most

  int max_iterations = 100;                ///< Gauss-Newton iterations at most
  double convergence_criterion = 1e-4;     ///< stop when the update's norm (m and rad) falls below
  double max_correspondence_distance = 3;  ///< m, pairs farther apart are not correspondences
  double kernel_scale = 1.0;               ///< m, Geman-McClure scale (KISS-ICP: threshold / 3)
  bool point_to_plane = true;  ///< residuals along local map normals (false: point-to-point)
  int normal_neighbors = 10;   ///< map points fitted for a local normal (point-to-plane)
  double max_planarity = 0.3;  ///< normals from flatter fits only: smallest/middle eigenvalue
  double min_spread = 0.1;     ///< and not from lines (one laser ring): middle/largest eigenvalue
  std::size_t min_inliers = 100;  ///< fewer correspondences than this: not converged
  /// m, a source point keeps its correspondence until it moves this far (saves searches)
  double reassociation_distance = 0.05;
  /// Degenerate when the weakest direction of the scaled normal matrix carries less than
  /// this fraction of its strongest (rotations scaled by the scan's RMS range).
  double degeneracy_threshold = 1e-3;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("max_iterations", max_iterations, "Gauss-Newton iterations at most").positive();
    v.field("convergence_criterion", convergence_criterion, "stop below this update norm")
        .positive();
    v.field("max_correspondence_distance", max_correspondence_distance,
            "m, farthest correspondence (the odometry sets it adaptively)")
        .positive();
    v.field("kernel_scale", kernel_scale, "m, Geman-McClure scale (the odometry sets it)")
        .positive();
    v.field("point_to_plane", point_to_plane, "point-to-plane residuals (false: point-to-point)");
    // A plane needs three points; the search keeps no more than kMaxNormalNeighbors.
    v.field("normal_neighbors", normal_neighbors, "map points fitted for a local normal")
        .within(3, kMaxNormalNeighbors);
    v.field("max_planarity", max_planarity, "smallest/middle eigenvalue for a usable normal")
        .within(0.0, 1.0);
    v.field("min_spread", min_spread, "middle/largest eigenvalue for a usable normal (no lines)")
        .within(0.0, 1.0);
    v.field("min_inliers", min_inliers, "fewest correspondences for convergence").positive();
    v.field("reassociation_distance", reassociation_distance,
            "m, a point keeps its correspondence until it moves this far")
        .nonNegative();
    v.field("degeneracy_threshold", degeneracy_threshold,
            "weakest/strongest scaled eigenvalue below which a fit is degenerate")
        .within(0.0, 1.0, core::Interval::open_high);
  }
};

/// The outcome of one registration.
struct RegistrationResult {
  /// The estimate: maps source points into the target (map) frame.
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  bool converged = false;   ///< the update fell below the criterion with enough inliers
  bool degenerate = false;  ///< some direction of motion is poorly constrained by the scene
  int iterations = 0;       ///< Gauss-Newton iterations run
  std::size_t inliers = 0;  ///< correspondences at the last linearisation
  double rmse = 0.0;        ///< m, RMS residual of those correspondences
  /// J^T W J of the final linearisation for a perturbation on the right,
  /// T_target_source * exp(xi), tangent [rho; phi] in the source frame
  /// (unit residual variance: scale by 1 / rmse^2 for a covariance-weighted information).
  core::Matrix6d information = core::Matrix6d::Zero();
};

/// Registers `source_points` (in the source frame) against `target_map` (in the
/// target frame), starting from `T_target_source_guess`. Never throws: an empty
/// map or scan gives converged = false and the guess back.
RegistrationResult registerScan(std::span<const Eigen::Vector3d> source_points,
                                const VoxelHashMap& target_map,
                                const Eigen::Isometry3d& T_target_source_guess,
                                const IcpConfig& config);

/// A sweep as registration takes it: every point in the sensor frame at its
/// firing time, and that time (s) relative to the reference time whose pose
/// is estimated (the sweep's middle). Empty offsets: a rigid scan.
struct SweepPoints {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> offsets;  ///< one per point, or none
};

/// What is known of a sweep's own motion before it is registered: the
/// predicted twist and how far the sweep's twist may stray from it.
struct SweepMotionPrior {
  core::Vector6d velocity = core::Vector6d::Zero();  ///< [v; omega], sensor frame (m/s, rad/s)
  core::Vector6d sigma = core::Vector6d::Ones();     ///< standard deviation about it, per axis
};

/// The outcome of a sweep's registration: its pose and its own motion.
struct SweepRegistration {
  RegistrationResult registration;                   ///< the pose at the reference time
  core::Vector6d velocity = core::Vector6d::Zero();  ///< the twist that deskews the sweep
};

/// Registers a sweep whose motion during the sweep is unknown: its pose at
/// the reference time and its twist [v; omega] are estimated together (the
/// continuous-time idea of CT-ICP, Dellenbach et al. 2022, with one twist a
/// sweep instead of a begin and an end pose), each point placed by the
/// twist at its own time. A sweep deskewed with the motion before it is bent
/// where the motion changed (braking into a turn bends a sweep by a degree at
/// its ends); here the bend is part of what is fitted. The prior holds the
/// twist where the scene does not see it (a point residual weighs as noise
/// of `config.kernel_scale`). Without offsets this is registerScan.
SweepRegistration registerSweep(const SweepPoints& sweep, const VoxelHashMap& target_map,
                                const Eigen::Isometry3d& T_target_source_guess,
                                const SweepMotionPrior& prior, const IcpConfig& config);

/// How the adaptive threshold starts and what motion it learns from.
struct AdaptiveThresholdConfig {
  double initial_threshold = 2.0;  ///< m, sigma before any motion was seen (KISS-ICP: 2.0)
  double min_motion = 0.1;         ///< m, frames moving less do not update the estimate
  double min_threshold = 0.05;     ///< m, the estimate never drops below (sensor noise floor)

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("initial_threshold", initial_threshold, "m, sigma before any motion was seen")
        .positive();
    v.field("min_motion", min_motion, "m, frames moving less do not update the estimate")
        .nonNegative();
    v.field("min_threshold", min_threshold, "m, lower bound of sigma")
        .positive()
        .atMost(initial_threshold, "initial_threshold");
  }
};

/// KISS-ICP's adaptive threshold: sigma is the RMS of the motion model's
/// deviations (prediction vs. registration) of past frames, each measured as
/// the largest point displacement it causes within `max_range`. ICP then
/// accepts pairs within 3 sigma and weights them with a kernel of sigma / 3.
class AdaptiveThreshold {
 public:
  /// A threshold for a sensor seeing up to `max_range` (m).
  AdaptiveThreshold(const AdaptiveThresholdConfig& config, double max_range);

  /// Records how far the registered motion deviated from the prediction,
  /// `T_deviation` = prediction^-1 * estimate, for a frame that moved `motion` m.
  void update(const Eigen::Isometry3d& T_deviation, double motion);

  /// m, the current sigma.
  [[nodiscard]] double sigma() const;

  /// True once a frame that moved has updated sigma (before, it is the initial guess).
  [[nodiscard]] bool learned() const { return count_ > 0; }

 private:
  AdaptiveThresholdConfig config_;
  double max_range_;
  double sum_squared_ = 0.0;
  std::size_t count_ = 0;
};

}  // namespace dcl::odometry
