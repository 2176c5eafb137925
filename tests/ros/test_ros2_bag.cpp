// ROS 2 bags (MCAP): ours read back as written, in every layout; and both
// ways against Foxglove's independent implementation (@mcap/core for the
// container, @foxglove/rosmsg2-serialization for the messages; a Node.js
// script, tests/ros/mcap_crosscheck.js), each message compared field by field.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/mcap.hpp>
#include <dcl/ros/ros2_bag.hpp>
#include <dcl/ros/ros2_messages.hpp>

#include "../common/kitti_test_data.hpp"

namespace dcl::ros2 {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

/// Seconds whose fractions are exact in binary and in nanoseconds.
constexpr double kStart = 1317384506.25;

Eigen::Isometry3d pose(double x, double y, double yaw) {
  return core::makePose(Eigen::Vector3d(x, y, 0.5 * x),
                        Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                           Eigen::AngleAxisd(0.01 * x, Eigen::Vector3d::UnitX())));
}

/// A few hundred points of a real KITTI scan, with intensities.
core::PointCloud cloud(std::size_t offset) {
  const core::PointCloud scan = test::kittiScan(0);
  core::PointCloud few;
  for (std::size_t i = offset; i < scan.size(); i += 300) {
    few.points.push_back(scan.points[i]);
    few.intensity.push_back(scan.intensity[i]);
  }
  return few;
}

class Ros2BagTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("dcl_ros2_bag_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  /// Three scans on /points, five Odometry poses on /odom, four PoseStamped on /pose.
  std::string writeBag(const std::string& name, io::McapWriteOptions options = {}) {
    McapBagWriter writer(path(name), options);
    for (std::size_t i = 0; i < 5; ++i) {
      const double t = kStart + 0.125 * static_cast<double>(i);
      if (i < 3) writer.writeCloud("/points", t, cloud(i), "velodyne");
      writer.writeOdometry("/odom", t, pose(i, -0.5 * i, 0.1 * i), "world", "base_link");
      if (i < 4) writer.writePose("pose", t + 0.0625, pose(2.0 * i, 1.0, -0.2 * i), "map");
    }
    writer.close();
    return path(name);
  }

  /// What `command` prints; the test fails when it exits non-zero.
  static std::string run(const std::string& command) {
    std::string output;
    FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
    if (pipe == nullptr) {
      ADD_FAILURE() << "cannot run " << command;
      return {};
    }
    char buffer[65536];
    std::size_t n = 0;
    while ((n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0) output.append(buffer, n);
    EXPECT_EQ(::pclose(pipe), 0) << command << "\n" << output.substr(0, 4000);
    return output;
  }
  static std::string node(const std::string& arguments) {
    const fs::path modules = DCL_NODE_MODULES;
    EXPECT_TRUE(fs::exists(modules / "@mcap" / "core"))
        << modules << " lacks @mcap/core: scripts/setup --npm-prefix installs it";
    return run(fmt::format("{} {}/tests/ros/mcap_crosscheck.js {} {}", DCL_NODE, DCL_SOURCE_DIR,
                           modules.string(), arguments));
  }

  fs::path dir_;
};

void expectSamePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  EXPECT_TRUE(a.isApprox(b, 1e-12)) << a.matrix() << "\n!=\n" << b.matrix();
}

void expectSameCloud(const core::PointCloud& read, const core::PointCloud& written) {
  ASSERT_EQ(read.size(), written.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read.points[i], written.points[i]) << i;
    EXPECT_EQ(read.intensity[i], written.intensity[i]) << i;
  }
}

TEST_F(Ros2BagTest, ReadsWhatItWritesInEveryLayout) {
  struct Layout {
    const char* name;
    io::McapWriteOptions options;
  };
  for (const Layout& layout :
       {Layout{"zstd", {}}, Layout{"lz4", {.compression = io::McapCompression::lz4}},
        Layout{"none", {.compression = io::McapCompression::none, .chunk_size = 2000}},
        Layout{"unchunked", {.chunked = false}}, Layout{"no summary", {.summary = false}}}) {
    SCOPED_TRACE(layout.name);
    const std::string bag = writeBag("bag.mcap", layout.options);
    const auto clouds = readMcapClouds(bag, "points");  // leading '/' optional
    ASSERT_EQ(clouds.size(), 3u);
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_EQ(clouds[i].stamp, kStart + 0.125 * static_cast<double>(i));
      expectSameCloud(clouds[i].cloud, cloud(i));
    }
    const core::Trajectory odom = readMcapTrajectory(bag, "/odom");
    ASSERT_EQ(odom.size(), 5u);
    for (std::size_t i = 0; i < 5; ++i) {
      EXPECT_EQ(odom.stamp(i), kStart + 0.125 * static_cast<double>(i));
      expectSamePose(odom.pose(i), pose(i, -0.5 * i, 0.1 * i));
    }
    const core::Trajectory poses = readMcapTrajectory(bag, "/pose");
    ASSERT_EQ(poses.size(), 4u);
    expectSamePose(poses.pose(3), pose(6.0, 1.0, -0.6));
    EXPECT_EQ(poses.stamp(3), kStart + 0.4375);
  }
}

TEST_F(Ros2BagTest, ListsTopicsAndIsAScanSource) {
  const std::string bag = writeBag("bag.mcap");
  const auto topics = listMcapTopics(bag);
  ASSERT_EQ(topics.size(), 3u);
  EXPECT_EQ(topics[0].name, "/odom");
  EXPECT_EQ(topics[0].type, "nav_msgs/msg/Odometry");
  EXPECT_EQ(topics[0].messages, 5u);
  EXPECT_EQ(topics[1].name, "/points");
  EXPECT_EQ(topics[1].type, "sensor_msgs/msg/PointCloud2");
  EXPECT_EQ(topics[2].name, "pose");
  EXPECT_EQ(topics[2].type, "geometry_msgs/msg/PoseStamped");
  const McapScanSource source(bag, "/points");
  ASSERT_EQ(source.size(), 3u);
  EXPECT_EQ(source.originStamp(), kStart);
  EXPECT_EQ(source.stamp(2), 0.25);
  expectSameCloud(source.scan(2), cloud(2));
  expectSameCloud(source.scan(0), cloud(0));  // backwards: read again from the start
  EXPECT_EQ(source.describe(), "mcap " + bag + " topic /points");
  EXPECT_THROW((void)source.stamp(3), core::Error);
}

TEST_F(Ros2BagTest, WrongTopicsAndDamagedMessagesAreNamed) {
  const std::string bag = writeBag("bag.mcap");
  const auto error = [](auto&& f) {
    try {
      f();
    } catch (const core::FileError& e) {
      return std::string(e.what());
    }
    ADD_FAILURE() << "no core::FileError";
    return std::string();
  };
  std::string msg = error([&] { readMcapClouds(bag, "/nope"); });
  EXPECT_NE(msg.find("topic '/nope': no such topic in the file; its topics: /odom "
                     "(nav_msgs/msg/Odometry), /points"),
            std::string::npos)
      << msg;
  msg = error([&] { readMcapClouds(bag, "/odom"); });
  EXPECT_NE(msg.find("type is nav_msgs/msg/Odometry, expected sensor_msgs/msg/PointCloud2"),
            std::string::npos)
      << msg;
  msg = error([&] { readMcapTrajectory(bag, "/points"); });
  EXPECT_NE(msg.find("expected nav_msgs/msg/Odometry or geometry_msgs/msg/PoseStamped"),
            std::string::npos)
      << msg;
  // Bytes that are no PointCloud2, in a well-formed file.
  const std::string broken = path("broken.mcap");
  io::McapWriter writer(broken);
  const auto schema = writer.addSchema("sensor_msgs/msg/PointCloud2", "ros2msg",
                                       messageDefinition("sensor_msgs/msg/PointCloud2"));
  const auto channel = writer.addChannel(schema, "/points", "cdr");
  writer.write(channel, 1, 1, encode(toPointCloud2(cloud(0), {1.0, "a"})));
  writer.write(channel, 2, 2, std::vector<std::uint8_t>{0, 1, 0, 0, 7, 7, 7});
  writer.close();
  McapCloudReader reader(broken, "/points");
  EXPECT_TRUE(reader.next());
  msg = error([&] { reader.next(); });
  EXPECT_NE(msg.find(broken + ": topic '/points' message 1: sensor_msgs::msg::dds_::PointCloud2_"),
            std::string::npos)
      << msg;
  EXPECT_FALSE(reader.next());
}

// ---- against Foxglove's implementation ----

void expectPoseJson(const json& p, const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  EXPECT_EQ(p["position"]["x"], T.translation().x());
  EXPECT_EQ(p["position"]["y"], T.translation().y());
  EXPECT_EQ(p["position"]["z"], T.translation().z());
  EXPECT_EQ(p["orientation"]["x"], q.x());
  EXPECT_EQ(p["orientation"]["y"], q.y());
  EXPECT_EQ(p["orientation"]["z"], q.z());
  EXPECT_EQ(p["orientation"]["w"], q.w());
}

void expectHeaderJson(const json& h, double stamp, const std::string& frame) {
  EXPECT_EQ(h["stamp"]["sec"], static_cast<std::int64_t>(stamp));
  EXPECT_EQ(h["stamp"]["nanosec"], std::llround((stamp - std::floor(stamp)) * 1e9));
  EXPECT_EQ(h["frame_id"], frame);
}

/// The messages as Foxglove decoded them, against what writeBag wrote.
void expectFoxglovesReading(const json& messages) {
  ASSERT_EQ(messages.size(), 12u);
  std::size_t clouds = 0, odoms = 0, poses = 0;
  for (const json& m : messages) {
    EXPECT_EQ(m["encoding"], "cdr");
    const json& v = m["message"];
    if (m["topic"] == "/points") {
      SCOPED_TRACE(fmt::format("cloud {}", clouds));
      const double t = kStart + 0.125 * static_cast<double>(clouds);
      EXPECT_EQ(m["schema"], "sensor_msgs/msg/PointCloud2");
      EXPECT_EQ(m["log_time"], std::to_string(std::llround(t * 1e9)));
      expectHeaderJson(v["header"], t, "velodyne");
      const PointCloud2 ours = toPointCloud2(cloud(clouds), {t, "velodyne"});
      EXPECT_EQ(v["height"], ours.height);
      EXPECT_EQ(v["width"], ours.width);
      ASSERT_EQ(v["fields"].size(), ours.fields.size());
      for (std::size_t f = 0; f < ours.fields.size(); ++f) {
        EXPECT_EQ(v["fields"][f]["name"], ours.fields[f].name);
        EXPECT_EQ(v["fields"][f]["offset"], ours.fields[f].offset);
        EXPECT_EQ(v["fields"][f]["datatype"], ours.fields[f].datatype);
        EXPECT_EQ(v["fields"][f]["count"], ours.fields[f].count);
      }
      EXPECT_EQ(v["is_bigendian"], false);
      EXPECT_EQ(v["point_step"], ours.point_step);
      EXPECT_EQ(v["row_step"], ours.row_step);
      EXPECT_EQ(v["data"].get<std::vector<std::uint8_t>>(), ours.data);
      EXPECT_EQ(v["is_dense"], true);
      ++clouds;
    } else if (m["topic"] == "/odom") {
      SCOPED_TRACE(fmt::format("odometry {}", odoms));
      const double i = static_cast<double>(odoms);
      EXPECT_EQ(m["schema"], "nav_msgs/msg/Odometry");
      expectHeaderJson(v["header"], kStart + 0.125 * i, "world");
      EXPECT_EQ(v["child_frame_id"], "base_link");
      expectPoseJson(v["pose"]["pose"], pose(i, -0.5 * i, 0.1 * i));
      EXPECT_EQ(v["pose"]["covariance"], std::vector<double>(36, 0.0));
      EXPECT_EQ(v["twist"]["twist"]["linear"]["x"], 0.0);
      ++odoms;
    } else {
      SCOPED_TRACE(fmt::format("pose {}", poses));
      const double i = static_cast<double>(poses);
      EXPECT_EQ(m["topic"], "pose");
      EXPECT_EQ(m["schema"], "geometry_msgs/msg/PoseStamped");
      expectHeaderJson(v["header"], kStart + 0.125 * i + 0.0625, "map");
      expectPoseJson(v["pose"], pose(2.0 * i, 1.0, -0.2 * i));
      ++poses;
    }
  }
  EXPECT_EQ(clouds, 3u);
  EXPECT_EQ(odoms, 5u);
  EXPECT_EQ(poses, 4u);
}

TEST_F(Ros2BagTest, FoxglovesMcapReadsOurs) {
  for (const auto compression :
       {io::McapCompression::zstd, io::McapCompression::lz4, io::McapCompression::none}) {
    SCOPED_TRACE(std::string(io::toString(compression)));
    const std::string bag = writeBag("ours.mcap", {.compression = compression, .chunk_size = 3000});
    const json read = json::parse(node("read " + bag));
    SCOPED_TRACE("indexed reader");
    expectFoxglovesReading(read["indexed"]);
    SCOPED_TRACE("stream reader");
    expectFoxglovesReading(read["stream"]);
  }
}

json headerJson(double stamp, const std::string& frame) {
  return {{"stamp",
           {{"sec", static_cast<std::int64_t>(stamp)},
            {"nanosec", std::llround((stamp - std::floor(stamp)) * 1e9)}}},
          {"frame_id", frame}};
}

json poseJson(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  const Eigen::Vector3d t = T.translation();
  return {{"position", {{"x", t.x()}, {"y", t.y()}, {"z", t.z()}}},
          {"orientation", {{"x", q.x()}, {"y", q.y()}, {"z", q.z()}, {"w", q.w()}}}};
}

/// The values of writeBag, as Foxglove's writer takes them.
json foxgloveSpec(const std::string& compression, bool chunked) {
  json messages = json::array();
  const json zeros = std::vector<double>(36, 0.0);
  for (std::size_t i = 0; i < 5; ++i) {
    const double t = kStart + 0.125 * static_cast<double>(i);
    const auto ns = [](double s) { return std::to_string(std::llround(s * 1e9)); };
    if (i < 3) {
      const PointCloud2 c = toPointCloud2(cloud(i), {t, "velodyne"});
      json fields = json::array();
      for (const auto& f : c.fields) {
        fields.push_back(
            {{"name", f.name}, {"offset", f.offset}, {"datatype", f.datatype}, {"count", f.count}});
      }
      messages.push_back({{"topic", "/points"},
                          {"type", "sensor_msgs/PointCloud2"},
                          {"log_time", ns(t)},
                          {"message",
                           {{"header", headerJson(t, "velodyne")},
                            {"height", c.height},
                            {"width", c.width},
                            {"fields", fields},
                            {"is_bigendian", false},
                            {"point_step", c.point_step},
                            {"row_step", c.row_step},
                            {"data", c.data},
                            {"is_dense", true}}}});
    }
    const double x = static_cast<double>(i);
    messages.push_back(
        {{"topic", "/odom"},
         {"type", "nav_msgs/Odometry"},
         {"log_time", ns(t)},
         {"message",
          {{"header", headerJson(t, "world")},
           {"child_frame_id", "base_link"},
           {"pose", {{"pose", poseJson(pose(x, -0.5 * x, 0.1 * x))}, {"covariance", zeros}}},
           {"twist",
            {{"twist",
              {{"linear", {{"x", 0.0}, {"y", 0.0}, {"z", 0.0}}},
               {"angular", {{"x", 0.0}, {"y", 0.0}, {"z", 0.0}}}}},
             {"covariance", zeros}}}}}});
    if (i < 4) {
      messages.push_back({{"topic", "pose"},
                          {"type", "geometry_msgs/PoseStamped"},
                          {"log_time", ns(t + 0.0625)},
                          {"message",
                           {{"header", headerJson(t + 0.0625, "map")},
                            {"pose", poseJson(pose(2.0 * x, 1.0, -0.2 * x))}}}});
    }
  }
  return {{"compression", compression}, {"chunked", chunked}, {"messages", messages}};
}

TEST_F(Ros2BagTest, WeReadFoxglovesMcap) {
  struct Layout {
    const char* compression;
    bool chunked;
  };
  for (const Layout& layout :
       {Layout{"zstd", true}, Layout{"lz4", true}, Layout{"", true}, Layout{"", false}}) {
    SCOPED_TRACE(fmt::format("'{}' chunked {}", layout.compression, layout.chunked));
    const std::string spec = path("spec.json");
    std::ofstream(spec) << foxgloveSpec(layout.compression, layout.chunked).dump();
    const std::string theirs = path("theirs.mcap");
    node(fmt::format("write {} {}", spec, theirs));
    ASSERT_TRUE(fs::exists(theirs));
    const std::string ours = writeBag("ours.mcap");
    EXPECT_EQ(io::McapReader(theirs).indexed(), layout.chunked);
    const auto clouds = readMcapClouds(theirs, "/points");
    const auto expected = readMcapClouds(ours, "/points");
    ASSERT_EQ(clouds.size(), expected.size());
    for (std::size_t i = 0; i < clouds.size(); ++i) {
      EXPECT_EQ(clouds[i].stamp, expected[i].stamp);
      expectSameCloud(clouds[i].cloud, cloud(i));
    }
    for (const char* topic : {"/odom", "pose"}) {
      const core::Trajectory a = readMcapTrajectory(theirs, topic);
      const core::Trajectory b = readMcapTrajectory(ours, topic);
      ASSERT_EQ(a.size(), b.size());
      for (std::size_t i = 0; i < a.size(); ++i) {
        EXPECT_EQ(a.stamp(i), b.stamp(i));
        expectSamePose(a.pose(i), b.pose(i));
      }
    }
    EXPECT_EQ(listMcapTopics(theirs)[1].type, "sensor_msgs/msg/PointCloud2");
  }
}

}  // namespace
}  // namespace dcl::ros2
