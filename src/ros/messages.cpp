#include <utility>

#include <dcl/ros/messages.hpp>

namespace dcl::msg {

PointCloud2 toPointCloud2(const core::PointCloud& cloud, Header header) {
  io::PointCloud2Data data = io::encodePointCloud2(cloud);
  PointCloud2 m;
  m.header = std::move(header);
  m.width = static_cast<std::uint32_t>(cloud.size());
  m.fields = std::move(data.fields);
  m.point_step = data.point_step;
  m.row_step = m.width * m.point_step;
  m.data = std::move(data.data);
  return m;
}

io::PointCloud2View PointCloud2::view() const {
  return {height, width, fields, is_bigendian, point_step, row_step, data};
}

}  // namespace dcl::msg
