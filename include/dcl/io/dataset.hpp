#pragma once

/// The dataset folder (DESIGN.md §3): a `dataset.yaml` that names the sensor,
/// the frame conventions, the simulated world (for simulated datasets) and,
/// per robot, where its scans come from and where its ground truth is.
///
/// Conventions of every dataset (also written into each dataset.yaml):
/// - ground truth is T_world_sensor in a TUM file (`t x y z qx qy qz qw`), one
///   world frame shared by all robots of the dataset;
/// - stamps (of scans and ground truth) are seconds since the robot's own start;
///   `start_time` places that start on the swarm's common clock;
/// - scan points are in the sensor frame at the moment each was fired;
/// - metres, seconds, radians.
/// A robot's odometry frame is its sensor frame at its first scan.
///
/// Paths inside dataset.yaml are relative to the dataset folder.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/core/trajectory.hpp>

namespace dcl::io {

/// The dataset.yaml format this code reads and writes.
inline constexpr int kDatasetFormatVersion = 1;

/// The file name of a dataset's description inside its folder.
inline constexpr std::string_view kDatasetFileName = "dataset.yaml";

/// Where a robot's scans come from.
enum class ScanSourceType {
  sim,    ///< regenerated on demand by the simulator (nothing on disk)
  kitti,  ///< a folder of KITTI `NNNNNN.bin` scans and a times file
  bag,    ///< a ROS1 bag topic of sensor_msgs/PointCloud2
  mcap,   ///< a ROS 2 bag (MCAP) topic of sensor_msgs/PointCloud2 (read by dcl::ros)
};

/// "sim", "kitti", "bag" or "mcap".
std::string_view toString(ScanSourceType type);

/// The type called `name`; none for an unknown name.
std::optional<ScanSourceType> parseScanSourceType(std::string_view name);

/// A robot's scans: the type and the fields that type uses.
struct ScanSourceSpec {
  ScanSourceType type = ScanSourceType::sim;  ///< default: simulated
  std::string folder{};  ///< kitti: folder of NNNNNN.bin (relative); default none
  std::string times{};   ///< kitti: stamps one a line, s since start (relative); default none
  std::string file{};    ///< bag, mcap: the bag file (relative); default none
  std::string topic{};   ///< bag, mcap: the sensor_msgs/PointCloud2 topic; default none
  /// bag, mcap: the robot's sensor_msgs/Imu topic, whose orientation levels
  /// each scan (ScanSource::up); default none.
  std::string imu_topic{};
  /// deg: the IMU frame's roll, pitch, yaw in the LiDAR frame; default 0, 0, 0.
  std::array<double, 3> imu_rpy{0.0, 0.0, 0.0};
};

/// The poses of a robot's own front-end (LIO-SAM, FAST-LIO2, wheel and IMU
/// odometry, ...), in a pose file or a ROS 1 or ROS 2 (MCAP) bag topic, taken instead of the
/// built-in LiDAR odometry, the scans then serving keyframe clouds, descriptors and verification
/// only. The poses are T_world_body on the scans' clock, read by readExternalOdometry
/// (external_odometry.hpp) and replayed by odometry::ExternalOdometry (the configuration's
/// `external` section gives T_body_sensor and the noise model).
struct FrontEndSpec {
  std::string file{};           ///< TUM or KITTI poses, or a bag (relative); "" when none
  std::string format = "auto";  ///< tum | kitti | bag | mcap | auto (by extension, else tum)
  std::string topic{};          ///< bag, mcap: nav_msgs/Odometry or PoseStamped topic
  std::string times{};          ///< kitti: stamps one a line (relative)

  [[nodiscard]] bool empty() const { return file.empty(); }
};

/// One robot of a dataset.
struct RobotSpec {
  std::string name{};          ///< unique within the dataset, e.g. "a"
  ScanSourceSpec scans{};      ///< where its scans come from
  std::string ground_truth{};  ///< TUM file of T_world_sensor (relative); "" when none
  double start_time = 0.0;     ///< s, the robot's start on the swarm clock; default 0
  FrontEndSpec odometry{};     ///< an external front-end's poses; none: the built-in odometry
};

/// The kinds of procedural world the simulator builds.
enum class WorldKind {
  city,      ///< urban blocks along the routes
  campus,    ///< open campus
  aliasing,  ///< repeated identical blocks (perceptual aliasing)
};

/// "city", "campus" or "aliasing".
std::string_view toString(WorldKind kind);

/// The kind called `name`; none for an unknown name.
std::optional<WorldKind> parseWorldKind(std::string_view name);

/// What a simulated dataset regenerates its world and scans from.
struct SimSpec {
  WorldKind world = WorldKind::city;  ///< world generator; default city
  std::uint64_t seed = 1;             ///< world and scan noise derive from it; default 1
  bool motion_distortion = true;      ///< scans distorted by the sweep's motion; default on
  bool noise = true;                  ///< range noise and dropout; default on
  /// With noise: each robot's LiDAR with its own lasers' elevation and range
  /// errors (sim::BeamCalibration); default on.
  bool calibration_error = true;
  /// With calibration_error: every robot carries the same LiDAR unit (the
  /// first robot's), as when one car's drive is split into robots (the KITTI
  /// presets); default off, each robot its own unit.
  bool shared_unit = false;
  /// Moving actors (cars, cyclists, pedestrians, cars parked for a while;
  /// sim/traffic.hpp): this times the world kind's traffic, 0 for none (the
  /// default), at most kMaxTraffic.
  double traffic = 0.0;
  /// Each robot carries an IMU whose gravity reading (the direction up in the
  /// sensor frame, with the unit's own tilt error and noise; sim::ImuModel)
  /// comes with every scan; default off (every preset's robots have one).
  bool imu = false;
};

/// The densest traffic a dataset may ask for (ten times a world kind's own).
inline constexpr double kMaxTraffic = 10.0;

/// The content of a dataset.yaml.
struct DatasetSpec {
  int format_version = kDatasetFormatVersion;  ///< version of the file format; default current
  std::string name{};                          ///< what the dataset is called
  std::string description{};                   ///< one line about it; optional
  std::string sensor = "hdl64";                ///< sensor model name ("hdl64", "vlp16", ...)
  double mount_height = 1.73;                  ///< m, sensor above the ground; default KITTI's
  std::optional<SimSpec> sim{};                ///< the simulated world; none for recorded datasets
  std::vector<RobotSpec> robots{};             ///< at least one
  /// The dataset folder this spec was read from (not stored in the file); relative
  /// paths resolve against it. Empty: the current folder.
  std::string folder{};

  /// `relative` resolved against `folder` (an absolute path is kept as it is).
  [[nodiscard]] std::string resolve(const std::string& relative) const;

  /// The index of the robot called `name`; none if there is no such robot.
  [[nodiscard]] std::optional<std::size_t> robotIndex(std::string_view name) const;
};

/// How much of the file system a dataset may name.
struct DatasetReadOptions {
  /// Ground-truth and scan paths may be absolute or climb out of the dataset
  /// folder. Off by default: a dataset from elsewhere reads nothing outside
  /// its own folder (`--allow-outside-paths` on the command line).
  bool allow_outside_paths = false;
};

/// Reads a dataset: `path` is the dataset folder or its dataset.yaml. Throws
/// core::FileError naming the file, the line and the key for malformed YAML,
/// missing or unknown keys, values of the wrong type, an unsupported format
/// version, conventions other than the ones above, a duplicate robot name, a
/// robot name that is not a plain name, a path outside the dataset folder
/// (unless `options` allow it), or a robot whose scan source lacks the
/// fields its type needs.
DatasetSpec readDataset(const std::string& path, const DatasetReadOptions& options = {});

/// Reads a dataset.yaml from its text, as readDataset reads the file `file`
/// (which names it in errors and whose folder relative paths resolve against).
DatasetSpec parseDataset(std::string_view text, const std::string& file,
                         const DatasetReadOptions& options = {});

/// The dataset.yaml text of `spec`, with comments explaining the conventions.
std::string datasetYaml(const DatasetSpec& spec);

/// Writes `spec` as `folder`/dataset.yaml, atomically (creates the folder).
void writeDataset(const std::string& folder, const DatasetSpec& spec);

/// The ground truth of robot `robot`; throws core::Error when it has none.
core::Trajectory readGroundTruth(const DatasetSpec& spec, std::size_t robot);

}  // namespace dcl::io
