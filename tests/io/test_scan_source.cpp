// Scan sources: a KITTI folder of real HDL-64 scans, a bag written by Python's
// rosbag (make_test_bag.py), and bags written by io::BagWriter read back by our
// reader and by Debian's Python rosbag (read_bag.py), an independent reader.

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/bag_writer.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/io/scan_source.hpp>

#include "cloud_test_util.hpp"

namespace dcl::io {
namespace {

using test::contains;
using test::fileError;

const std::string kVelodyne = test::dataDir() + "/lidar_scans/kitti_00/velodyne";

/// Debian's interpreter, which has python3-rosbag; DCL_ROS_PYTHON overrides it.
std::string python() {
  const char* custom = std::getenv("DCL_ROS_PYTHON");
  return custom ? custom : "/usr/bin/python3";
}

/// Runs `command`; its stdout, or a test failure.
std::string runCommand(const std::string& command) {
  std::string out;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) {
    ADD_FAILURE() << "cannot run " << command;
    return out;
  }
  char buffer[4096];
  while (std::fgets(buffer, sizeof(buffer), pipe) != nullptr) out += buffer;
  EXPECT_EQ(::pclose(pipe), 0) << command;
  return out;
}

/// A times file of `n` stamps 0.1 s apart (from 0.05).
std::string writeTimes(const test::TempDir& dir, int n) {
  std::string text;
  for (int i = 0; i < n; ++i) text += fmt::format("{}\n", 0.05 + 0.1 * i);
  return dir.write("times.txt", text);
}

TEST(KittiScanSource, ReadsRealScansByIndex) {
  test::TempDir dir;
  const KittiScanSource source(kVelodyne, writeTimes(dir, 6));
  ASSERT_EQ(source.size(), 6u);
  EXPECT_DOUBLE_EQ(source.stamp(3), 0.35);
  for (std::size_t i : {5u, 0u, 2u}) {
    const core::PointCloud scan = source.scan(i);
    EXPECT_GT(scan.size(), 100000u);
    EXPECT_TRUE(test::sameCloud(scan, readKittiScan(fmt::format("{}/{:06}.bin", kVelodyne, i))));
  }
  EXPECT_THROW((void)source.scan(6), core::Error);
  EXPECT_THROW((void)source.stamp(6), core::Error);
}

TEST(KittiScanSource, ParallelReadsMatchSerialOnes) {
  test::TempDir dir;
  const KittiScanSource source(kVelodyne, writeTimes(dir, 6));
  std::vector<core::PointCloud> parallel(6);
  std::vector<std::thread> threads;
  for (std::size_t i = 0; i < 6; ++i)
    threads.emplace_back([&, i] { parallel[i] = source.scan(i); });
  for (auto& t : threads) t.join();
  for (std::size_t i = 0; i < 6; ++i) EXPECT_TRUE(test::sameCloud(parallel[i], source.scan(i)));
}

TEST(KittiScanSource, RejectsMissingScansAndBadTimes) {
  test::TempDir dir;
  // Frames 0-5 exist, frame 6 does not.
  EXPECT_TRUE(contains(fileError([&] { KittiScanSource(kVelodyne, writeTimes(dir, 7)); }),
                       "000006.bin is missing"));
  const std::string decreasing = dir.write("dec.txt", "0.0\n0.2\n0.1\n");
  EXPECT_TRUE(contains(fileError([&] { KittiScanSource(kVelodyne, decreasing); }), ":3:"));
  // Repeated and NaN stamps went into the outputs' trajectories as they were.
  const std::string repeated = dir.write("rep.txt", "0.0\n0.1\n0.1\n");
  EXPECT_TRUE(contains(fileError([&] { KittiScanSource(kVelodyne, repeated); }),
                       "rep.txt:3: field 't': repeats the stamp 0.1 of line 2"));
  const std::string nan = dir.write("nan.txt", "0.0\nnan\n");
  EXPECT_TRUE(contains(fileError([&] { KittiScanSource(kVelodyne, nan); }),
                       "nan.txt:2: field 't': 'nan' is not finite"));
  const std::string bad = dir.write("bad.txt", "0.0\nzero\n");
  EXPECT_TRUE(contains(fileError([&] { KittiScanSource(kVelodyne, bad); }), "'zero'"));
}

class BagSourceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = test::freshDir("bag_source");
    command_ = fmt::format("'{}' '{}/tests/io/make_test_bag.py' '{}'", python(), DCL_SOURCE_DIR,
                           dir_.string());
    if (std::system(command_.c_str()) == 0) bag_ = (dir_ / "clouds.bag").string();
  }
  void SetUp() override { ASSERT_FALSE(bag_.empty()) << "could not write test bags: " << command_; }

  static inline std::filesystem::path dir_;
  static inline std::string bag_;
  static inline std::string command_;
};

TEST_F(BagSourceTest, RandomAccessByIndexWithRelativeStamps) {
  const BagScanSource source(bag_, "/velodyne_points");
  ASSERT_EQ(source.size(), 3u);
  EXPECT_DOUBLE_EQ(source.originStamp(), 100.5);
  EXPECT_NEAR(source.stamp(2), 0.2, 1e-9);
  // make_test_bag.py: message k has x = k + j/4 for point j.
  for (std::size_t k : {2u, 0u, 1u, 1u, 2u}) {
    const core::PointCloud scan = source.scan(k);
    ASSERT_EQ(scan.size(), 4u);
    EXPECT_EQ(scan.points[1].x(), static_cast<float>(k) + 0.25f);
  }
  EXPECT_THROW((void)source.scan(3), core::Error);
}

TEST_F(BagSourceTest, FactoryOpensKittiAndBagRobotsButNotSimulatedOnes) {
  test::TempDir dir;
  DatasetSpec spec;
  spec.name = "files";
  spec.folder = dir.file("");
  RobotSpec kitti{.name = "a", .scans = {.type = ScanSourceType::kitti}};
  kitti.scans.folder = kVelodyne;  // absolute paths are kept
  kitti.scans.times = "times.txt";
  RobotSpec bag{.name = "b", .scans = {.type = ScanSourceType::bag}};
  bag.scans.file = bag_;
  bag.scans.topic = "velodyne_points";
  spec.robots = {kitti, bag, RobotSpec{.name = "c"}};
  (void)writeTimes(dir, 4);
  EXPECT_EQ(openScanSource(spec, 0)->size(), 4u);
  EXPECT_EQ(openScanSource(spec, 1)->size(), 3u);
  try {
    (void)openScanSource(spec, 2);
    ADD_FAILURE() << "a simulated robot opened as a file source";
  } catch (const core::Error& e) {
    EXPECT_TRUE(contains(e.what(), "robot 'c' has simulated scans"));
  }
  EXPECT_THROW((void)BagScanSource(bag_, "/nope"), core::FileError);
}

/// A cloud with every channel and finite values: point i at (i/4, -i/8, 3 + i/16).
core::PointCloud finiteCloud(std::size_t n) {
  core::PointCloud cloud = test::fullCloud(n);
  cloud.points[1].x() = 0.5f;  // fullCloud puts a NaN here
  return cloud;
}

TEST(BagWriter, CloudsAndOdometryReadBackBitExact) {
  test::TempDir dir;
  const std::string path = dir.file("out/robot.bag");
  const Eigen::Isometry3d T = core::makePose(Eigen::Vector3d(1.5, -2.25, 0.125),
                                             Eigen::Quaterniond(0.9, 0.1, -0.3, 0.2).normalized());
  {
    BagWriter writer(path);
    for (int k = 0; k < 3; ++k) {
      writer.writeCloud("/points", 1000.0 + 0.1 * k, finiteCloud(10 + k), "a/lidar");
      writer.writeOdometry("/ground_truth", 1000.0 + 0.1 * k, T, "world", "a/lidar");
    }
    EXPECT_FALSE(std::filesystem::exists(path));  // only the temporary file until close
    writer.close();
  }
  const auto clouds = readBagClouds(path, "/points");
  ASSERT_EQ(clouds.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(clouds[k].stamp, 1000.0 + 0.1 * k, 1e-9);
    EXPECT_TRUE(test::sameCloud(clouds[k].cloud, finiteCloud(10 + k)));
  }
  const core::Trajectory gt = readBagTrajectory(path, "/ground_truth");
  ASSERT_EQ(gt.size(), 3u);
  EXPECT_TRUE(gt.pose(2).isApprox(T, 1e-12));
}

TEST(BagWriter, DebiansPythonRosbagReadsWhatWeWrite) {
  test::TempDir dir;
  const std::string path = dir.file("robot.bag");
  const core::PointCloud cloud = finiteCloud(7);
  {
    BagWriter writer(path);
    writer.writeCloud("/points", 1234.5, cloud, "lidar");
    writer.writeOdometry("/ground_truth", 1234.5, core::makePose2d(3.0, 4.0, 0.5), "world",
                         "lidar");
    writer.close();
  }
  const std::string out = runCommand(
      fmt::format("'{}' '{}/tests/io/read_bag.py' '{}'", python(), DCL_SOURCE_DIR, path));
  std::istringstream lines(out);
  std::string cloud_line, odom_line;
  std::getline(lines, cloud_line);
  std::getline(lines, odom_line);
  const auto cloud_tokens = splitWhitespace(cloud_line);
  ASSERT_EQ(cloud_tokens.size(), 11u) << cloud_line;
  EXPECT_EQ(cloud_tokens[0], "cloud");
  EXPECT_EQ(cloud_tokens[1], "/points");
  EXPECT_EQ(cloud_tokens[2], "1234.500000000");
  EXPECT_EQ(cloud_tokens[3], "7");
  EXPECT_EQ(cloud_tokens[4], "x:0:7,y:4:7,z:8:7,intensity:12:7,ring:16:4,time:20:7");
  const std::size_t j = 6;  // read_bag.py prints the last point
  const std::vector<double> expected = {cloud.points[j].x(),
                                        cloud.points[j].y(),
                                        cloud.points[j].z(),
                                        cloud.intensity[j],
                                        static_cast<double>(cloud.ring[j]),
                                        cloud.time[j]};
  for (std::size_t k = 0; k < expected.size(); ++k) {
    EXPECT_EQ(parseNumber<double>(cloud_tokens[5 + k]), expected[k]) << cloud_line;
  }
  const auto odom_tokens = splitWhitespace(odom_line);
  ASSERT_EQ(odom_tokens.size(), 12u) << odom_line;
  EXPECT_EQ(odom_tokens[0], "odom");
  EXPECT_EQ(odom_tokens[3], "world");
  EXPECT_EQ(odom_tokens[4], "lidar");
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  const std::vector<double> pose = {3.0, 4.0, 0.0, q.x(), q.y(), q.z(), q.w()};
  for (std::size_t k = 0; k < pose.size(); ++k) {
    EXPECT_NEAR(*parseNumber<double>(odom_tokens[5 + k]), pose[k], 1e-15) << odom_line;
  }
}

TEST(BagWriter, UnclosedWriterLeavesNoFileAndBadStampsAreRefused) {
  test::TempDir dir;
  const std::string path = dir.file("robot.bag");
  {
    BagWriter writer(path);
    writer.writeCloud("/points", 1.0, finiteCloud(3), "lidar");
    EXPECT_TRUE(contains(fileError([&] { writer.writeCloud("/points", 0.0, finiteCloud(3), "l"); }),
                         "not positive"));
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
}

}  // namespace
}  // namespace dcl::io
