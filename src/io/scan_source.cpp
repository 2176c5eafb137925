#include <filesystem>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/io/scan_source.hpp>

namespace dcl::io {

namespace {

namespace fs = std::filesystem;

void requireIndex(std::size_t i, std::size_t size, const std::string& what) {
  if (i >= size) throw core::Error(fmt::format("{}: no scan {} (it has {})", what, i, size));
}

}  // namespace

// ---- KITTI folder ----

KittiScanSource::KittiScanSource(std::string folder, const std::string& times_path)
    : folder_(std::move(folder)), stamps_(readKittiTimes(times_path)) {
  for (std::size_t i = 0; i < stamps_.size(); ++i) {
    if (!fs::is_regular_file(scanPath(i))) {
      throw core::FileError({times_path}, fmt::format("{} stamps, but scan {} is missing",
                                                      stamps_.size(), scanPath(i)));
    }
  }
}

double KittiScanSource::stamp(std::size_t i) const {
  requireIndex(i, stamps_.size(), describe());
  return stamps_[i];
}

core::PointCloud KittiScanSource::scan(std::size_t i) const {
  requireIndex(i, stamps_.size(), describe());
  return readKittiScan(scanPath(i));
}

std::string KittiScanSource::describe() const {
  return "kitti folder " + folder_;
}

std::string KittiScanSource::scanPath(std::size_t i) const {
  return (fs::path(folder_) / fmt::format("{:06}.bin", i)).string();
}

// ---- ROS1 bag ----

/// The open bag, positioned at scan `reader.index()`.
struct BagScanSource::Reader {
  BagCloudReader reader;
};

BagScanSource::BagScanSource(std::string path, std::string topic)
    : path_(std::move(path)), topic_(std::move(topic)) {
  BagCloudReader reader(path_, topic_);
  stamps_.reserve(reader.size());
  while (auto cloud = reader.next()) stamps_.push_back(cloud->stamp);
  if (stamps_.empty()) throw core::FileError({path_}, "topic '" + topic_ + "' has no messages");
  origin_ = stamps_.front();
  for (double& s : stamps_) s -= origin_;
}

BagScanSource::~BagScanSource() = default;

double BagScanSource::stamp(std::size_t i) const {
  requireIndex(i, stamps_.size(), describe());
  return stamps_[i];
}

core::PointCloud BagScanSource::scan(std::size_t i) const {
  requireIndex(i, stamps_.size(), describe());
  const std::lock_guard lock(mutex_);
  if (!reader_ || reader_->reader.index() > i) {
    reader_ = std::make_unique<Reader>(Reader{BagCloudReader(path_, topic_)});
  }
  while (reader_->reader.index() < i) reader_->reader.next();
  auto cloud = reader_->reader.next();
  if (!cloud)
    throw core::FileError({path_}, fmt::format("topic '{}' ended before scan {}", topic_, i));
  return std::move(cloud->cloud);
}

std::string BagScanSource::describe() const {
  return "bag " + path_ + " topic " + topic_;
}

// ---- factory ----

std::unique_ptr<ScanSource> openScanSource(const DatasetSpec& spec, std::size_t robot) {
  const RobotSpec& r = spec.robots.at(robot);
  switch (r.scans.type) {
    case ScanSourceType::kitti:
      return std::make_unique<KittiScanSource>(spec.resolve(r.scans.folder),
                                               spec.resolve(r.scans.times));
    case ScanSourceType::bag:
      return std::make_unique<BagScanSource>(spec.resolve(r.scans.file), r.scans.topic);
    case ScanSourceType::mcap:
      throw core::Error(fmt::format(
          "dataset '{}': robot '{}' has its scans in a ROS 2 bag (MCAP), which dcl::ros decodes "
          "(open it with dcl::sim::openRobotScans)",
          spec.name, r.name));
    default:
      throw core::Error(fmt::format(
          "dataset '{}': robot '{}' has simulated scans (open it with dcl::sim::openRobotScans)",
          spec.name, r.name));
  }
}

}  // namespace dcl::io
