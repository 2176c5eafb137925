#pragma once

// Ids, pose keys and data paths as the tests write them, shared by the test
// files of one program (a program's files compile together in unity batches).

#include <cstdint>
#include <string>

#include <dcl/core/ids.hpp>

namespace dcl::test {

/// Robot `id`.
inline core::RobotId robot(int id) {
  return core::RobotId(static_cast<std::uint8_t>(id));
}

/// Keyframe `keyframe` of robot `robot`.
inline core::PoseKey key(int robot, int keyframe) {
  return {core::RobotId(static_cast<std::uint8_t>(robot)),
          core::KeyframeId(static_cast<std::uint64_t>(keyframe))};
}

/// A file under the shared data's pose_graphs folder.
inline std::string poseGraphPath(const std::string& relative) {
  return std::string(DCL_DATA_DIR) + "/pose_graphs/" + relative;
}

}  // namespace dcl::test
