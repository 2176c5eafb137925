#include <array>
#include <cstring>
#include <span>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/kitti_scan.hpp>

#include "point_fields.hpp"

namespace dcl::io {

namespace {

core::PointCloud decodeRecords(std::span<const char> data, std::size_t n) {
  core::PointCloud cloud;
  cloud.points.resize(n);
  cloud.intensity.resize(n);
  std::array<float, 4> record{};
  for (std::size_t i = 0; i < n; ++i) {
    std::memcpy(record.data(), data.data() + i * kKittiRecordBytes, kKittiRecordBytes);
    cloud.points[i] = {record[0], record[1], record[2]};
    cloud.intensity[i] = record[3];
  }
  return cloud;
}

std::string encodeRecords(const core::PointCloud& cloud) {
  std::string data(cloud.size() * kKittiRecordBytes, '\0');
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const auto& p = cloud.points[i];
    const std::array<float, 4> record{p.x(), p.y(), p.z(),
                                      cloud.hasIntensity() ? cloud.intensity[i] : 0.0f};
    std::memcpy(data.data() + i * kKittiRecordBytes, record.data(), kKittiRecordBytes);
  }
  return data;
}

}  // namespace

core::PointCloud readKittiScan(const std::string& path) {
  return decodeKittiScan(readFile(path), path);
}

core::PointCloud decodeKittiScan(std::span<const char> data, const std::string& name) {
  if (data.empty()) throw core::FileError({name, std::nullopt, 0}, "empty file (no points)");
  const std::size_t n = data.size() / kKittiRecordBytes;
  if (data.size() % kKittiRecordBytes != 0) {
    throw core::FileError(
        {name, std::nullopt, n * kKittiRecordBytes},
        fmt::format("partial point record: {} bytes of 16 (file size {} is not a multiple of 16)",
                    data.size() % kKittiRecordBytes, data.size()));
  }
  return decodeRecords(data, n);
}

void writeKittiScan(const std::string& path, const core::PointCloud& cloud) {
  detail::requireConsistent(cloud, path);
  if (cloud.empty()) {
    throw core::FileError({path}, "cannot write an empty cloud (an empty .bin reads as an error)");
  }
  const std::string data = encodeRecords(cloud);
  detail::writeBytes(path, data);
}

}  // namespace dcl::io
