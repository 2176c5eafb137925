#pragma once

/// Odometry from another front-end (paper §III-A: the framework is front-end
/// agnostic): poses recorded by LIO-SAM, FAST-LIO2, a ground-truth system or
/// any other source, replayed at the scan times, or streamed in as a live
/// front-end publishes them. The recorded poses are given as a trajectory
/// (io::readExternalOdometry reads them from a TUM or KITTI file or a topic of
/// a ROS1 bag or a ROS 2 bag in MCAP); this module reads no file.
///
/// The source gives T_world_body at its own stamps. For a scan at `stamp` the
/// pose is interpolated there (core::Trajectory::at), moved to the LiDAR by a
/// fixed extrinsic, T_world_sensor = T_world_body T_body_sensor, and
/// re-expressed in the odometry frame, the sensor frame of the first frame
/// processed: T_odom_sensor = T_world_sensor(first)^-1 T_world_sensor(stamp).
/// The extrinsic is needed when the source tracks another body than the LiDAR
/// (an IMU, or KITTI's left camera: T_body_sensor = Tr, the velodyne-to-camera
/// calibration); it is the identity when the poses are the LiDAR's own.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <optional>
#include <string>

#include <dcl/core/trajectory.hpp>
#include <dcl/odometry/odometry.hpp>

namespace dcl::odometry {

/// Where the external poses come from (the application reads them:
/// io::readExternalOdometry) and how they are used.
struct ExternalOdometryConfig {
  /// How far the norm of T_body_sensor's quaternion may be from 1 (values written to a few digits).
  static constexpr double kQuaternionTolerance = 1e-2;

  std::string file = "";  ///< pose file or bag; default none (a trajectory is given in code)
  /// "tum", "kitti", "bag" (ROS1), "mcap" (ROS 2) or "auto" (by extension: .bag, .mcap, else tum)
  std::string format = "auto";
  std::string times = "";  ///< kitti: the times file (one stamp a line); default none
  std::string topic = "";  ///< bag: the nav_msgs/Odometry or PoseStamped topic; default none
  /// T_body_sensor as x y z qx qy qz qw: the LiDAR's pose in the source's body frame;
  /// default identity (the poses are the LiDAR's).
  Eigen::Matrix<double, 7, 1> T_body_sensor =
      (Eigen::Matrix<double, 7, 1>() << 0, 0, 0, 0, 0, 0, 1).finished();
  /// m per sqrt(m): translation standard deviation of the reported motion
  /// covariance, a random walk in distance travelled (the source reports none).
  double translation_sigma = 0.01;
  /// rad per sqrt(m): rotation standard deviation of the reported motion covariance.
  double rotation_sigma = 1e-3;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("file", file, "pose file, ROS1 bag or ROS 2 bag (MCAP) of the external front-end");
    v.field("format", format, "tum, kitti, bag, mcap or auto (by extension)")
        .oneOf({"tum", "kitti", "bag", "mcap", "auto"});
    v.field("times", times, "kitti: times file");
    v.field("topic", topic, "bag: nav_msgs/Odometry or geometry_msgs/PoseStamped topic")
        .rule(file.empty() || !readsBag() || !topic.empty(), "must be given to read a bag", "file");
    v.field("T_body_sensor", T_body_sensor,
            "LiDAR pose in the source's body frame, x y z qx qy qz qw")
        .rule(T_body_sensor.allFinite() &&
                  std::abs(T_body_sensor.tail<4>().norm() - 1.0) <= kQuaternionTolerance,
              "must be finite, with a unit quaternion (norm 1 within 0.01)");
    v.field("translation_sigma", translation_sigma, "m per sqrt(m) of travel, motion covariance")
        .positive();
    v.field("rotation_sigma", rotation_sigma, "rad per sqrt(m) of travel, motion covariance")
        .positive();
  }

  /// Whether `file` is read as a bag, ROS1 or ROS 2: format bag or mcap, or
  /// auto and a .bag or .mcap file.
  [[nodiscard]] bool readsBag() const {
    return format == "bag" || format == "mcap" ||
           (format == "auto" && (file.ends_with(".bag") || file.ends_with(".mcap")));
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const ExternalOdometryConfig& config);

/// Replays recorded poses as an Odometry.
class ExternalOdometry final : public Odometry {
 public:
  /// Replays `T_world_body` (sorted by stamp; rotations are projected onto SO(3),
  /// KITTI files print 7 digits). Throws core::Error when it is empty or unsorted.
  explicit ExternalOdometry(core::Trajectory T_world_body,
                            const ExternalOdometryConfig& config = {});

  /// An odometry fed while it runs (a live front-end's messages, append()),
  /// with no pose yet.
  static ExternalOdometry streaming(const ExternalOdometryConfig& config);

  /// The front-end's next pose: false (and nothing kept) when `stamp` is not
  /// finite or not after the last one, or the pose not finite. Poses before
  /// the last frame processed are let go as new ones come.
  bool append(double stamp, const Eigen::Isometry3d& T_world_body);

  /// Whether a pose at or after `stamp` has arrived, so that a frame at
  /// `stamp` can be placed (or found before the first pose).
  /// Poses held (a streamed front-end's stay a few thousand).
  [[nodiscard]] std::size_t posesHeld() const { return T_world_body_.size(); }

  [[nodiscard]] bool reaches(double stamp) const {
    return !T_world_body_.empty() && T_world_body_.stamps().back() >= stamp;
  }

  /// The pose at `stamp` (the scan is not used). A stamp outside the
  /// trajectory, not finite, or before the previous frame's gives
  /// health.accepted = false and the pose held. The covariance is the model of
  /// the config (random walk in the distance moved since the previous frame).
  OdometryResult process(double stamp, const core::PointCloud& scan) override;

  /// The latest pose, T_odom_sensor.
  [[nodiscard]] Eigen::Isometry3d pose() const override { return T_odom_sensor_; }

  /// "external".
  [[nodiscard]] std::string name() const override { return "external"; }

  /// Throws core::Error naming both time ranges when the scans' stamps, from
  /// `first_stamp` to `last_stamp`, never meet the trajectory's: no frame would
  /// get a pose (a file on another clock than the scans, say Unix time against
  /// seconds since the start).
  void requireOverlap(double first_stamp, double last_stamp) const;

  /// The first and last stamp of the replayed trajectory.
  [[nodiscard]] double firstStamp() const { return T_world_body_.stamps().front(); }
  [[nodiscard]] double lastStamp() const {
    return T_world_body_.stamps().back();
  }  ///< see firstStamp

 private:
  [[nodiscard]] OdometryResult held(double stamp, std::string problem) const;
  [[nodiscard]] core::Matrix6d motionCovariance(const Eigen::Isometry3d& T_step) const;

  struct Streaming {};
  ExternalOdometry(Streaming, const ExternalOdometryConfig& config);

  core::Trajectory T_world_body_;
  Eigen::Isometry3d T_body_sensor_;
  ExternalOdometryConfig config_;
  std::optional<Eigen::Isometry3d> T_world_odom_;  ///< set by the first usable frame
  std::optional<double> last_stamp_;
  Eigen::Isometry3d T_odom_sensor_ = Eigen::Isometry3d::Identity();
};

}  // namespace dcl::odometry
