#pragma once

/// The keyframe selector of the paper (§III-A): a frame becomes a keyframe when
/// the sensor moved more than 1.0 m or turned more than 0.2 rad since the last
/// keyframe. Each keyframe carries its scan voxel-filtered for storage, its
/// odometry pose, and the odometry factor to the previous keyframe: the relative
/// pose and its covariance, composed from the per-frame covariances.

#include <cstddef>
#include <numbers>
#include <optional>

#include <dcl/core/config.hpp>
#include <dcl/core/keyframe.hpp>
#include <dcl/core/point_cloud.hpp>
#include <dcl/odometry/odometry.hpp>

namespace dcl::odometry {

/// When a frame becomes a keyframe and how its scan is stored.
struct KeyframeConfig {
  static constexpr double kMaxTranslation = 1000.0;         ///< m, translation at most
  static constexpr double kMaxRotation = std::numbers::pi;  ///< rad, rotation at most

  double translation = 1.0;  ///< m, moved farther than this since the last keyframe (paper: 1.0)
  double rotation = 0.2;     ///< rad, turned more than this since the last keyframe (paper: 0.2)
  /// m, voxel edge of the stored scan. 0.5 m keeps an HDL-64 keyframe at about
  /// 15-25 k points (a tenth of the scan) and is KISS-ICP's registration sampling
  /// for such a sensor, so ICP against a submap of keyframes (0.3 m inliers) still
  /// sees every surface; VLP-16 keyframes are sparse already and lose little.
  double voxel_size = 0.5;
  /// Floor of every variance of the odometry factor (m^2 and rad^2), so that an
  /// over-confident front-end cannot make a factor infinitely stiff.
  double min_variance = 1e-8;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    // No turn is larger than pi, and a keyframe every kilometre leaves no map.
    v.field("translation", translation, "m, keyframe after moving this far (paper: 1.0)")
        .within(0.0, kMaxTranslation);
    v.field("rotation", rotation, "rad, keyframe after turning this much (paper: 0.2)")
        .within(0.0, kMaxRotation);
    v.field("voxel_size", voxel_size, "m, voxel edge of the stored keyframe scan")
        .within(core::kMinVoxelEdge, core::kMaxVoxelEdge);
    v.field("min_variance", min_variance, "floor of the odometry factor's variances").positive();
  }
};

/// Picks keyframes from a robot's stream of odometry results.
///
/// Covariance of the odometry factor: a frame's covariance Sigma_i is that of
/// its motion T_{i-1,i} perturbed on the right, T_{i-1,i} exp(xi_i). Composing
/// T_{k,i} = T_{k,i-1} T_{i-1,i} with independent errors gives, to first order,
/// Sigma_{k,i} = Ad(T_{i-1,i}^-1) Sigma_{k,i-1} Ad(T_{i-1,i}^-1)^T + Sigma_i,
/// starting from zero at keyframe k: the earlier errors seen from the newer
/// frame, plus the newest. A frame that was not accepted (its pose held, not
/// measured) never becomes a keyframe, but its covariance still counts.
class KeyframeSelector {
 public:
  /// A selector for robot `robot`.
  explicit KeyframeSelector(core::RobotId robot, const KeyframeConfig& config = {});

  /// Takes the next frame and `scan`, its cloud in the sensor frame at the frame's
  /// stamp (OdometryResult::registered for the built-in odometry, the raw scan for
  /// external odometry). Returns a keyframe when the frame becomes one; the first
  /// accepted frame always does (identity relative pose, zero covariance).
  std::optional<core::Keyframe> add(const OdometryResult& frame, const core::PointCloud& scan);

  /// add() with the frame's own registered cloud.
  std::optional<core::Keyframe> add(const OdometryResult& frame) {
    return add(frame, frame.registered);
  }

  /// `scan` as a keyframe stores it (thinned to the keyframe voxel).
  [[nodiscard]] core::PointCloud keyframeCloud(const core::PointCloud& scan) const;

  /// The number of keyframes made so far.
  [[nodiscard]] std::size_t count() const { return count_; }

  /// The odometry pose of the last keyframe (none before the first).
  [[nodiscard]] std::optional<Eigen::Isometry3d> lastKeyframePose() const { return T_odom_last_; }

 private:
  [[nodiscard]] bool isKeyframe(const Eigen::Isometry3d& T_last_frame) const;
  core::Keyframe makeKeyframe(const OdometryResult& frame, const core::PointCloud& scan) const;
  void accumulate(const OdometryResult& frame);

  core::RobotId robot_;
  KeyframeConfig config_;
  std::size_t count_ = 0;
  std::optional<Eigen::Isometry3d> T_odom_last_;  ///< the last keyframe's odometry pose
  Eigen::Isometry3d T_odom_previous_frame_ = Eigen::Isometry3d::Identity();
  core::Matrix6d covariance_ = core::Matrix6d::Zero();  ///< since the last keyframe
};

/// `cloud` thinned to one point per voxel of edge `voxel_size` (xyz only; no
/// channel survives the thinning). Non-finite points are dropped.
core::PointCloud voxelFilter(const core::PointCloud& cloud, double voxel_size);

}  // namespace dcl::odometry
