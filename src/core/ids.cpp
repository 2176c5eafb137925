#include <dcl/core/ids.hpp>

namespace dcl::core {

std::string robotName(RobotId robot) {
  if (robot.value() < 26) return std::string(1, static_cast<char>('a' + robot.value()));
  return std::to_string(robot.value());
}

std::string keyName(const PoseKey& key) {
  return robotName(key.robot) + std::to_string(key.keyframe.value());
}

}  // namespace dcl::core
