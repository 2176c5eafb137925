#pragma once

/// The poses of another front-end (LIO-SAM, FAST-LIO2, a ground-truth system,
/// ...) as recorded: a TUM or KITTI pose file, or a topic of a ROS1 bag or a
/// ROS 2 bag in MCAP (nav_msgs/Odometry, geometry_msgs/PoseStamped). They are
/// the trajectory T_world_body that odometry::ExternalOdometry replays.
///
/// A ROS 2 bag's messages are CDR, which dcl::ros decodes, and dcl::ros sits
/// above io: its reader, ros2::readMcapTrajectory, is handed in.

#include <string>

#include <dcl/core/trajectory.hpp>

namespace dcl::io {

/// Reads the poses of `topic` in the ROS 2 bag (MCAP) at `path`: ros2::readMcapTrajectory.
using McapTrajectoryReader = core::Trajectory (*)(const std::string& path,
                                                  const std::string& topic);

/// How readExternalOdometry reads its file.
struct ExternalOdometryReadOptions {
  /// "tum", "kitti", "bag" (ROS1), "mcap" (ROS 2) or "auto" (by extension: .bag, .mcap, else tum)
  std::string format = "auto";
  std::string times = "";  ///< kitti: the times file (one stamp a line); default none
  std::string topic = "";  ///< bag, mcap: the nav_msgs/Odometry or PoseStamped topic; default none
  /// mcap: the ROS 2 bag reader (ros2::readMcapTrajectory); default none, an MCAP file is refused
  McapTrajectoryReader read_mcap = nullptr;
};

/// The trajectory T_world_body recorded at `path`, read as `options` say: a
/// TUM or KITTI file by readPoses, a ROS1 bag topic by readBagTrajectory, an
/// MCAP topic by `options.read_mcap`. Throws core::FileError naming the file
/// when it cannot be read, and core::Error for an unknown format, a bag without
/// a topic, or an MCAP file without a reader.
core::Trajectory readExternalOdometry(const std::string& path,
                                      const ExternalOdometryReadOptions& options = {});

}  // namespace dcl::io
