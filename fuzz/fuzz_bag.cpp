// libFuzzer target: ROS1 bags (the record layer, bz2 and lz4 chunks, and the
// PointCloud2, Odometry, PoseStamped and Imu messages in them). A reader may refuse
// input only with core::FileError. The input is handed over as an in-memory file.
#include <cstdint>
#include <set>
#include <string>

#include <dcl/core/error.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/ros/imu_readings.hpp>

#include "fuzz_input_file.hpp"

namespace {

/// Reads one topic of each message type the way the pipeline does: clouds one
/// by one, past bad ones (each topic opens the bag anew, and a second topic of
/// a type would only slow the search).
void readAll(const std::string& path) {
  std::set<std::string> types_read;
  for (const auto& topic : dcl::io::listBagTopics(path)) {
    if (!types_read.insert(topic.type).second) continue;
    try {
      if (topic.type == "sensor_msgs/PointCloud2") {
        dcl::io::BagCloudReader reader(path, topic.name);
        for (;;) {
          try {
            if (!reader.next()) break;
          } catch (const dcl::core::FileError&) {
          }
        }
      } else if (topic.type == "sensor_msgs/Imu") {
        (void)dcl::ros1::readBagImu(path, topic.name);
      } else {
        (void)dcl::io::readBagTrajectory(path, topic.name);
      }
    } catch (const dcl::core::FileError&) {
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  dcl::fuzz::withMemoryFile("bag", data, size, [](const std::string& path) {
    try {
      readAll(path);
    } catch (const dcl::core::FileError&) {
    }
  });
  return 0;
}
