#pragma once

// A ROS 1 node through roscpp (Debian's libroscpp): topics of the messages in
// messages.hpp, serialised by ros1_messages.hpp, so that no ROS 1 message
// header is compiled. Built only where roscpp is (DCL_WITH_ROS1); elsewhere
// the node refuses to start, saying what to install.

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <dcl/core/error.hpp>
#include <dcl/ros/ros1_messages.hpp>

namespace dcl::ros1 {

/// How a topic's messages travel.
enum class Qos {
  sensor_data,      ///< queue of 5, TCP without Nagle: clouds from a driver
  reliable,         ///< queue of 100
  transient_local,  ///< latched: the last message goes to every late subscriber (maps, paths)
};

/// Where the node speaks.
struct NodeConfig {
  /// The node's name in the graph (e.g. "dcl_slam_a"): letters, digits, '_'.
  std::string name = "dcl_slam";
  /// The ROS master's URI; empty: ROS_MASTER_URI, as every ROS 1 node.
  std::string master_uri{};
  /// How long to wait for the master before giving up, s.
  double master_wait = 10.0;
};

/// Whether this build has ROS 1.
bool available();

/// Throws core::Error naming the name when it is not a ROS 1 graph name
/// (letters, digits, '_' and '/', no empty part, no part starting with a digit).
void checkTopicName(const std::string& name);

/// The node: publishers and subscriptions of the messages in messages.hpp.
/// One per process (roscpp is one per process). Not thread-safe: call from one
/// thread; callbacks run in spin().
class Node {
 public:
  /// Joins the graph; throws core::Error if ROS 1 is not built in or the master
  /// does not answer within config.master_wait.
  explicit Node(const NodeConfig& config);
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  /// Makes the publisher of `topic` (once per topic).
  template <class M>
  void advertise(const std::string& topic, Qos qos) {
    advertiseBytes(topic, messageType<M>(), qos);
  }

  /// Sends `message` on `topic`, which advertise() made.
  template <class M>
  void publish(const std::string& topic, const M& message) {
    publishBytes(topic, encode(message, ++seq_));
  }

  /// Calls `callback` in spin() with each message that arrives on `topic`. A
  /// message of another type or that does not decode is dropped and counted in
  /// refused(). `depth` > 0 queues that many messages instead of the Qos's.
  template <class M>
  void subscribe(const std::string& topic, Qos qos, std::function<void(M&&)> callback,
                 std::int32_t depth = 0) {
    subscribeBytes(topic, messageType<M>(), qos, depth,
                   [callback = std::move(callback)](std::span<const std::uint8_t> bytes) {
                     callback(decode<M>(bytes));
                   });
  }

  /// Hands what arrived to the callbacks, waiting up to `timeout` for the
  /// first message; returns the number of messages delivered.
  std::size_t spin(std::chrono::milliseconds timeout);

  /// Messages dropped per topic, and why (the last reason).
  [[nodiscard]] std::map<std::string, std::pair<std::size_t, std::string>> refused() const;

  /// Subscribers of `topic` connected to this node's publisher, or publishers
  /// connected to its subscription.
  [[nodiscard]] std::size_t matched(const std::string& topic) const;

 private:
  void advertiseBytes(const std::string& topic, const MessageType& type, Qos qos);
  void publishBytes(const std::string& topic, const std::vector<std::uint8_t>& bytes);
  /// `take` throws core::Error when the bytes are not a message of `type`.
  void subscribeBytes(const std::string& topic, const MessageType& type, Qos qos,
                      std::int32_t depth, std::function<void(std::span<const std::uint8_t>)> take);

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::uint32_t seq_ = 0;
};

}  // namespace dcl::ros1
