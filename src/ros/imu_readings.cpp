#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/ros/imu_readings.hpp>
#include <dcl/ros/ros1_messages.hpp>

namespace dcl::msg {

Eigen::Matrix3d rotationOfRpy(double roll_deg, double pitch_deg, double yaw_deg) {
  const double k = M_PI / 180.0;
  return (Eigen::AngleAxisd(k * yaw_deg, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(k * pitch_deg, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(k * roll_deg, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

bool UpReadings::add(const Imu& imu, const Eigen::Matrix3d& R_lidar_imu, double offset) {
  const std::optional<Eigen::Vector3d> up = upInLidar(imu, R_lidar_imu);
  if (!up || !std::isfinite(imu.header.stamp + offset)) return false;
  add(imu.header.stamp + offset, *up);
  return true;
}

void UpReadings::add(double stamp, const Eigen::Vector3d& up) {
  // Nearly always at the end: readings come in stamp order.
  const auto at = std::upper_bound(readings_.begin(), readings_.end(), stamp,
                                   [](double s, const auto& r) { return s < r.first; });
  readings_.emplace(at, stamp, up);
}

std::optional<Eigen::Vector3d> UpReadings::nearest(double stamp, double max_gap) const {
  const auto after = std::lower_bound(readings_.begin(), readings_.end(), stamp,
                                      [](const auto& r, double s) { return r.first < s; });
  const std::pair<double, Eigen::Vector3d>* best = nullptr;
  if (after != readings_.end()) best = &*after;
  if (after != readings_.begin()) {
    const auto& before = *std::prev(after);
    if (best == nullptr || stamp - before.first < best->first - stamp) best = &before;
  }
  if (best == nullptr || std::abs(best->first - stamp) > max_gap) return std::nullopt;
  return best->second;
}

bool UpReadings::reaches(double stamp) const {
  return !readings_.empty() && readings_.back().first >= stamp;
}

void UpReadings::dropBefore(double stamp) {
  while (!readings_.empty() && readings_.front().first < stamp) readings_.pop_front();
}

LevelledScanSource::LevelledScanSource(std::unique_ptr<io::ScanSource> scans, UpReadings readings,
                                       double origin, double max_gap)
    : scans_(std::move(scans)),
      readings_(std::move(readings)),
      origin_(origin),
      max_gap_(max_gap) {}

std::optional<Eigen::Vector3d> LevelledScanSource::up(std::size_t i) const {
  return readings_.nearest(origin_ + scans_->stamp(i), max_gap_);
}

std::string LevelledScanSource::describe() const {
  return fmt::format("{}, levelled by {} IMU readings", scans_->describe(), readings_.size());
}

}  // namespace dcl::msg

namespace dcl::ros1 {

std::vector<msg::Imu> readBagImu(const std::string& path, const std::string& topic) {
  const MessageType& type = messageType<msg::Imu>();
  const std::vector<io::RawBagMessage> raw =
      io::readBagMessages(path, topic, type.name, type.md5sum);
  std::vector<msg::Imu> out;
  out.reserve(raw.size());
  for (std::size_t i = 0; i < raw.size(); ++i) {
    try {
      out.push_back(decode<msg::Imu>(raw[i].bytes));
    } catch (const core::Error& e) {
      throw core::FileError({path}, fmt::format("topic '{}' message {}: {}", topic, i, e.what()));
    }
  }
  return out;
}

}  // namespace dcl::ros1
