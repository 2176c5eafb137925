#pragma once

// sensor_msgs/PointCloud2 as ROS 1 and ROS 2 both define it, apart from how
// each serialises it: its points read into a core::PointCloud whatever the
// driver's layout (fields in any order and type, padding, rows, big-endian),
// and a core::PointCloud laid out for publishing.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>

namespace dcl::io {

/// sensor_msgs/PointField.
struct PointField {
  std::string name{};
  std::uint32_t offset = 0;
  std::uint8_t datatype =
      0;  ///< INT8 = 1, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = 8
  std::uint32_t count = 1;
};

/// The fields of a sensor_msgs/PointCloud2 but its header, the data borrowed.
struct PointCloud2View {
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  std::vector<PointField> fields{};
  bool is_bigendian = false;
  std::uint32_t point_step = 0;
  std::uint32_t row_step = 0;
  std::span<const std::uint8_t> data{};
};

/// The points of `msg` stamped `stamp`: x, y and z (required), intensity, time
/// (s from the stamp) and ring when present. Non-finite points are dropped when
/// `drop_nan`, an error otherwise. Throws core::Error naming the field or the
/// size that does not fit.
core::PointCloud decodePointCloud2(const PointCloud2View& msg, double stamp, bool drop_nan);

/// A cloud laid out for publishing: x y z intensity float32, ring uint16 (and
/// 2 bytes of padding), time float32; 24 bytes a point, little-endian, one row.
struct PointCloud2Data {
  std::vector<PointField> fields{};
  std::uint32_t point_step = 0;
  std::vector<std::uint8_t> data{};
};

/// `cloud` as PointCloud2 fields and data (channels it lacks are written as 0).
/// Throws core::Error if its channels are of different lengths.
PointCloud2Data encodePointCloud2(const core::PointCloud& cloud);

}  // namespace dcl::io
