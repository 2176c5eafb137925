// ROS1 bags: topic listing and PoseStamped trajectories on evo's real bags;
// PointCloud2 layouts, Odometry and corrupt messages on bags written by
// make_test_bag.py (whose values are mirrored here), also in small uncompressed,
// bz2 and lz4 chunks; truncated, unindexed and randomly corrupted bags.

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <dcl/io/rosbag.hpp>

#include "cloud_test_util.hpp"

namespace dcl::io {
namespace {

using test::contains;
using test::fileError;

const std::string kEvoBag = test::dataDir() + "/rosbags/evo_ROS_example.bag";
const std::string kTfBag = test::dataDir() + "/rosbags/evo_tf_example.bag";

class RosbagTest : public ::testing::Test {
 protected:
  /// Debian's interpreter, which has python3-rosbag; DCL_ROS_PYTHON overrides it.
  static std::string python() {
    const char* custom = std::getenv("DCL_ROS_PYTHON");
    return custom ? custom : "/usr/bin/python3";
  }

  static void SetUpTestSuite() {
    dir_ = test::freshDir("rosbag");
    const std::string command = fmt::format("'{}' '{}/tests/io/make_test_bag.py' '{}'", python(),
                                            DCL_SOURCE_DIR, dir_.string());
    if (std::system(command.c_str()) == 0) bag_ = (dir_ / "clouds.bag").string();
    command_ = command;
  }

  void SetUp() override { ASSERT_FALSE(bag_.empty()) << "could not write test bags: " << command_; }

  /// A copy of the generated bag cut to `bytes`.
  static std::string cutBag(std::size_t bytes) {
    const std::string path = (dir_ / ("cut_" + std::to_string(bytes) + ".bag")).string();
    test::writeBytes(path, test::readBytes(bag_).substr(0, bytes));
    return path;
  }

  /// A generated bag: clouds.bag, or "chunked", "bz2", "lz4".
  static std::string variant(const std::string& name) {
    return (dir_ / ("clouds_" + name + ".bag")).string();
  }

  /// Everything the reader makes of `path`, as text with the path left out:
  /// topics, every cloud (stamp, points, times, rings) and every pose, or the error.
  static std::string contentOf(const std::string& path) {
    std::string out;
    const auto error = [&](const core::FileError& e) {
      std::string what = e.what();
      const std::size_t at = what.find(path);
      if (at != std::string::npos) what.replace(at, path.size(), "BAG");
      out.append("error ").append(what).append("\n");
    };
    for (const BagTopic& t : listBagTopics(path)) {
      out += fmt::format("{} {} {}\n", t.name, t.type, t.messages);
      if (t.type == "sensor_msgs/PointCloud2") {
        BagCloudReader reader(path, t.name);
        for (;;) {
          try {
            const auto c = reader.next();
            if (!c) break;
            out += fmt::format("{} {}:", c->stamp, c->cloud.size());
            for (std::size_t i = 0; i < c->cloud.size(); ++i) {
              const Eigen::Vector3f& p = c->cloud.points[i];
              out += fmt::format(" {} {} {}", p.x(), p.y(), p.z());
              if (c->cloud.hasTime()) out += fmt::format(" t{}", c->cloud.time[i]);
              if (c->cloud.hasRing()) out += fmt::format(" r{}", c->cloud.ring[i]);
            }
            out += "\n";
          } catch (const core::FileError& e) {
            error(e);
          }
        }
      } else if (t.type != "tf2_msgs/TFMessage") {
        try {
          const core::Trajectory trajectory = readBagTrajectory(path, t.name);
          for (std::size_t k = 0; k < trajectory.size(); ++k) {
            const Eigen::Isometry3d& T = trajectory.pose(k);
            out += fmt::format("{} {} {} {}\n", trajectory.stamp(k), T.translation().x(),
                               T.translation().y(), T.linear()(0, 1));
          }
        } catch (const core::FileError& e) {
          error(e);
        }
      }
    }
    return out;
  }

  static const BagTopic* find(const std::vector<BagTopic>& topics, const std::string& name) {
    for (const auto& t : topics) {
      if (t.name == name) return &t;
    }
    return nullptr;
  }

  static inline std::filesystem::path dir_;
  static inline std::string bag_;
  static inline std::string command_;
};

TEST_F(RosbagTest, ListsTheTopicsOfTheGeneratedBag) {
  const auto topics = listBagTopics(bag_);
  EXPECT_EQ(topics.size(), 13u);
  const BagTopic* velodyne = find(topics, "/velodyne_points");
  ASSERT_NE(velodyne, nullptr);
  EXPECT_EQ(velodyne->type, "sensor_msgs/PointCloud2");
  EXPECT_EQ(velodyne->messages, 3u);
  ASSERT_NE(find(topics, "/odom"), nullptr);
  EXPECT_EQ(find(topics, "/odom")->type, "nav_msgs/Odometry");
  ASSERT_NE(find(topics, "pose"), nullptr);
  EXPECT_EQ(find(topics, "pose")->messages, 2u);
}

TEST_F(RosbagTest, ListsTheTopicsOfTheRealBags) {
  const auto topics = listBagTopics(kEvoBag);
  ASSERT_EQ(topics.size(), 3u);
  EXPECT_EQ(topics[0].name, "ORB-SLAM");
  EXPECT_EQ(topics[0].messages, 8362u);
  EXPECT_EQ(topics[1].name, "S-PTAM");
  EXPECT_EQ(topics[1].messages, 5439u);
  EXPECT_EQ(topics[2].name, "groundtruth");
  EXPECT_EQ(topics[2].messages, 12765u);
  for (const auto& t : topics) EXPECT_EQ(t.type, "geometry_msgs/PoseStamped");
  const auto tf = listBagTopics(kTfBag);
  ASSERT_EQ(tf.size(), 2u);
  EXPECT_EQ(tf[0].name, "/tf");
  EXPECT_EQ(tf[0].messages, 517u);
  EXPECT_EQ(tf[1].type, "tf2_msgs/TFMessage");
}

TEST_F(RosbagTest, StreamsVelodyneLikeClouds) {
  BagCloudReader reader(bag_, "/velodyne_points");
  EXPECT_EQ(reader.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(reader.index(), static_cast<std::size_t>(k));
    const auto scan = reader.next();
    ASSERT_TRUE(scan);
    EXPECT_DOUBLE_EQ(scan->stamp, 100 + (500000000 + k * 100000000) * 1e-9);
    const core::PointCloud& c = scan->cloud;
    ASSERT_EQ(c.size(), 4u);
    for (int j = 0; j < 4; ++j) {
      EXPECT_EQ(c.points[j], Eigen::Vector3f(k + j * 0.25f, -j * 0.5f, j * 0.125f));
      EXPECT_EQ(c.intensity[j], 10.0f * j + k);
      EXPECT_EQ(c.ring[j], j);
      EXPECT_EQ(c.time[j], j / 1024.0f);
    }
  }
  EXPECT_FALSE(reader.next());
  EXPECT_EQ(readBagClouds(bag_, "velodyne_points").size(), 3u);  // leading '/' optional
}

TEST_F(RosbagTest, ReadsOrganisedOusterCloudsWithNanosecondTimes) {
  const auto scans = readBagClouds(bag_, "/ouster/points");
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].stamp, 50.0);
  const core::PointCloud& c = scans[0].cloud;
  ASSERT_EQ(c.size(), 6u);
  for (int r = 0; r < 2; ++r) {
    for (int col = 0; col < 3; ++col) {
      const int i = 3 * r + col;
      EXPECT_EQ(c.points[i], Eigen::Vector3f(i, r, col));
      EXPECT_EQ(c.intensity[i], 100.0f + i);
      EXPECT_EQ(c.time[i], static_cast<float>(i * 1000000 * 1e-9));
      EXPECT_EQ(c.ring[i], r);
    }
  }
  const core::PointCloud u8 = readBagClouds(bag_, "/ouster/points_u8_ring")[0].cloud;
  ASSERT_EQ(u8.size(), 2u);
  EXPECT_FALSE(u8.hasIntensity());
  EXPECT_EQ(u8.points[1], Eigen::Vector3f(2, 2, 2));
  EXPECT_EQ(u8.time[1], static_cast<float>(5000000 * 1e-9));
  EXPECT_EQ(u8.ring, (std::vector<std::uint16_t>{60, 61}));
}

TEST_F(RosbagTest, ReadsBigEndianDoublesWithRowPadding) {
  const core::PointCloud c = readBagClouds(bag_, "/f64_big_endian")[0].cloud;
  ASSERT_EQ(c.size(), 4u);
  EXPECT_FALSE(c.hasTime());
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(c.points[i],
              Eigen::Vector3f(static_cast<float>(1000.123456789 + i), static_cast<float>(-2.5 * i),
                              static_cast<float>(0.001 * i)));
    EXPECT_EQ(c.intensity[i], 200.0f + i);
    EXPECT_EQ(c.ring[i], i);
  }
}

TEST_F(RosbagTest, MakesAbsoluteTimestampsRelativeToTheHeader) {
  const auto scans = readBagClouds(bag_, "/hesai/points");
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_DOUBLE_EQ(scans[0].stamp, 1700000000.25);
  const core::PointCloud& c = scans[0].cloud;
  ASSERT_EQ(c.size(), 3u);
  for (int j = 0; j < 3; ++j) {
    EXPECT_NEAR(c.time[j], 0.0005 * j, 1e-6);
    EXPECT_EQ(c.ring[j], 31 - j);
  }
}

TEST_F(RosbagTest, KeepsOrDropsNanPoints) {
  EXPECT_EQ(readBagClouds(bag_, "/with_nan")[0].cloud.size(), 3u);
  const core::PointCloud c = readBagClouds(bag_, "/with_nan", {.drop_nan = true})[0].cloud;
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(4, 5, 6));
}

TEST_F(RosbagTest, CorruptMessagesNameBagTopicAndIndex) {
  struct Corrupt {
    std::string topic, expected;
  };
  for (const Corrupt& c : {
           Corrupt{"short_data", "data holds 20 bytes, height 1 x row_step 32 needs 32"},
           Corrupt{"field_overrun", "field 'z' (offset 14, 4 bytes) overruns point_step 16"},
           Corrupt{"no_x", "no field 'x' among the PointCloud2 fields"},
           Corrupt{"row_step", "row_step 16 is less than width 2 x point_step 16"},
           Corrupt{"bad_datatype", "field 'x': unknown datatype 42"},
       }) {
    SCOPED_TRACE(c.topic);
    const std::string topic = "/corrupt/" + c.topic;
    BagCloudReader reader(bag_, topic);
    ASSERT_TRUE(reader.next());  // the first message is sound
    const std::string msg = fileError([&] { reader.next(); });
    EXPECT_TRUE(contains(msg, bag_ + ": topic '" + topic + "' message 1: " + c.expected));
    EXPECT_FALSE(reader.next());  // the reader moved past the corrupt message
    EXPECT_TRUE(contains(fileError([&] { readBagClouds(bag_, topic); }), "message 1"));
  }
}

TEST_F(RosbagTest, ReadsOdometryAsATrajectory) {
  const core::Trajectory t = readBagTrajectory(bag_, "/odom");
  ASSERT_EQ(t.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(t.stamp(k), 200.0 + k);
    EXPECT_TRUE(t.pose(k).translation().isApprox(Eigen::Vector3d(k, 2.0 * k, 0.5)));
    const Eigen::Matrix3d R(Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitZ()));
    EXPECT_TRUE(t.pose(k).linear().isApprox(R, 1e-12));
  }
}

TEST_F(RosbagTest, ReadsPoseStampedAndNormalisesQuaternions) {
  const core::Trajectory t = readBagTrajectory(bag_, "/pose");  // recorded as "pose"
  ASSERT_EQ(t.size(), 2u);
  EXPECT_DOUBLE_EQ(t.stamp(1), 301.25);
  EXPECT_TRUE(t.pose(1).translation().isApprox(Eigen::Vector3d(-1, 0, 1)));
  EXPECT_TRUE(t.pose(1).linear().isApprox(Eigen::Matrix3d::Identity()));
}

TEST_F(RosbagTest, ReadsTheRealGroundTruth) {
  const core::Trajectory t = readBagTrajectory(kEvoBag, "/groundtruth");
  ASSERT_EQ(t.size(), 12765u);
  EXPECT_DOUBLE_EQ(t.stamp(0), 1502792570 + 283404827 * 1e-9);
  EXPECT_TRUE(t.pose(0).translation().isApprox(
      Eigen::Vector3d(-0.004899939787714927, -0.01775981455685227, -0.013755318406774505)));
  const Eigen::Quaterniond q0(0.9999926388911098, -0.0036862949370505883, -7.802442831383871e-05,
                              0.0010617464008890892);
  EXPECT_TRUE(t.pose(0).linear().isApprox(q0.normalized().toRotationMatrix(), 1e-12));
  EXPECT_DOUBLE_EQ(t.stamp(12764), 1502793459 + 302349567 * 1e-9);
  EXPECT_TRUE(t.pose(12764).translation().isApprox(
      Eigen::Vector3d(-3.3215975657197134, -4.640516510388755, 32.783932900251884)));
  EXPECT_TRUE(t.isSorted());
  EXPECT_EQ(readBagTrajectory(kEvoBag, "S-PTAM").size(), 5439u);
}

TEST_F(RosbagTest, MissingTopicListsTheBagsTopics) {
  const std::string msg = fileError([&] { BagCloudReader(bag_, "/nope"); });
  EXPECT_TRUE(contains(msg, bag_ + ": topic '/nope': no such topic in the bag; its topics: "));
  EXPECT_TRUE(contains(msg, "/odom (nav_msgs/Odometry)"));
  EXPECT_TRUE(contains(fileError([&] { readBagTrajectory(kEvoBag, "/gt"); }),
                       "groundtruth (geometry_msgs/PoseStamped)"));
}

TEST_F(RosbagTest, WrongTopicTypesAreNamed) {
  EXPECT_TRUE(contains(fileError([&] { readBagClouds(bag_, "/odom"); }),
                       bag_ + ": topic '/odom': type is nav_msgs/Odometry, expected "
                              "sensor_msgs/PointCloud2"));
  EXPECT_TRUE(contains(fileError([&] { readBagTrajectory(bag_, "/velodyne_points"); }),
                       "type is sensor_msgs/PointCloud2, expected nav_msgs/Odometry or "
                       "geometry_msgs/PoseStamped or geometry_msgs/PoseWithCovarianceStamped"));
  EXPECT_TRUE(
      contains(fileError([&] { readBagTrajectory(kTfBag, "/tf"); }), "type is tf2_msgs/TFMessage"));
}

TEST_F(RosbagTest, MissingEmptyAndForeignFilesAreErrors) {
  const std::string missing = (dir_ / "none.bag").string();
  EXPECT_TRUE(contains(fileError([&] { listBagTopics(missing); }), missing + ": no such file"));
  const std::string empty = (dir_ / "empty.bag").string();
  test::writeBytes(empty, "");
  EXPECT_TRUE(contains(fileError([&] { listBagTopics(empty); }),
                       empty + ": byte 0: not a ROS1 bag: it does not begin with '#ROSBAG V2.0'"));
  const std::string pcd = test::dataDir() + "/lidar_scans/hdl_outdoor_pair_fast_gicp/251370668.pcd";
  EXPECT_TRUE(contains(fileError([&] { readBagClouds(pcd, "/points"); }),
                       pcd + ": byte 0: not a ROS1 bag"));
  const std::string old = (dir_ / "old.bag").string();
  test::writeBytes(old, "#ROSBAG V1.2\n" + std::string(100, ' '));
  EXPECT_TRUE(
      contains(fileError([&] { listBagTopics(old); }), "bag format '1.2' is not read, only 2.0"));
}

TEST_F(RosbagTest, TruncatedBagsAreErrors) {
  const std::size_t size = test::readBytes(bag_).size();
  struct Cut {
    std::size_t bytes;
    std::string expected;
  };
  const std::string truncated = "truncated: ";
  for (const Cut& cut :
       {Cut{5, "byte 0: not a ROS1 bag"}, Cut{13, "byte 13: the bag holds no records"},
        Cut{100, truncated}, Cut{4200, truncated}, Cut{size / 2, truncated},
        Cut{size - 100, truncated}, Cut{size - 1, truncated}}) {
    SCOPED_TRACE(cut.bytes);
    const std::string path = cutBag(cut.bytes);
    const std::string msg = fileError([&] { listBagTopics(path); });
    EXPECT_TRUE(contains(msg, path + ": ")) << msg;
    EXPECT_TRUE(contains(msg, cut.expected)) << msg;
  }
}

TEST_F(RosbagTest, ReadsChunkedBz2AndLz4BagsAlike) {
  const std::string expected = contentOf(bag_);
  EXPECT_TRUE(contains(expected, "/velodyne_points sensor_msgs/PointCloud2 3"));
  EXPECT_TRUE(contains(expected, "field 'x': unknown datatype 42"));  // errors are content too
  for (const std::string name : {"chunked", "bz2", "lz4"}) {
    SCOPED_TRACE(name);
    EXPECT_EQ(contentOf(variant(name)), expected);
  }
}

TEST_F(RosbagTest, ReadsABagWhoseRecordingStoppedBeforeItsIndex) {
  // What an interrupted recording leaves: whole chunks, no index, index_pos 0.
  std::string bytes = test::readBytes(variant("lz4"));
  const std::size_t field = bytes.find("index_pos=");
  ASSERT_NE(field, std::string::npos);
  std::uint64_t index_pos = 0;
  std::memcpy(&index_pos, bytes.data() + field + 10, 8);
  ASSERT_LT(index_pos, bytes.size());
  bytes.resize(index_pos);
  std::memset(bytes.data() + field + 10, 0, 8);
  const std::string path = (dir_ / "unindexed.bag").string();
  test::writeBytes(path, bytes);
  EXPECT_EQ(contentOf(path), contentOf(bag_));
  // Its last chunk cut short is an error that says what happened.
  test::writeBytes(path, bytes.substr(0, bytes.size() - 10));
  EXPECT_TRUE(contains(fileError([&] { listBagTopics(path); }), "the recording may have been "));
}

TEST_F(RosbagTest, ACompressedChunkMayNotClaimAGigabyteFromAFewBytes) {
  // A chunk's header says how large it is once decompressed; a claim far past
  // what its compressed bytes can hold is refused before any is decompressed.
  std::string bytes = test::readBytes(variant("bz2"));
  const std::size_t field = bytes.find("size=", bytes.find("compression=bz2"));
  ASSERT_NE(field, std::string::npos);
  const std::uint32_t claimed = 600'000'000;
  std::memcpy(bytes.data() + field + 5, &claimed, 4);
  const std::string path = (dir_ / "bomb.bag").string();
  test::writeBytes(path, bytes);
  const std::string msg = fileError([&] { listBagTopics(path); });
  EXPECT_TRUE(contains(msg, "chunk says 600000000 bytes from ")) << msg;
  EXPECT_TRUE(contains(msg, "compressed: corrupt (at most 1000 times)")) << msg;
}

TEST_F(RosbagTest, CorruptedBagsAreErrorsOrReadNeverACrash) {
  // 50 random bytes changed, as a damaged disk or transfer does: every copy is
  // read through; each either reads or fails with a FileError naming the bag.
  std::mt19937 random(29);
  int errors = 0, read = 0;
  for (const std::string& source :
       {bag_, variant("chunked"), variant("bz2"), variant("lz4"), kTfBag, kEvoBag}) {
    const std::string original = test::readBytes(source);
    const int copies = source == kEvoBag ? 15 : 40;
    for (int copy = 0; copy < copies; ++copy) {
      std::string bytes = original;
      std::uniform_int_distribution<std::size_t> at(0, bytes.size() - 1);
      for (int k = 0; k < 50; ++k) bytes[at(random)] = static_cast<char>(random() & 0xff);
      const std::string path = (dir_ / "damaged.bag").string();
      test::writeBytes(path, bytes);
      SCOPED_TRACE(source + " copy " + std::to_string(copy));
      try {
        const std::string content = contentOf(path);
        ++read;
        if (contains(content, "error ")) ++errors;
      } catch (const core::FileError& e) {
        ++errors;
        EXPECT_TRUE(contains(e.what(), path + ": ")) << e.what();
      }
    }
  }
  RecordProperty("damaged_copies_failing", errors);
  EXPECT_GT(errors, 100);  // most damage is found
  EXPECT_GT(read, 0);      // and damage inside a message body can pass
}

}  // namespace
}  // namespace dcl::io
