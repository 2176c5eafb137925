#include <optional>

#include <dcl/core/error.hpp>
#include <dcl/io/external_odometry.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/rosbag.hpp>

namespace dcl::io {
namespace {

std::string formatOf(const std::string& path, const std::string& format) {
  if (format != "auto") return format;
  if (path.ends_with(".mcap")) return "mcap";
  return path.ends_with(".bag") ? "bag" : "tum";
}

}  // namespace

core::Trajectory readExternalOdometry(const std::string& path,
                                      const ExternalOdometryReadOptions& options) {
  const std::string format = formatOf(path, options.format);
  if (format == "bag" || format == "mcap") {
    if (options.topic.empty()) throw core::Error("external odometry: a bag needs a topic");
    if (format == "bag") return readBagTrajectory(path, options.topic);
    if (!options.read_mcap) {
      throw core::Error("external odometry: " + path +
                        " is a ROS 2 bag (MCAP), whose messages dcl::ros decodes "
                        "(read it with read_mcap = ros2::readMcapTrajectory)");
    }
    return options.read_mcap(path, options.topic);
  }
  if (format != "tum" && format != "kitti") {
    throw core::Error("external odometry: unknown format '" + format +
                      "' (expected tum, kitti, bag, mcap or auto)");
  }
  std::optional<std::string> times;
  if (!options.times.empty()) times = options.times;
  return readPoses(path, parsePoseFormat(format), times);
}

}  // namespace dcl::io
