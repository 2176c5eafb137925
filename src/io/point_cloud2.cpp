// sensor_msgs/PointCloud2's points, read and laid out alike for ROS 1 bags and
// ROS 2 topics (point_fields.hpp does the per-field work).
#include <array>
#include <cstring>
#include <optional>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/point_cloud2.hpp>

#include "point_fields.hpp"

namespace dcl::io {

namespace {

using detail::PointLayout;
using detail::ScalarKind;
using detail::ScalarType;

std::optional<ScalarType> rosScalarType(std::uint8_t datatype) {
  switch (datatype) {  // sensor_msgs/PointField constants
    case 1:
      return ScalarType{ScalarKind::kInt, 1};
    case 2:
      return ScalarType{ScalarKind::kUint, 1};
    case 3:
      return ScalarType{ScalarKind::kInt, 2};
    case 4:
      return ScalarType{ScalarKind::kUint, 2};
    case 5:
      return ScalarType{ScalarKind::kInt, 4};
    case 6:
      return ScalarType{ScalarKind::kUint, 4};
    case 7:
      return ScalarType{ScalarKind::kFloat, 4};
    case 8:
      return ScalarType{ScalarKind::kFloat, 8};
    default:
      return std::nullopt;
  }
}

PointLayout cloudLayout(const PointCloud2View& msg) {
  PointLayout layout;
  layout.swap = msg.is_bigendian;
  for (const auto& f : msg.fields) {
    const auto channel = detail::channelOf(f.name);
    if (!channel) continue;
    const auto type = rosScalarType(f.datatype);
    if (!type)
      throw core::Error(fmt::format("field '{}': unknown datatype {}", f.name, f.datatype));
    if (std::size_t{f.offset} + type->size > msg.point_step) {
      throw core::Error(fmt::format("field '{}' (offset {}, {} bytes) overruns point_step {}",
                                    f.name, f.offset, type->size, msg.point_step));
    }
    layout.assign(*channel, {f.offset, msg.point_step, *type, f.name});
  }
  if (auto missing = layout.missingXyz()) {
    throw core::Error(fmt::format("no field '{}' among the PointCloud2 fields", *missing));
  }
  return layout;
}

/// Checks width, height, point_step and row_step against the data length.
void checkCloudSize(const PointCloud2View& msg) {
  if (msg.width == 0 || msg.height == 0) return;
  const std::size_t row_bytes = std::size_t{msg.width} * msg.point_step;  // < 2^64
  if (msg.row_step < row_bytes) {
    throw core::Error(fmt::format("row_step {} is less than width {} x point_step {}", msg.row_step,
                                  msg.width, msg.point_step));
  }
  const std::size_t total = std::size_t{msg.row_step} * msg.height;
  if (msg.data.size() < total) {
    throw core::Error(fmt::format("data holds {} bytes, height {} x row_step {} needs {}",
                                  msg.data.size(), msg.height, msg.row_step, total));
  }
}

/// The layout written: x y z intensity float32, ring uint16 (+2 bytes pad), time float32.
constexpr std::uint8_t kUint16 = 4;
constexpr std::uint8_t kFloat32 = 7;
constexpr std::uint32_t kPointStep = 24;

}  // namespace

core::PointCloud decodePointCloud2(const PointCloud2View& msg, double stamp, bool drop_nan) {
  const PointLayout layout = cloudLayout(msg);
  checkCloudSize(msg);
  detail::CloudBuilder builder(layout, drop_nan);
  if (msg.width == 0 || msg.height == 0) return builder.finish(stamp);  // no rows to walk
  builder.reserve(std::size_t{msg.width} * msg.height);
  for (std::size_t r = 0; r < msg.height; ++r) {
    const char* row = reinterpret_cast<const char*>(msg.data.data()) + r * msg.row_step;
    for (std::size_t c = 0; c < msg.width; ++c) {
      if (auto error = builder.add(detail::loadPoint(row, c, layout))) {
        throw core::Error(fmt::format("point {}: {}", r * msg.width + c, *error));
      }
    }
  }
  return builder.finish(stamp);
}

PointCloud2Data encodePointCloud2(const core::PointCloud& cloud) {
  if (!cloud.consistent()) throw core::Error("a cloud's channels are of different lengths");
  PointCloud2Data out;
  out.fields = {{"x", 0, kFloat32},          {"y", 4, kFloat32},    {"z", 8, kFloat32},
                {"intensity", 12, kFloat32}, {"ring", 16, kUint16}, {"time", 20, kFloat32}};
  out.point_step = kPointStep;
  out.data.assign(cloud.size() * kPointStep, 0);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    std::uint8_t* record = out.data.data() + i * kPointStep;
    const Eigen::Vector3f& p = cloud.points[i];
    const float values[4] = {p.x(), p.y(), p.z(), cloud.hasIntensity() ? cloud.intensity[i] : 0.0f};
    const std::uint16_t ring = cloud.hasRing() ? cloud.ring[i] : 0;
    const float time = cloud.hasTime() ? cloud.time[i] : 0.0f;
    std::memcpy(record, values, sizeof(values));
    std::memcpy(record + 16, &ring, sizeof(ring));
    std::memcpy(record + 20, &time, sizeof(time));
  }
  return out;
}

}  // namespace dcl::io
