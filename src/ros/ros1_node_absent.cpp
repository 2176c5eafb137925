// ROS 1 in a build without roscpp (ros1_node.hpp): the node says what to install.
#include <dcl/ros/ros1_node.hpp>

namespace dcl::ros1 {

struct Node::Impl {};

bool available() {
  return false;
}

Node::Node(const NodeConfig& /*config*/) {
  throw core::Error(
      "ROS 1: this dcl-slam was built without roscpp; install libroscpp-dev and "
      "libtopic-tools-dev (scripts/setup does) and build again");
}

Node::~Node() = default;

void Node::advertiseBytes(const std::string& /*topic*/, const MessageType& /*type*/, Qos /*qos*/) {}
void Node::publishBytes(const std::string& /*topic*/, const std::vector<std::uint8_t>& /*bytes*/) {}
void Node::subscribeBytes(const std::string& /*topic*/, const MessageType& /*type*/, Qos /*qos*/,
                          std::int32_t /*depth*/,
                          std::function<void(std::span<const std::uint8_t>)> /*take*/) {}

std::size_t Node::spin(std::chrono::milliseconds /*timeout*/) {
  return 0;
}

std::map<std::string, std::pair<std::size_t, std::string>> Node::refused() const {
  return {};
}

std::size_t Node::matched(const std::string& /*topic*/) const {
  return 0;
}

}  // namespace dcl::ros1
