// readCloud / writeCloud: dispatch by extension, conversions between the
// formats, and the real PCD and PLY copies of the same two scans.

#include <filesystem>

#include <gtest/gtest.h>

#include <dcl/io/cloud_file.hpp>

#include "cloud_test_util.hpp"

namespace dcl::io {
namespace {

using test::contains;
using test::fileError;

const std::string kScans = test::dataDir() + "/lidar_scans";

TEST(CloudFileTest, FormatFollowsTheExtensionInAnyCase) {
  EXPECT_EQ(cloudFormatOf("a/b/000001.bin"), CloudFormat::kKittiBin);
  EXPECT_EQ(cloudFormatOf("scan.PCD"), CloudFormat::kPcd);
  EXPECT_EQ(cloudFormatOf("map.v2.Ply"), CloudFormat::kPly);
  EXPECT_FALSE(cloudFormatOf("scan.xyz"));
  EXPECT_FALSE(cloudFormatOf("ply"));
  EXPECT_FALSE(cloudFormatOf("scan.pcd.gz"));
}

TEST(CloudFileTest, UnknownExtensionsAreNamed) {
  const auto dir = test::freshDir("cloud_unknown");
  const std::string path = (dir / "scan.las").string();
  test::writeBytes(path, "x");
  const std::string msg = fileError([&] { readCloud(path); });
  EXPECT_TRUE(contains(msg, path + ": unknown point-cloud extension '.las'"));
  EXPECT_TRUE(contains(msg, ".bin, .pcd or .ply"));
  const std::string bare = (dir / "scan").string();
  EXPECT_TRUE(contains(fileError([&] { writeCloud(bare, test::fullCloud(3)); }),
                       bare + ": unknown point-cloud extension ''"));
  EXPECT_FALSE(std::filesystem::exists(bare));
}

TEST(CloudFileTest, RoundTripsThroughEveryFormatAndEncoding) {
  const auto dir = test::freshDir("cloud_round_trip");
  const core::PointCloud cloud = test::fullCloud(50);
  for (const std::string name : {"a.pcd", "a.ply", "A.PLY"}) {
    for (bool ascii : {false, true}) {
      SCOPED_TRACE(name + (ascii ? " ascii" : " binary"));
      const std::string path = (dir / name).string();
      writeCloud(path, cloud, {.ascii = ascii});
      EXPECT_TRUE(test::sameCloud(readCloud(path), cloud));
      const std::string head = test::readBytes(path).substr(0, 400);
      EXPECT_EQ(ascii, head.find("DATA ascii\n") != std::string::npos ||
                           head.find("format ascii 1.0\n") != std::string::npos);
    }
  }
  const std::string bin = (dir / "a.bin").string();
  writeCloud(bin, cloud);
  core::PointCloud kitti = cloud;
  kitti.time.clear();
  kitti.ring.clear();
  EXPECT_TRUE(test::sameCloud(readCloud(bin), kitti));
  EXPECT_EQ(readCloud(bin, {.drop_nan = true}).size(), cloud.size() - 1);
}

TEST(CloudFileTest, ConvertsARealKittiScanLosslessly) {
  const auto dir = test::freshDir("cloud_convert");
  const std::string original = kScans + "/kitti_00/velodyne/000094.bin";
  const core::PointCloud scan = readCloud(original);
  writeCloud((dir / "s.pcd").string(), scan);
  writeCloud((dir / "s.ply").string(), readCloud((dir / "s.pcd").string()));
  writeCloud((dir / "s.bin").string(), readCloud((dir / "s.ply").string()));
  EXPECT_EQ(test::readBytes(dir / "s.bin"), test::readBytes(original));
}

TEST(CloudFileTest, ThePcdAndPlyPairsHoldTheSameScans) {
  // small_gicp's PLY files are CloudCompare re-saves of fast_gicp's PCD files.
  const std::vector<std::pair<std::string, std::string>> pairs = {
      {"hdl_outdoor_pair_fast_gicp/251370668.pcd", "small_gicp_pair/target.ply"},
      {"hdl_outdoor_pair_fast_gicp/251371071.pcd", "small_gicp_pair/source.ply"}};
  for (const auto& [pcd, ply] : pairs) {
    SCOPED_TRACE(pcd);
    const core::PointCloud a = readCloud(kScans + "/" + pcd);
    const core::PointCloud b = readCloud(kScans + "/" + ply);
    ASSERT_EQ(a.size(), b.size());
    Eigen::AlignedBox3f box_a, box_b;
    for (const auto& p : a.points) box_a.extend(p);
    for (const auto& p : b.points) box_b.extend(p);
    EXPECT_TRUE(box_a.min() == box_b.min() && box_a.max() == box_b.max());
    EXPECT_TRUE(test::sameCloud(a, b));  // point for point, bit for bit
  }
}

TEST(CloudFileTest, ReaderErrorsPassThrough) {
  const auto dir = test::freshDir("cloud_errors");
  for (const std::string name : {"e.bin", "e.pcd", "e.ply"}) {
    const std::string path = (dir / name).string();
    test::writeBytes(path, "");
    EXPECT_TRUE(contains(fileError([&] { readCloud(path); }), path + ": byte 0: empty file"));
  }
}

}  // namespace
}  // namespace dcl::io
