#pragma once

/// The built-in LiDAR-only odometry (paper §III-A), after KISS-ICP (Vizzo et
/// al. 2023): deskew under constant velocity, voxel-downsample, predict with
/// constant velocity, register point-to-plane against a local voxel hash map
/// with an adaptive threshold, then grow and cull the map.

#include <Eigen/Geometry>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/odometry/odometry.hpp>
#include <dcl/odometry/registration.hpp>
#include <dcl/odometry/voxel_map.hpp>

namespace dcl::odometry {

/// Everything the LiDAR odometry can be told.
struct OdometryConfig {
  static constexpr int kMaxPointsPerVoxel = 1000;  ///< a voxel's budget at most
  /// min_points at most: more than any LiDAR's scan, so that no setting skips every scan.
  static constexpr std::size_t kMaxMinPoints = 10'000'000;

  double max_range = 100.0;       ///< m, farther points are dropped; also the map's radius
  double min_range = 2.0;         ///< m, nearer points (the ego vehicle) are dropped
  double voxel_size = 0.0;        ///< m, map voxel edge; 0 = max_range / 100 (KISS-ICP's rule)
  int max_points_per_voxel = 20;  ///< map points a voxel keeps (KISS-ICP: 20)
  bool deskew = true;             ///< undo the motion during the sweep when points carry times
  /// m: map points within this distance that a new sweep sees through (its
  /// beams return from farther away all around them) are removed: what moved
  /// away (a car, a pedestrian) leaves no ghost in the map. 0 (the default)
  /// turns it off: it costs about a third of a VLP-16 frame's time today.
  double free_space_radius = 0.0;
  /// m: when the registered motion moves a point 10 m out at the sweep's ends
  /// by more than this against the velocity the sweep was deskewed with (a
  /// sharp turn or braking), the sweep's own twist is estimated with its pose
  /// (registerSweep); 0 turns this off.
  double motion_change_error = 0.05;
  /// Likewise when the deskewed sweep's RMS residual exceeds this many times
  /// the average of the recent frames' (a sweep bent by a change of motion
  /// fits badly even where its pose stays near the prediction).
  double motion_change_rmse_ratio = 2.0;
  /// m/s and rad/s: how far that sweep's own twist may stray from the last
  /// sweep's (one standard deviation); the prior holds the twist only where
  /// the scene does not show it. Wide enough for a car braking into a turn
  /// (KITTI 00's ground truth changes its yaw rate by 24 deg/s from one frame
  /// to the next there) and for a handheld or legged sensor's jolts.
  double twist_sigma_linear = 1.0;
  double twist_sigma_angular = 0.5;     ///< rad/s, the same for the angular velocity
  std::size_t min_points = 100;         ///< a scan with fewer usable points is skipped
  double min_translation_sigma = 0.01;  ///< m, floor of the reported per-frame covariance
  /// rad, floor of the reported per-frame covariance about the sensor's x and y axes.
  double min_rotation_sigma = 1e-3;
  /// rad, the same about its z (spin) axis: walls all round pin the heading,
  /// and the odometry's keyframe yaw errs about a fifth as much as its roll
  /// and pitch (`dcl-slam bench noise`, BENCHMARKS.md), on HDL-64 and VLP-16 alike.
  double min_yaw_sigma = 1.5e-4;
  double max_sigma = 10.0;  ///< m or rad, ceiling of the covariance in unobservable directions
  /// Level the poses with the IMU's readings of up where scans come with them
  /// (observeUp): registration alone drifts in roll and pitch, and the height
  /// with them, wherever the LiDAR's elevations are off (KITTI's HDL-64E by
  /// 0.2 deg); gravity does not drift. Off: LiDAR only.
  bool use_imu = true;
  /// s, how quickly the levelled roll and pitch follow the readings: each
  /// frame moves them the share 1 - exp(-dt / this) of the way (86 % at 10
  /// Hz). Registration pulls them back toward its local map every frame, so
  /// a slower pull leaves them that far behind: at 0.3 s, 0.1-0.2 deg on the
  /// simulated KITTI routes (0.7 deg braking into a turn), at 0.05 s 0.01-0.09.
  double imu_time_constant = 0.05;
  /// rad, the floor of a levelled frame's covariance about the sensor's x
  /// and y axes, instead of min_rotation_sigma: two readings' noise (an
  /// OXTS-class IMU's 0.02 deg each, sqrt(2) of it between two frames).
  /// Registration's floor would let the pose graph tilt the levelled chain
  /// by degrees over a few hundred frames, and bend its height to fit others'.
  double imu_tilt_sigma = 5e-4;
  AdaptiveThresholdConfig threshold{};  ///< KISS-ICP's adaptive correspondence threshold
  IcpConfig icp{};  ///< registration (the odometry overrides its distance and kernel per frame)

  /// The map voxel edge after applying the `voxel_size = 0` rule.
  [[nodiscard]] double mapVoxelSize() const {
    return voxel_size > 0.0 ? voxel_size : max_range / 100.0;
  }

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    // max_range / 100 is the map voxel when voxel_size is 0: it stays a voxel edge.
    v.field("max_range", max_range, "m, farther points are dropped; also the map's radius")
        .within(100.0 * core::kMinVoxelEdge, 100.0 * core::kMaxVoxelEdge);
    v.field("min_range", min_range, "m, nearer points (the ego vehicle) are dropped")
        .nonNegative()
        .lessThan(max_range, "max_range");
    v.field("voxel_size", voxel_size, "m, map voxel edge; 0 = max_range / 100")
        .zeroOrWithin(core::kMinVoxelEdge, core::kMaxVoxelEdge, "max_range / 100");
    v.field("max_points_per_voxel", max_points_per_voxel, "map points a voxel keeps")
        .within(1, kMaxPointsPerVoxel);
    v.field("deskew", deskew, "undo the motion during the sweep when points carry times");
    v.field("free_space_radius", free_space_radius,
            "m, map points this near that a new sweep sees through are removed (what moved "
            "away leaves no ghost; 0: never; try 40 among traffic)")
        .nonNegative();
    v.field("motion_change_error", motion_change_error,
            "m, estimate a sweep's own twist when the registered motion moves a point 10 m out at "
            "the sweep's ends by more than this (0: never)")
        .nonNegative();
    v.field("motion_change_rmse_ratio", motion_change_rmse_ratio,
            "likewise when the sweep's RMS residual exceeds this many times the recent frames' "
            "(0: never)")
        .nonNegative();
    v.field("twist_sigma_linear", twist_sigma_linear,
            "m/s, how far such a sweep's own velocity may stray from the last sweep's (1 sigma)")
        .positive();
    v.field("twist_sigma_angular", twist_sigma_angular,
            "rad/s, how far such a sweep's own angular velocity may stray from the last sweep's")
        .positive();
    v.field("min_points", min_points, "a scan with fewer usable points is skipped")
        .atMost(kMaxMinPoints);
    v.field("min_translation_sigma", min_translation_sigma, "m, covariance floor").nonNegative();
    v.field("min_rotation_sigma", min_rotation_sigma, "rad, covariance floor about x and y")
        .nonNegative();
    v.field("min_yaw_sigma", min_yaw_sigma, "rad, covariance floor about the spin axis z")
        .nonNegative();
    v.field("max_sigma", max_sigma, "m or rad, covariance ceiling in unobservable directions")
        .positive();
    v.field("use_imu", use_imu,
            "level roll and pitch with the IMU's readings of up where scans come with them");
    v.field("imu_time_constant", imu_time_constant,
            "s, how quickly the levelled roll and pitch follow the IMU's readings")
        .positive();
    v.field("imu_tilt_sigma", imu_tilt_sigma,
            "rad, covariance floor about x and y of a frame levelled with the IMU")
        .nonNegative();
    v.section("threshold", threshold, "adaptive correspondence threshold");
    v.section("icp", icp, "registration");
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const OdometryConfig& config);

/// KISS-ICP-style LiDAR odometry. Not thread-safe; registration itself runs on
/// TBB's threads (limit them with tbb::global_control).
class LidarOdometry final : public Odometry {
 public:
  /// An odometry with `config`; the first scan defines the odometry frame.
  explicit LidarOdometry(const OdometryConfig& config = {});

  /// Registers the scan taken at `stamp` (see Odometry::process).
  OdometryResult process(double stamp, const core::PointCloud& scan) override;

  /// Keeps the IMU's reading of up for the next scan (use_imu).
  void observeUp(const Eigen::Vector3d& up_sensor) override;

  /// The latest pose, T_odom_sensor.
  [[nodiscard]] Eigen::Isometry3d pose() const override { return T_odom_sensor_; }

  /// "lidar".
  [[nodiscard]] std::string name() const override { return "lidar"; }

  /// The local map, in the odometry frame.
  [[nodiscard]] const VoxelHashMap& localMap() const { return map_; }

  /// The sensor's twist [v; omega] in its own frame (m/s, rad/s): from the last
  /// two frames, or the last sweep's own when its motion changed sharply.
  [[nodiscard]] const core::Vector6d& velocity() const { return velocity_; }

  /// The configuration in use.
  [[nodiscard]] const OdometryConfig& config() const { return config_; }

 private:
  /// Why a frame cannot be used before registration; none when it can.
  [[nodiscard]] std::optional<std::string> checkStamp(double stamp) const;
  /// The result of a frame that does not update the state.
  [[nodiscard]] OdometryResult skipped(double stamp, std::string problem) const;
  /// The ICP settings for a frame registered with threshold `sigma` (m): 3 sigma
  /// gate, sigma / 3 kernel (KISS-ICP), sigma raised to the map's sampling spacing.
  [[nodiscard]] IcpConfig frameIcpConfig(double sigma) const;
  /// The covariance of a frame's motion from its registration, with the
  /// IMU's floor about x and y when the frame was `levelled`.
  [[nodiscard]] core::Matrix6d covarianceOf(const RegistrationResult& registration,
                                            bool levelled) const;
  /// Re-deskews the first sweep once a velocity is known and anchors the odometry frame at its
  /// stamp.
  void redoFirstSweep();
  /// The constant-velocity prediction of the sensor pose at `time` (s, absolute).
  [[nodiscard]] Eigen::Isometry3d predictReference(double time) const;
  /// The cleaned `cloud` deskewed to `t_mid` (s after the stamp) with the
  /// current velocity (none when deskewing is off).
  [[nodiscard]] std::vector<Eigen::Vector3d> deskewedFrame(const core::PointCloud& cloud,
                                                           double t_mid) const;
  /// The same, one point per half map voxel.
  [[nodiscard]] std::vector<Eigen::Vector3d> thinnedFrame(const core::PointCloud& cloud,
                                                          double t_mid) const;
  /// A frame's points as registration takes them: one per 1.5 map voxels,
  /// deskewed with `velocity`, and the same points raw with their offsets
  /// from mid-sweep (none when the points carry no times).
  struct FrameSource {
    std::vector<Eigen::Vector3d> deskewed;
    SweepPoints sweep;
  };
  /// A frame's registration, with the sweep's own twist when it was estimated.
  struct FrameRegistration {
    RegistrationResult registration;
    std::optional<core::Vector6d> twist;
    std::size_t source_points = 0;  ///< the deskewed, thinned source it registered
  };
  [[nodiscard]] FrameSource sourceOf(const core::PointCloud& cloud, double t_mid,
                                     const core::Vector6d& velocity) const;
  /// The rigid registration of the deskewed source from `T_predicted`.
  [[nodiscard]] RegistrationResult registerRigid(const FrameSource& source,
                                                 const Eigen::Isometry3d& T_predicted) const;
  /// Rigid registration of `points` from `T_start`, coarse to fine: the
  /// first, wide gate, then halved at each pass, each from where the last
  /// ended, down to the learned gate.
  [[nodiscard]] RegistrationResult registerCoarseToFine(std::span<const Eigen::Vector3d> points,
                                                        const Eigen::Isometry3d& T_start) const;
  /// True when the sweep's motion changed sharply (motion_change_error,
  /// motion_change_rmse_ratio): the rigid fit at mid-sweep `reference_time`
  /// (s) of a sweep of `duration` s implies another twist, or fits badly.
  [[nodiscard]] bool motionChanged(const RegistrationResult& rigid, double reference_time,
                                   double duration) const;
  /// Registers the cleaned sweep `cloud` (stamped `stamp`, middle `t_mid` s
  /// later) from `T_predicted`: rigidly, deskewed with the current velocity,
  /// then with its own twist when its motion changed sharply.
  [[nodiscard]] FrameRegistration registerFrame(const core::PointCloud& cloud, double stamp,
                                                double t_mid,
                                                const Eigen::Isometry3d& T_predicted) const;
  /// Commits an accepted mid-sweep pose (the sweep's middle is `t_mid` s after
  /// `stamp`) and the sweep's twist (none: from the last accepted frame):
  /// velocity, adaptive threshold, and the pose at the stamp.
  void commit(double stamp, double t_mid, const RegistrationResult& registration,
              const Eigen::Isometry3d& T_predicted, const std::optional<core::Vector6d>& twist,
              const std::optional<Eigen::Vector3d>& up);
  /// Turns the committed mid-sweep pose toward the IMU's reading `up_stamp`
  /// (sensor frame at the stamp) about a horizontal axis through the sensor,
  /// by the share of imu_time_constant; the first reading after the odometry
  /// frame is settled defines up in that frame.
  void level(const Eigen::Vector3d& up_stamp, double t_mid, double reference_time);
  /// Removes the map points the committed sweep `deskewed` (mid-sweep sensor
  /// frame) sees through, then adds its thinned `frame` to the map and culls
  /// the map by distance.
  void growMap(std::span<const Eigen::Vector3d> deskewed, std::span<const Eigen::Vector3d> frame);

  OdometryConfig config_;
  VoxelHashMap map_;
  AdaptiveThreshold threshold_;
  /// The sensor at the last accepted stamp.
  Eigen::Isometry3d T_odom_sensor_ = Eigen::Isometry3d::Identity();
  /// The sensor at the middle of the last accepted sweep: registration happens
  /// there, because deskewing to mid-sweep makes a velocity error distort the
  /// scan symmetrically (no net shift), which keeps the velocity -> deskew ->
  /// registration -> velocity loop stable. Deskewing to the sweep's start feeds
  /// half a sweep of velocity error back into the pose and oscillates.
  Eigen::Isometry3d T_odom_reference_ = Eigen::Isometry3d::Identity();
  core::Vector6d velocity_ = core::Vector6d::Zero();
  double rmse_average_ = 0.0;  ///< m, moving average of the accepted frames' residuals
  /// Moving average of the accepted frames' inlier shares (inliers over source points).
  double inlier_share_average_ = 0.0;
  /// A frame whose inlier share falls below this times the average is fitted
  /// again with the first, wide gate (registerRigid).
  static constexpr double kLostShareRatio = 0.85;
  std::optional<double> last_stamp_;           ///< s, of the last accepted frame
  std::optional<double> last_reference_time_;  ///< s, mid-sweep of the last accepted frame
  /// The first sweep (with per-point times), kept until the second frame gives a velocity.
  struct FirstSweep {
    core::PointCloud cloud;  ///< cleaned, in the sensor frame at firing times
    double t_mid = 0.0;      ///< s after the stamp, where it was registered
    double stamp = 0.0;      ///< s, the frame's
  };
  std::optional<FirstSweep> first_sweep_;
  /// The first frame deskewed again, for the result of the frame that did it.
  std::optional<OdometryResult::Redone> first_frame_redone_;
  int frames_since_carving_ = 0;               ///< accepted frames since the map was last carved
  std::optional<Eigen::Vector3d> pending_up_;  ///< the IMU's reading of up for the next scan
  std::optional<Eigen::Vector3d> up_odom_;     ///< up in the odometry frame, from the IMU
  double last_level_time_ = 0.0;               ///< s, mid-sweep of the last levelled frame
};

}  // namespace dcl::odometry
