#pragma once

// A ROS 2 participant without ROS 2: topics read and written on DDS as
// rmw_cyclonedds does (DDS topic "rt/<name>", ROS 2's type names and QoS
// profiles, the default partition, apart from the swarm's), so that ROS 2
// nodes, RViz and Foxglove see them as any other node's; the node itself is
// announced on "ros_discovery_info" as rmw_dds_common defines it.

#include <cctype>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include <dcl/comm/dds_transport.hpp>
#include <dcl/core/config.hpp>
#include <dcl/ros/ros2_messages.hpp>

namespace dcl::ros2 {

/// How a topic's samples travel, as ROS 2's QoS profiles do.
enum class Qos {
  sensor_data,      ///< best effort, keep last 5: clouds from a driver
  reliable,         ///< reliable, keep last 10: ROS 2's default
  transient_local,  ///< reliable, keep last 1, kept for late joiners: maps, paths
};

/// Where the node speaks.
struct NodeConfig {
  static constexpr std::uint32_t kMaxDomain = 232;                        ///< as ROS_DOMAIN_ID
  static constexpr std::size_t kMaxSampleBytes = std::size_t{256} << 20;  ///< a cloud at most

  /// DDS domain id, ROS 2's ROS_DOMAIN_ID.
  std::uint32_t domain = 0;
  /// Network interface with multicast discovery on it (e.g. "lo"); empty:
  /// Cyclone's default or CYCLONEDDS_URI.
  std::string interface {};
  /// The node's name, as `ros2 node list` shows it (in namespace "/").
  std::string name = "dcl_slam";

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("domain", domain, "DDS domain of the ROS 2 topics (ROS_DOMAIN_ID)").atMost(kMaxDomain);
    v.field("interface", interface, "network interface with multicast discovery (empty: default)")
        .rule(interface.size() <= comm::DdsConfig::kMaxInterfaceChars &&
                  comm::isPlainName(interface, "_-.:"),
              "must be empty or a network interface name (up to 15 letters, digits or '_', '-', "
              "'.', ':')");
    v.field("name", name, "the node's name")
        .rule(!name.empty() && name.size() <= 256 && comm::isPlainName(name, "_") &&
                  std::isdigit(static_cast<unsigned char>(name.front())) == 0,
              "must be letters, digits and '_', not starting with a digit, up to 256");
  }
};

/// "/a/odom" or "a/odom" as the DDS topic "rt/a/odom"; throws core::Error naming
/// the name when it is not a ROS 2 topic name (letters, digits, '_' and '/',
/// no empty part, no part starting with a digit).
std::string ddsTopicName(const std::string& ros_name);

/// One participant: publishers and subscriptions of the messages in
/// ros2_messages.hpp. Not thread-safe: call from one thread.
class Node {
 public:
  /// Joins the domain; throws core::Error if it cannot.
  explicit Node(const NodeConfig& config);
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  /// Makes the writer of `topic` (once; later calls must give the same QoS).
  template <class M>
  void advertise(const std::string& topic, Qos qos);

  /// Writes `message` on `topic`, which advertise() made.
  template <class M>
  void publish(const std::string& topic, const M& message);

  /// Calls `callback` in spin() with each message that arrives on `topic`.
  /// A sample whose values the message cannot hold (a zero quaternion, a time
  /// out of range) is dropped and counted in refused().
  /// `depth` > 0 keeps that many samples instead of the profile's (a fast
  /// odometry topic read between two scans' work).
  template <class M>
  void subscribe(const std::string& topic, Qos qos, std::function<void(M&&)> callback,
                 std::int32_t depth = 0);

  /// Hands what arrived to the callbacks, waiting up to `timeout` for the
  /// first sample; returns the number of messages delivered.
  std::size_t spin(std::chrono::milliseconds timeout);

  /// Samples dropped per topic, and why (the last reason).
  [[nodiscard]] std::map<std::string, std::pair<std::size_t, std::string>> refused() const;

  /// Readers and writers of other participants matched to this node's on `topic`.
  [[nodiscard]] std::size_t matched(const std::string& topic) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::ros2
