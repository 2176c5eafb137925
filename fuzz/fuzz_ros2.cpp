// libFuzzer target: ROS 2 messages as a robot receives them (the bytes of one
// DDS sample, encapsulation header first): PointCloud2 and its points,
// Odometry, Imu (and the reading of up from it), Path, TFMessage, MarkerArray. Bytes may be refused
// only with core::Error.
#include <cstdint>
#include <span>

#include <dcl/core/error.hpp>
#include <dcl/io/point_cloud2.hpp>
#include <dcl/ros/ros2_messages.hpp>

namespace {

template <class M, class Then>
void decodeAs(std::span<const std::uint8_t> bytes, Then&& then) {
  try {
    then(dcl::ros2::decode<M>(bytes));
  } catch (const dcl::core::Error&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  using namespace dcl::ros2;
  decodeAs<PointCloud2>(bytes, [](const PointCloud2& m) {
    (void)dcl::io::decodePointCloud2(m.view(), m.header.stamp, /*drop_nan=*/true);
  });
  decodeAs<Odometry>(bytes, [](const Odometry&) {});
  decodeAs<Imu>(bytes,
                [](const Imu& m) { (void)dcl::msg::upInLidar(m, Eigen::Matrix3d::Identity()); });
  decodeAs<Path>(bytes, [](const Path&) {});
  decodeAs<TFMessage>(bytes, [](const TFMessage&) {});
  decodeAs<MarkerArray>(bytes, [](const MarkerArray&) {});
  return 0;
}
