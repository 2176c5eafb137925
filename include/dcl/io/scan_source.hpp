#pragma once

/// A robot's scans by index, wherever they come from: a KITTI folder, a ROS1
/// bag topic, or (in dcl::sim) the simulator regenerating them on demand.

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/io/dataset.hpp>

namespace dcl::io {

/// The scans of one robot, by index, with their stamps (s since the robot's start).
class ScanSource {
 public:
  virtual ~ScanSource() = default;

  /// Number of scans.
  [[nodiscard]] virtual std::size_t size() const = 0;

  /// Stamp of scan `i`, seconds since the robot's start; throws core::Error past the end.
  [[nodiscard]] virtual double stamp(std::size_t i) const = 0;

  /// Scan `i`, points in the sensor frame at firing time. Throws core::Error past
  /// the end and core::FileError when the scan cannot be read.
  [[nodiscard]] virtual core::PointCloud scan(std::size_t i) const = 0;

  /// The robot's IMU reading of up (against gravity) at scan `i`'s stamp: a
  /// unit vector in the sensor frame. None (the default) when the source has no IMU.
  [[nodiscard]] virtual std::optional<Eigen::Vector3d> up(std::size_t /*i*/) const {
    return std::nullopt;
  }

  /// What the scans are, for messages ("kitti folder a/velodyne", ...).
  [[nodiscard]] virtual std::string describe() const = 0;
};

/// A folder of KITTI scans `000000.bin`, `000001.bin`, ... and a times file (one
/// stamp a line, s since the start). `scan` is safe to call from several threads.
class KittiScanSource final : public ScanSource {
 public:
  /// Reads the times file (io::readKittiTimes: finite stamps that increase);
  /// throws core::FileError when it cannot be read or is not one, or a scan file
  /// for one of its lines is missing.
  KittiScanSource(std::string folder, const std::string& times_path);

  /// Number of lines of the times file.
  [[nodiscard]] std::size_t size() const override { return stamps_.size(); }
  /// Line `i` of the times file.
  [[nodiscard]] double stamp(std::size_t i) const override;
  /// `scanPath(i)` read with io::readKittiScan (x y z intensity).
  [[nodiscard]] core::PointCloud scan(std::size_t i) const override;
  /// "kitti folder PATH".
  [[nodiscard]] std::string describe() const override;

  /// The path of scan `i` (`folder/NNNNNN.bin`).
  [[nodiscard]] std::string scanPath(std::size_t i) const;

 private:
  std::string folder_;
  std::vector<double> stamps_;
};

/// The sensor_msgs/PointCloud2 messages of one ROS1 bag topic. Stamps are the
/// header stamps relative to the first message's (the robot's start).
///
/// Access is cheapest in order: the bag is read forward; asking for an earlier
/// scan than the last one reopens the bag and reads forward again. Calls are
/// serialised by a mutex (safe from several threads, but not in parallel).
class BagScanSource final : public ScanSource {
 public:
  /// Opens the bag and reads every header stamp once; throws core::FileError
  /// when the bag or topic cannot be read or the topic holds no messages.
  BagScanSource(std::string path, std::string topic);
  ~BagScanSource() override;

  /// Number of messages on the topic.
  [[nodiscard]] std::size_t size() const override { return stamps_.size(); }
  /// Header stamp of message `i` minus that of message 0.
  [[nodiscard]] double stamp(std::size_t i) const override;
  /// Message `i` decoded by io::BagCloudReader (every channel the message has).
  [[nodiscard]] core::PointCloud scan(std::size_t i) const override;
  /// "bag PATH topic TOPIC".
  [[nodiscard]] std::string describe() const override;

  /// The header stamp of the first message, s since the epoch (stamp 0).
  [[nodiscard]] double originStamp() const { return origin_; }

 private:
  struct Reader;
  std::string path_;
  std::string topic_;
  std::vector<double> stamps_;
  double origin_ = 0.0;
  mutable std::mutex mutex_;
  mutable std::unique_ptr<Reader> reader_;
};

/// The scans of robot `robot` of a dataset whose scans are on disk (kitti or
/// bag). Throws core::Error for a simulated robot or an MCAP one (dcl::sim
/// opens those: sim::openRobotScans) and core::FileError when the files cannot be read.
std::unique_ptr<ScanSource> openScanSource(const DatasetSpec& spec, std::size_t robot);

}  // namespace dcl::io
