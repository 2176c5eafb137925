// An external front-end's recorded poses: TUM and KITTI files and ROS1 bag
// topics read by io, ROS 2 bags (MCAP) by dcl::ros's reader handed in; the
// format given or found by the file's extension.

#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/external_odometry.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/ros/ros2_bag.hpp>

namespace dcl::io {
namespace {

std::string data(const std::string& relative) {
  return std::string(DCL_DATA_DIR) + "/" + relative;
}

double poseError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return core::logSE3(a.inverse() * b).norm();
}

/// True when both trajectories hold the same stamps and poses.
bool same(const core::Trajectory& a, const core::Trajectory& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a.stamp(i) != b.stamp(i) || !a.pose(i).isApprox(b.pose(i))) return false;
  }
  return true;
}

TEST(ExternalOdometryFile, ReadsTumKittiAndBagFilesByFormatOrExtension) {
  const std::string tum = data("trajectories/evo/freiburg1_xyz-groundtruth.txt");
  EXPECT_TRUE(same(readExternalOdometry(tum), readTumPoses(tum)));  // "auto": tum
  const std::string kitti = data("trajectories/evo/KITTI_00_gt.txt");
  const std::string times = data("trajectories/evo/KITTI_00_gt_times.txt");
  EXPECT_TRUE(same(readExternalOdometry(kitti, {.format = "kitti", .times = times}),
                   readKittiPoses(kitti, times)));
  const std::string bag = data("rosbags/evo_ROS_example.bag");
  const core::Trajectory read = readExternalOdometry(bag, {.topic = "/groundtruth"});  // by .bag
  EXPECT_EQ(read.size(), 12765u);
  EXPECT_TRUE(same(read, readBagTrajectory(bag, "/groundtruth")));
}

TEST(ExternalOdometryFile, ReadsOdometryAndPoseStampedFromAnMcapBag) {
  // The real bag's poses written as a ROS 2 bag, read back by extension and by format.
  const core::Trajectory bag =
      readBagTrajectory(data("rosbags/evo_ROS_example.bag"), "/groundtruth");
  const std::string mcap = (std::filesystem::path(::testing::TempDir()) /
                            ("external_" + std::to_string(::getpid()) + ".mcap"))
                               .string();
  ros2::McapBagWriter writer(mcap);
  for (std::size_t i = 0; i < 200; ++i) {
    writer.writeOdometry("/odom", bag.stamp(i), bag.pose(i), "world", "base_link");
    writer.writePose("/pose", bag.stamp(i), bag.pose(i), "world");
  }
  writer.close();
  for (const char* topic : {"/odom", "pose"}) {
    SCOPED_TRACE(topic);
    // format "auto": by the .mcap extension
    ExternalOdometryReadOptions options{.topic = topic, .read_mcap = &ros2::readMcapTrajectory};
    const core::Trajectory read = readExternalOdometry(mcap, options);
    ASSERT_EQ(read.size(), 200u);
    EXPECT_NEAR(read.stamp(150), bag.stamp(150), 1e-9);
    EXPECT_LT(poseError(read.pose(150), bag.pose(150)), 1e-9);
    const std::string renamed = mcap + ".renamed";
    std::filesystem::copy_file(mcap, renamed, std::filesystem::copy_options::overwrite_existing);
    options.format = "mcap";
    EXPECT_EQ(readExternalOdometry(renamed, options).size(), 200u);
    std::filesystem::remove(renamed);
  }
  // Without dcl::ros's reader an MCAP file is refused, not misread.
  EXPECT_THROW((void)readExternalOdometry(mcap, {.topic = "/odom"}), core::Error);
  std::filesystem::remove(mcap);
}

TEST(ExternalOdometryFile, RejectsUnusableSources) {
  const std::string bag = data("rosbags/evo_ROS_example.bag");
  EXPECT_THROW((void)readExternalOdometry(bag), core::Error);  // a bag needs a topic
  EXPECT_THROW((void)readExternalOdometry(bag, {.format = "csv"}), core::Error);
  EXPECT_THROW((void)readExternalOdometry(data("no_such_file.txt"), {.format = "tum"}),
               core::FileError);
}

}  // namespace
}  // namespace dcl::io
