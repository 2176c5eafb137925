#pragma once

// The wire form of the ROS messages (messages.hpp) on ROS 2, as
// rmw_cyclonedds puts them on DDS: XCDR1 (plain CDR) after the 4-byte
// encapsulation header, little-endian when written. The types on the wire are
// generated from idl/ros2/*.idl; nothing here needs a ROS 2 installation.
//
// Decoding accepts either byte order and refuses (core::Error naming the type
// and what is wrong) bytes that do not hold one whole message of the type.

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include <dcl/ros/messages.hpp>

namespace dcl::ros2 {

using msg::ColorRGBA;
using msg::Header;
using msg::Imu;
using msg::Marker;
using msg::MarkerArray;
using msg::Odometry;
using msg::Path;
using msg::PointCloud2;
using msg::PoseStamped;
using msg::TFMessage;
using msg::toPointCloud2;  // the values, by the names of their ROS 2 codec
using msg::TransformStamped;

/// The DDS type name of each message, as ROS 2 names it on the wire.
template <class Message>
std::string_view typeName();

/// The message's bytes on the wire: encapsulation header (CDR, little-endian), then XCDR1.
std::vector<std::uint8_t> encode(const PointCloud2& message);
std::vector<std::uint8_t> encode(const Imu& message);
std::vector<std::uint8_t> encode(const Odometry& message);
std::vector<std::uint8_t> encode(const PoseStamped& message);
std::vector<std::uint8_t> encode(const Path& message);
std::vector<std::uint8_t> encode(const TFMessage& message);
std::vector<std::uint8_t> encode(const MarkerArray& message);

/// The message the bytes hold; throws core::Error naming the type and the reason.
template <class Message>
Message decode(std::span<const std::uint8_t> bytes);

}  // namespace dcl::ros2
