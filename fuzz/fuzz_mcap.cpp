// libFuzzer target: MCAP files (the records, the summary and its indexes,
// uncompressed, zstd and lz4 chunks, CRCs) and the ROS 2 PointCloud2,
// Odometry, PoseStamped and Imu messages in them. A reader may refuse input only
// with core::FileError. The input is handed over as an in-memory file.
#include <cstdint>
#include <set>
#include <string>

#include <dcl/core/error.hpp>
#include <dcl/io/mcap.hpp>
#include <dcl/ros/ros2_bag.hpp>

#include "fuzz_input_file.hpp"

namespace {

/// Every message's bytes, past damaged ones.
void readMessages(const std::string& path) {
  dcl::io::McapReader reader(path);
  for (const auto& ref : reader.messages()) {
    try {
      (void)reader.read(ref);
    } catch (const dcl::core::FileError&) {
    }
  }
}

/// One topic of each type the way the pipeline reads it: clouds one by one,
/// past bad ones; poses as a trajectory.
void readTopics(const std::string& path) {
  std::set<std::string> types_read;
  for (const auto& topic : dcl::ros2::listMcapTopics(path)) {
    if (!types_read.insert(topic.type).second) continue;
    try {
      if (topic.type == "sensor_msgs/msg/PointCloud2") {
        dcl::ros2::McapCloudReader reader(path, topic.name);
        for (;;) {
          try {
            if (!reader.next()) break;
          } catch (const dcl::core::FileError&) {
          }
        }
      } else if (topic.type == "sensor_msgs/msg/Imu") {
        (void)dcl::ros2::readMcapImu(path, topic.name);
      } else {
        (void)dcl::ros2::readMcapTrajectory(path, topic.name);
      }
    } catch (const dcl::core::FileError&) {
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  dcl::fuzz::withMemoryFile("mcap", data, size, [](const std::string& path) {
    try {
      readMessages(path);
      readTopics(path);
    } catch (const dcl::core::FileError&) {
    }
  });
  return 0;
}
