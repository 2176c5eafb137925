#include <filesystem>
#include <type_traits>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/bag_writer.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/ros/ros1_messages.hpp>
#include <dcl/ros/ros2_bag.hpp>
#include <dcl/sim/export.hpp>
#include <dcl/sim/imu_model.hpp>
#include <dcl/sim/sim_source.hpp>

namespace dcl::sim {

namespace {

namespace fs = std::filesystem;

/// Counts scans and points as they are written and reports progress.
struct Tally {
  std::size_t total = 0;
  std::size_t scans = 0;
  std::size_t points = 0;
  const ExportProgress& progress;

  void add(const core::PointCloud& cloud) {
    ++scans;
    points += cloud.size();
    if (progress) progress(scans, total);
  }
};

void writeTimes(const std::string& path, const io::ScanSource& source) {
  io::writeFileAtomic(path, [&](std::ostream& out) {
    for (std::size_t i = 0; i < source.size(); ++i) out << fmt::format("{}\n", source.stamp(i));
  });
}

io::ScanSourceSpec exportKitti(const io::ScanSource& source,
                               const std::optional<core::Trajectory>& gt, const fs::path& dir,
                               Tally& tally) {
  for (std::size_t i = 0; i < source.size(); ++i) {
    const core::PointCloud cloud = source.scan(i);
    io::writeKittiScan((dir / "velodyne" / fmt::format("{:06}.bin", i)).string(), cloud);
    tally.add(cloud);
  }
  writeTimes((dir / "times.txt").string(), source);
  if (gt) io::writeKittiPoses((dir / "poses.txt").string(), *gt);
  const std::string name = dir.filename().string();
  return {.type = io::ScanSourceType::kitti,
          .folder = name + "/velodyne",
          .times = name + "/times.txt"};
}

/// Scans and ground truth into a ROS1 bag (io::BagWriter) or a ROS 2 one
/// (ros2::McapBagWriter): both write the same messages.
template <class Writer>
io::ScanSourceSpec exportBag(const io::ScanSource& source, const io::RobotSpec& robot,
                             const std::optional<core::Trajectory>& gt, const fs::path& dir,
                             const ExportOptions& options, Tally& tally) {
  const double offset = options.bag_epoch + robot.start_time;
  const std::string frame = robot.name + "/lidar";
  constexpr bool mcap = std::is_same_v<Writer, ros2::McapBagWriter>;
  const std::string file = mcap ? "scans.mcap" : "scans.bag";
  Writer writer((dir / file).string());
  const double tilt_sigma = ImuModel{}.readingSigma();
  bool with_imu = false;
  for (std::size_t i = 0; i < source.size(); ++i) {
    const double stamp = offset + source.stamp(i);
    // The IMU's reading of up with the scan, as the orientation of a
    // sensor_msgs/Imu (the simulated IMU sits at the LiDAR): before it, as a
    // driver's IMU at hundreds of Hz would be.
    if (const std::optional<Eigen::Vector3d> up = source.up(i)) {
      with_imu = true;
      const msg::Imu imu = msg::imuOfUp(*up, tilt_sigma * tilt_sigma, {stamp, frame});
      if constexpr (mcap) {
        writer.writeImu(options.imu_topic, imu);
      } else {
        const ros1::MessageType& type = ros1::messageType<msg::Imu>();
        writer.writeSerialised(options.imu_topic, stamp, type.name, type.md5sum, type.definition,
                               ros1::encode(imu, static_cast<std::uint32_t>(i)));
      }
    }
    const core::PointCloud cloud = source.scan(i);
    writer.writeCloud(options.cloud_topic, stamp, cloud, frame);
    tally.add(cloud);
  }
  for (std::size_t i = 0; gt && i < gt->size(); ++i) {
    writer.writeOdometry(options.ground_truth_topic, offset + gt->stamp(i), gt->pose(i),
                         options.world_frame, frame);
  }
  writer.close();
  return {.type = mcap ? io::ScanSourceType::mcap : io::ScanSourceType::bag,
          .file = dir.filename().string() + "/" + file,
          .topic = options.cloud_topic,
          .imu_topic = with_imu ? options.imu_topic : std::string()};
}

/// A byte-exact copy (a TUM file read and written again could differ in the last digits).
void copyFile(const std::string& from, const fs::path& to) {
  const std::vector<char> bytes = io::readFile(from);
  io::writeFileAtomic(
      to.string(), [&](std::ostream& out) { out.write(bytes.data(), std::ssize(bytes)); }, true);
}

std::uintmax_t folderBytes(const fs::path& folder) {
  std::uintmax_t bytes = 0;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    if (entry.is_regular_file()) bytes += entry.file_size();
  }
  return bytes;
}

std::size_t totalScans(const std::vector<std::unique_ptr<io::ScanSource>>& sources) {
  std::size_t total = 0;
  for (const auto& s : sources) total += s->size();
  return total;
}

}  // namespace

std::string_view toString(ExportFormat format) {
  switch (format) {
    case ExportFormat::bag:
      return "bag";
    case ExportFormat::mcap:
      return "mcap";
    default:
      return "kitti";
  }
}

std::optional<ExportFormat> parseExportFormat(std::string_view name) {
  for (const auto format : {ExportFormat::kitti, ExportFormat::bag, ExportFormat::mcap}) {
    if (toString(format) == name) return format;
  }
  return std::nullopt;
}

ExportResult exportDataset(const io::DatasetSpec& spec, const std::string& folder,
                           const ExportOptions& options, const ExportProgress& progress) {
  const auto sources = openDatasetScans(spec);
  Tally tally{.total = totalScans(sources), .progress = progress};
  io::DatasetSpec copy = spec;
  copy.sim.reset();
  for (std::size_t r = 0; r < spec.robots.size(); ++r) {
    io::RobotSpec& robot = copy.robots[r];
    const fs::path dir = fs::path(folder) / robot.name;
    std::optional<core::Trajectory> gt;
    if (!robot.ground_truth.empty()) gt = io::readGroundTruth(spec, r);
    switch (options.format) {
      case ExportFormat::bag:
        robot.scans = exportBag<io::BagWriter>(*sources[r], robot, gt, dir, options, tally);
        break;
      case ExportFormat::mcap:
        robot.scans = exportBag<ros2::McapBagWriter>(*sources[r], robot, gt, dir, options, tally);
        break;
      default:
        robot.scans = exportKitti(*sources[r], gt, dir, tally);
    }
    if (gt) {
      robot.ground_truth = robot.name + "/ground_truth.tum";
      copyFile(spec.resolve(spec.robots[r].ground_truth), (fs::path(folder) / robot.ground_truth));
    }
    // An external front-end's poses go along.
    if (const io::FrontEndSpec& from = spec.robots[r].odometry; !from.empty()) {
      robot.odometry.file = robot.name + "/odometry" + fs::path(from.file).extension().string();
      copyFile(spec.resolve(from.file), fs::path(folder) / robot.odometry.file);
      if (!from.times.empty()) {
        robot.odometry.times = robot.name + "/odometry_times.txt";
        copyFile(spec.resolve(from.times), fs::path(folder) / robot.odometry.times);
      }
    }
  }
  io::writeDataset(folder, copy);
  return {.dataset = io::readDataset(folder),
          .scans = tally.scans,
          .points = tally.points,
          .bytes = folderBytes(folder)};
}

}  // namespace dcl::sim
