#pragma once

/// Exporting a dataset's scans to real files for other tools: KITTI folders,
/// ROS1 bags or ROS 2 bags (MCAP), with a dataset.yaml describing the exported copy.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include <dcl/io/dataset.hpp>

namespace dcl::sim {

/// The file formats a dataset exports to.
enum class ExportFormat {
  kitti,  ///< per robot: velodyne/NNNNNN.bin, times.txt, poses.txt (KITTI poses)
  bag,    ///< per robot: scans.bag with PointCloud2 scans and Odometry ground truth
  mcap,   ///< per robot: scans.mcap (ROS 2, zstd) with PointCloud2 scans and Odometry ground truth
};

/// "kitti", "bag" or "mcap".
std::string_view toString(ExportFormat format);

/// The format called `name`; none for another name.
std::optional<ExportFormat> parseExportFormat(std::string_view name);

/// How a dataset is exported.
struct ExportOptions {
  ExportFormat format = ExportFormat::kitti;         ///< default KITTI folders
  std::string cloud_topic = "/points";               ///< bag topic of the scans
  std::string ground_truth_topic = "/ground_truth";  ///< bag topic of the ground truth
  std::string imu_topic = "/imu";     ///< bag topic of the IMU's readings (sensor_msgs/Imu)
  std::string world_frame = "world";  ///< frame_id of the ground truth
  /// s, added to every bag (and MCAP) stamp: ROS time must be positive, robot stamps start at 0.
  /// Readers of the exported dataset subtract the first scan's stamp again.
  double bag_epoch = 1.0e9;
};

/// What an export wrote.
struct ExportResult {
  io::DatasetSpec dataset{};  ///< the exported copy, as read back from its dataset.yaml
  std::size_t scans = 0;      ///< scans written, all robots
  std::size_t points = 0;     ///< points written, all robots
  std::uintmax_t bytes = 0;   ///< size of the files written
};

/// Called after each scan written with (scans done, scans in total).
using ExportProgress = std::function<void(std::size_t, std::size_t)>;

/// Writes every scan of every robot of `spec` (simulated or not) into `folder`
/// in `options.format`, with per robot a copy of its ground truth
/// (`NAME/ground_truth.tum`) and a dataset.yaml whose scan sources point at the
/// exported files. Scans are generated robot by robot, in order; files are
/// written atomically. Throws core::Error / core::FileError on failure.
ExportResult exportDataset(const io::DatasetSpec& spec, const std::string& folder,
                           const ExportOptions& options = {}, const ExportProgress& progress = {});

}  // namespace dcl::sim
