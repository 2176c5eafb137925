#pragma once

// The wire form of the ROS messages (messages.hpp) on ROS 1: its own
// serialisation (little-endian, packed; a string or a variable array is a
// uint32 count then its elements; a time is uint32 seconds and nanoseconds),
// and each type's name, MD5 sum and full definition, which a ROS 1 connection
// and a bag both carry. Written here without ROS; ROS 1's own serialisers
// (genpy, roscpp) read and write the same bytes.
//
// Decoding refuses (core::Error naming the type, the field and what is wrong)
// bytes that do not hold exactly one whole message of the type, before
// allocating more than the bytes could hold; as the ROS 2 codec, it also
// refuses a boolean neither 0 nor 1, nanoseconds of 10^9 or more, and a
// non-finite position or an orientation whose norm is not within 1% of 1
// (which it normalises). The header's seq is not kept (msg::Header has none).

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include <dcl/ros/messages.hpp>

namespace dcl::ros1 {

/// What a ROS 1 connection and a bag say of a message type.
struct MessageType {
  std::string_view name;        ///< e.g. "sensor_msgs/PointCloud2"
  std::string_view md5sum;      ///< of the definition, as genmsg computes it
  std::string_view definition;  ///< the full text, with its dependencies' definitions
};

/// The type of each message.
template <class Message>
const MessageType& messageType();

/// The message's bytes; `seq` goes into the message's own header (TFMessage and
/// MarkerArray have none; the headers of the poses, transforms and markers
/// inside a message get 0). Throws core::Error naming the type and the field
/// for a stamp that is not a ROS 1 time (uint32 seconds since the epoch), a
/// lifetime that is not a ROS 1 duration (int32 seconds), or a string or an
/// array longer than a uint32 count.
std::vector<std::uint8_t> encode(const msg::PointCloud2& message, std::uint32_t seq = 0);
std::vector<std::uint8_t> encode(const msg::Imu& message, std::uint32_t seq = 0);
std::vector<std::uint8_t> encode(const msg::Odometry& message, std::uint32_t seq = 0);
std::vector<std::uint8_t> encode(const msg::PoseStamped& message, std::uint32_t seq = 0);
std::vector<std::uint8_t> encode(const msg::Path& message, std::uint32_t seq = 0);
std::vector<std::uint8_t> encode(const msg::TFMessage& message, std::uint32_t seq = 0);
std::vector<std::uint8_t> encode(const msg::MarkerArray& message, std::uint32_t seq = 0);

/// The message the bytes hold; throws core::Error naming the type and the reason.
template <class Message>
Message decode(std::span<const std::uint8_t> bytes);

}  // namespace dcl::ros1
