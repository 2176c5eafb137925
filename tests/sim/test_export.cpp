// Exporting a simulated dataset: KITTI folders and ROS1 bags that our readers
// and Debian's Python rosbag read back, equal to the regenerated scans, and
// byte-identical when exported twice.

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <dcl/io/file.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/io/scan_source.hpp>
#include <dcl/ros/ros2_bag.hpp>
#include <dcl/ros/ros2_messages.hpp>
#include <dcl/sim/export.hpp>
#include <dcl/sim/sim_source.hpp>

#include "dataset_test_util.hpp"

namespace dcl::sim {
namespace {

namespace fs = std::filesystem;

/// The cloud with only what a KITTI .bin keeps: x y z intensity.
core::PointCloud kittiChannels(core::PointCloud cloud) {
  cloud.time.clear();
  cloud.ring.clear();
  return cloud;
}

/// The number of lines Debian's Python rosbag prints for `bag` (tests/io/read_bag.py).
std::size_t pythonMessageCount(const std::string& bag) {
  const char* custom = std::getenv("DCL_ROS_PYTHON");
  const std::string command =
      fmt::format("'{}' '{}/tests/io/read_bag.py' '{}'", custom ? custom : "/usr/bin/python3",
                  DCL_SOURCE_DIR, bag);
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return 0;
  std::size_t lines = 0;
  for (int c = std::fgetc(pipe); c != EOF; c = std::fgetc(pipe)) lines += c == '\n';
  EXPECT_EQ(::pclose(pipe), 0) << command;
  return lines;
}

class ExportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::freshDir();
    spec_ = writeSimDataset((dir_ / "sim").string(), test::tinyPreset(7, 3));
    sources_ = openDatasetScans(spec_);
  }

  fs::path dir_;
  io::DatasetSpec spec_;
  std::vector<std::unique_ptr<io::ScanSource>> sources_;
};

TEST_F(ExportTest, KittiFoldersHoldTheRegeneratedScans) {
  std::size_t reported = 0;
  const ExportResult result =
      exportDataset(spec_, (dir_ / "kitti").string(), {}, [&](std::size_t done, std::size_t total) {
        EXPECT_EQ(total, 6u);
        reported = done;
      });
  EXPECT_EQ(result.scans, 6u);
  EXPECT_EQ(reported, 6u);
  EXPECT_GT(result.bytes, result.points * io::kKittiRecordBytes);
  EXPECT_FALSE(result.dataset.sim);
  ASSERT_EQ(result.dataset.robots.size(), 2u);
  EXPECT_EQ(result.dataset.robots[1].scans.type, io::ScanSourceType::kitti);
  EXPECT_TRUE(fs::exists(dir_ / "kitti/b/velodyne/000002.bin"));
  const auto exported = io::openScanSource(result.dataset, 1);
  ASSERT_EQ(exported->size(), 3u);
  std::size_t points = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(exported->stamp(i), sources_[1]->stamp(i));
    EXPECT_TRUE(test::sameCloud(exported->scan(i), kittiChannels(sources_[1]->scan(i))));
    points += exported->scan(i).size() + io::openScanSource(result.dataset, 0)->scan(i).size();
  }
  EXPECT_EQ(points, result.points);
  // Ground truth: KITTI poses beside the scans, TUM copied byte for byte.
  const core::Trajectory gt = io::readGroundTruth(spec_, 1);
  const core::Trajectory kitti = io::readKittiPoses((dir_ / "kitti/b/poses.txt").string());
  EXPECT_TRUE(kitti.pose(2).isApprox(gt.pose(2), 1e-12));
  EXPECT_EQ(io::readFile((dir_ / "kitti/b/ground_truth.tum").string()),
            io::readFile(spec_.resolve(spec_.robots[1].ground_truth)));
}

TEST_F(ExportTest, KittiExportIsByteIdenticalTwice) {
  (void)exportDataset(spec_, (dir_ / "one").string());
  // The second export regenerates from an independently read dataset.
  (void)exportDataset(io::readDataset((dir_ / "sim").string()), (dir_ / "two").string());
  for (const char* file : {"a/velodyne/000000.bin", "b/velodyne/000002.bin", "a/times.txt"}) {
    SCOPED_TRACE(file);
    EXPECT_EQ(io::readFile((dir_ / "one" / file).string()),
              io::readFile((dir_ / "two" / file).string()));
  }
}

TEST_F(ExportTest, BagsHoldScansWithEveryChannelAndGroundTruth) {
  const ExportResult result =
      exportDataset(spec_, (dir_ / "bag").string(), {.format = ExportFormat::bag});
  EXPECT_EQ(result.dataset.robots[0].scans.type, io::ScanSourceType::bag);
  const std::string bag = (dir_ / "bag/a/scans.bag").string();
  const auto exported = io::openScanSource(result.dataset, 0);
  ASSERT_EQ(exported->size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(exported->stamp(i), sources_[0]->stamp(i), 1e-6);
    EXPECT_TRUE(test::sameCloud(exported->scan(i), sources_[0]->scan(i)));
  }
  const core::Trajectory gt = io::readBagTrajectory(bag, "/ground_truth");
  const core::Trajectory expected = io::readGroundTruth(spec_, 0);
  ASSERT_EQ(gt.size(), expected.size());
  EXPECT_NEAR(gt.stamp(2) - 1.0e9, expected.stamp(2), 1e-6);
  EXPECT_TRUE(gt.pose(2).isApprox(expected.pose(2), 1e-12));
  // An independent reader: 3 clouds and 3 odometry messages.
  EXPECT_EQ(pythonMessageCount(bag), 6u);
}

TEST_F(ExportTest, Ros2BagsHoldScansWithEveryChannelAndGroundTruth) {
  const ExportResult result =
      exportDataset(spec_, (dir_ / "mcap").string(), {.format = ExportFormat::mcap});
  EXPECT_EQ(result.dataset.robots[0].scans.type, io::ScanSourceType::mcap);
  EXPECT_EQ(result.dataset.robots[0].scans.file, "a/scans.mcap");
  const std::string bag = (dir_ / "mcap/a/scans.mcap").string();
  const auto exported = openRobotScans(result.dataset, 0);  // as the dataset.yaml says
  ASSERT_EQ(exported->size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(exported->stamp(i), sources_[0]->stamp(i), 1e-6);
    EXPECT_TRUE(test::sameCloud(exported->scan(i), sources_[0]->scan(i)));
  }
  const core::Trajectory gt = ros2::readMcapTrajectory(bag, "/ground_truth");
  const core::Trajectory expected = io::readGroundTruth(spec_, 0);
  ASSERT_EQ(gt.size(), expected.size());
  EXPECT_NEAR(gt.stamp(2) - 1.0e9, expected.stamp(2), 1e-6);
  EXPECT_TRUE(gt.pose(2).isApprox(expected.pose(2), 1e-12));
  EXPECT_TRUE(io::McapReader(bag).indexed());
}

TEST(ExportImu, BagsCarryEachScansImuReadingAsAnOrientation) {
  // Robots with IMUs: each scan's reading of up goes on /imu before the scan,
  // as a sensor_msgs/Imu whose orientation reads as that up again.
  const fs::path dir = test::freshDir();
  Preset preset = test::tinyPreset(7, 3);
  preset.imu = true;
  const io::DatasetSpec spec = writeSimDataset((dir / "sim").string(), preset);
  const auto source = openRobotScans(spec, 0);
  ASSERT_TRUE(source->up(2).has_value());
  (void)exportDataset(spec, (dir / "bag").string(), {.format = ExportFormat::bag});
  const std::vector<io::BagTopic> topics = io::listBagTopics((dir / "bag/a/scans.bag").string());
  const auto imu = std::find_if(topics.begin(), topics.end(),
                                [](const io::BagTopic& t) { return t.name == "/imu"; });
  ASSERT_NE(imu, topics.end()) << io::describeTopics(topics);
  EXPECT_EQ(imu->type, "sensor_msgs/Imu");
  EXPECT_EQ(imu->messages, 3u);
  // Debian's rosbag decodes them from the definition the bag stores.
  EXPECT_EQ(pythonMessageCount((dir / "bag/a/scans.bag").string()), 9u);
  (void)exportDataset(spec, (dir / "mcap").string(), {.format = ExportFormat::mcap});
  io::McapReader reader((dir / "mcap/a/scans.mcap").string());
  std::vector<std::uint16_t> imu_channels;
  for (const io::McapChannel& c : reader.channels()) {
    if (c.topic == "/imu") imu_channels.push_back(c.id);
  }
  ASSERT_EQ(imu_channels.size(), 1u);
  const auto messages = reader.messages(imu_channels);
  ASSERT_EQ(messages.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    const msg::Imu m = ros2::decode<msg::Imu>(reader.read(messages[i]).data);
    EXPECT_NEAR(m.header.stamp - 1.0e9, source->stamp(i), 1e-6);
    const auto up = msg::upInLidar(m, Eigen::Matrix3d::Identity());
    ASSERT_TRUE(up.has_value());
    EXPECT_LT((*up - *source->up(i)).norm(), 1e-12) << i;
  }
  // Read back as the exported dataset.yaml says (its imu_topic), both bags
  // level each scan with the reading the simulated robot had.
  for (const char* format : {"bag", "mcap"}) {
    const io::DatasetSpec exported = io::readDataset((dir / format).string());
    EXPECT_EQ(exported.robots[0].scans.imu_topic, "/imu") << format;
    const auto scans = openRobotScans(exported, 0);
    ASSERT_EQ(scans->size(), 3u);
    for (std::size_t i = 0; i < 3; ++i) {
      ASSERT_TRUE(scans->up(i).has_value()) << format << " " << i;
      EXPECT_LT((*scans->up(i) - *source->up(i)).norm(), 1e-12) << format << " " << i;
    }
  }
}

TEST(ExportFormatNames, ParseBothWays) {
  EXPECT_EQ(parseExportFormat("kitti"), ExportFormat::kitti);
  EXPECT_EQ(parseExportFormat(toString(ExportFormat::bag)), ExportFormat::bag);
  EXPECT_EQ(parseExportFormat(toString(ExportFormat::mcap)), ExportFormat::mcap);
  EXPECT_FALSE(parseExportFormat("pcd"));
}

}  // namespace
}  // namespace dcl::sim
