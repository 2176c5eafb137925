// KITTI Velodyne .bin scans: the real scans of sequence 00, round trips and
// every way a file can be cut.

#include <filesystem>

#include <gtest/gtest.h>

#include <dcl/io/kitti_scan.hpp>

#include "cloud_test_util.hpp"

namespace dcl::io {
namespace {

using test::contains;
using test::fileError;

const std::string kScanDir = test::dataDir() + "/lidar_scans/kitti_00/velodyne";

TEST(KittiScanTest, ReadsEveryRealScanWithSaneValues) {
  std::size_t scans = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kScanDir)) {
    SCOPED_TRACE(entry.path().string());
    const core::PointCloud cloud = readKittiScan(entry.path().string());
    ++scans;
    EXPECT_EQ(cloud.size(), entry.file_size() / 16);
    EXPECT_GT(cloud.size(), 100000u);  // an HDL-64E sweep
    ASSERT_TRUE(cloud.hasIntensity());
    EXPECT_FALSE(cloud.hasTime());
    EXPECT_FALSE(cloud.hasRing());
    float max_range = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      ASSERT_TRUE(cloud.points[i].allFinite()) << "point " << i;
      max_range = std::max(max_range, cloud.points[i].norm());
      ASSERT_GE(cloud.intensity[i], 0.0f);
      ASSERT_LE(cloud.intensity[i], 1.0f);
    }
    EXPECT_LT(max_range, 130.0f);
    EXPECT_GT(max_range, 50.0f);
  }
  EXPECT_EQ(scans, 10u);
}

TEST(KittiScanTest, FirstScansMatchPublishedCountsAndFirstPoint) {
  const core::PointCloud frame0 = readKittiScan(kScanDir + "/000000.bin");
  EXPECT_EQ(frame0.size(), 124668u);
  EXPECT_EQ(readKittiScan(kScanDir + "/000001.bin").size(), 124605u);
  EXPECT_FLOAT_EQ(frame0.points[0].x(), 52.897941589f);
  EXPECT_FLOAT_EQ(frame0.points[0].y(), 0.022989738f);
  EXPECT_FLOAT_EQ(frame0.points[0].z(), 1.997994542f);
  EXPECT_FLOAT_EQ(frame0.intensity[0], 0.08f);
}

TEST(KittiScanTest, RoundTripKeepsXyzAndIntensityBitForBit) {
  const auto dir = test::freshDir("kitti_round_trip");
  const core::PointCloud real = readKittiScan(kScanDir + "/000005.bin");
  writeKittiScan((dir / "real.bin").string(), real);
  EXPECT_TRUE(test::sameCloud(readKittiScan((dir / "real.bin").string()), real));
  EXPECT_EQ(test::readBytes(dir / "real.bin"), test::readBytes(kScanDir + "/000005.bin"));

  core::PointCloud full = test::fullCloud(10);
  writeKittiScan((dir / "full.bin").string(), full);
  full.time.clear();  // KITTI keeps x y z intensity only
  full.ring.clear();
  EXPECT_TRUE(test::sameCloud(readKittiScan((dir / "full.bin").string()), full));
}

TEST(KittiScanTest, DecodesBytesInMemoryAsItReadsTheFile) {
  const std::string bytes = test::readBytes(kScanDir + "/000094.bin");
  EXPECT_TRUE(
      test::sameCloud(decodeKittiScan(bytes, "memory"), readKittiScan(kScanDir + "/000094.bin")));
  EXPECT_TRUE(contains(fileError([&] { decodeKittiScan(bytes.substr(0, 37), "cut.bin"); }),
                       "cut.bin: byte 32"));
}

TEST(KittiScanTest, WritesZeroIntensityWhenAbsent) {
  const auto dir = test::freshDir("kitti_no_intensity");
  core::PointCloud cloud;
  cloud.points = {{1, 2, 3}, {4, 5, 6}};
  writeKittiScan((dir / "a.bin").string(), cloud);
  const core::PointCloud back = readKittiScan((dir / "a.bin").string());
  EXPECT_EQ(back.intensity, (std::vector<float>{0.0f, 0.0f}));
  EXPECT_EQ(back.points[1], Eigen::Vector3f(4, 5, 6));
}

TEST(KittiScanTest, RejectsEmptyAndInconsistentClouds) {
  const auto dir = test::freshDir("kitti_write_errors");
  const std::string path = (dir / "a.bin").string();
  EXPECT_TRUE(contains(fileError([&] { writeKittiScan(path, core::PointCloud{}); }), path));
  core::PointCloud bad = test::fullCloud(3);
  bad.intensity.pop_back();
  EXPECT_TRUE(contains(fileError([&] { writeKittiScan(path, bad); }), "differ in length"));
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(KittiScanTest, EmptyFileIsAnError) {
  const auto dir = test::freshDir("kitti_empty");
  const std::string path = (dir / "empty.bin").string();
  test::writeBytes(path, "");
  const std::string msg = fileError([&] { readKittiScan(path); });
  EXPECT_TRUE(contains(msg, path));
  EXPECT_TRUE(contains(msg, "empty file"));
}

TEST(KittiScanTest, TruncatedFileNamesThePartialRecord) {
  const auto dir = test::freshDir("kitti_truncated");
  const std::string bytes = test::readBytes(kScanDir + "/000000.bin");
  for (std::size_t cut : {std::size_t{1}, std::size_t{15}, std::size_t{17}, std::size_t{1000},
                          bytes.size() / 2 + 3, bytes.size() - 1}) {
    SCOPED_TRACE(cut);
    const std::string path = (dir / "cut.bin").string();
    test::writeBytes(path, bytes.substr(0, cut));
    const std::string msg = fileError([&] { readKittiScan(path); });
    EXPECT_TRUE(contains(msg, path + ": byte " + std::to_string(cut / 16 * 16) + ":"));
    EXPECT_TRUE(contains(msg, "partial point record: " + std::to_string(cut % 16) + " bytes"));
  }
}

TEST(KittiScanTest, MissingFileIsNamed) {
  const std::string path = kScanDir + "/999999.bin";
  const std::string msg = fileError([&] { readKittiScan(path); });
  EXPECT_TRUE(contains(msg, path));
  EXPECT_TRUE(contains(msg, "no such file"));
}

}  // namespace
}  // namespace dcl::io
