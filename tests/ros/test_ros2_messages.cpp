// ROS 2 messages on the wire: our encoder and decoder against each other, and
// against Foxglove's independent implementation of ROS 2's CDR (read by a
// Node.js script; scripts/setup installs the packages into the build); and
// decoding damaged bytes only ever ends in core::Error.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/point_cloud2.hpp>
#include <dcl/ros/ros2_messages.hpp>

#include "../common/kitti_test_data.hpp"
#include "imu_test_messages.hpp"

namespace dcl::ros2 {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

/// Stamps whose fractions are exact in binary, so that seconds and
/// nanoseconds read the same in both directions.
constexpr double kStamp = 1317384506.25;

Eigen::Isometry3d pose(double x, double y, double z, double yaw, double pitch, double roll) {
  return core::makePose(Eigen::Vector3d(x, y, z),
                        Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                           Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                           Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX())));
}

PointCloud2 cloudMessage() {
  // Every 50th point of a real KITTI scan, with its intensities.
  const core::PointCloud scan = test::kittiScan(0);
  core::PointCloud few;
  for (std::size_t i = 0; i < scan.size(); i += 50) {
    few.points.push_back(scan.points[i]);
    few.intensity.push_back(scan.intensity[i]);
  }
  return toPointCloud2(few, {kStamp, "velodyne"});
}

Odometry odometryMessage() {
  Odometry m;
  m.header = {kStamp + 0.5, "odom"};
  m.child_frame_id = "base_link";
  m.pose = pose(12.5, -3.25, 0.75, 0.3, -0.02, 0.01);
  for (int i = 0; i < 6; ++i) {
    m.pose_covariance(i, i) = 0.01 * (i + 1);
    m.twist_covariance(i, i) = 0.001 * (i + 1);
  }
  m.pose_covariance(0, 1) = m.pose_covariance(1, 0) = 0.002;
  m.linear_velocity = {8.5, 0.1, -0.05};
  m.angular_velocity = {0.01, -0.02, 0.4};
  return m;
}

Imu imuMessage() {
  return test::imuMessage(kStamp + 0.25);
}

Imu imuWithoutOrientation() {
  return test::imuWithoutOrientation(kStamp + 0.25);
}

Path pathMessage() {
  Path m;
  m.header = {kStamp, "map"};
  for (int i = 0; i < 3; ++i) {
    m.poses.push_back({{kStamp + 0.125 * i, "map"}, pose(2.0 * i, 0.5 * i, 0.0, 0.1 * i, 0, 0)});
  }
  return m;
}

TFMessage tfMessage() {
  TFMessage m;
  m.transforms.resize(2);
  m.transforms[0].header = {kStamp, "map"};
  m.transforms[0].child_frame_id = "a/odom";
  m.transforms[0].transform = pose(100, 50, 1, 1.2, 0.01, -0.01);
  m.transforms[1].header = {kStamp, "a/odom"};
  m.transforms[1].child_frame_id = "a/base_link";
  m.transforms[1].transform = pose(3, 4, 0, -0.5, 0, 0);
  return m;
}

MarkerArray markerMessage() {
  Marker loops;
  loops.header = {kStamp, "map"};
  loops.ns = "inter_robot_loops";
  loops.id = 7;
  loops.type = Marker::kLineList;
  loops.scale = {0.2, 0.0, 0.0};
  loops.color = {0.1F, 0.8F, 0.3F, 1.0F};
  loops.lifetime = 0.5;
  loops.points = {{0, 0, 0}, {10, 5, 0.5}, {20, 0, 1}, {25, -5, 1}};
  loops.colors = {{1, 0, 0, 1}, {0, 0, 1, 1}, {1, 0, 0, 1}, {0, 0.5F, 0.5F, 1}};
  loops.text = "a-b";
  Marker clear;
  clear.header = {kStamp, "map"};
  clear.action = Marker::kDeleteAll;
  MarkerArray m;
  m.markers = {clear, loops};
  return m;
}

// ---- the values as Foxglove's reader returns them ----

json time(double seconds) {
  const double whole = std::floor(seconds);
  return {{"sec", static_cast<std::int64_t>(whole)},
          {"nanosec", static_cast<std::int64_t>(std::llround((seconds - whole) * 1e9))}};
}
json toJson(const Header& h) {
  return {{"stamp", time(h.stamp)}, {"frame_id", h.frame_id}};
}
json xyz(const Eigen::Vector3d& v) {
  return {{"x", v.x()}, {"y", v.y()}, {"z", v.z()}};
}
json quaternion(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  return {{"x", q.x()}, {"y", q.y()}, {"z", q.z()}, {"w", q.w()}};
}
json toJson(const Eigen::Isometry3d& T) {
  return {{"position", xyz(T.translation())}, {"orientation", quaternion(T)}};
}
json covariance(const Eigen::Matrix<double, 6, 6>& m) {
  json out = json::array();
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) out.push_back(m(r, c));
  return out;
}
json color(const ColorRGBA& c) {
  return {{"r", c.r}, {"g", c.g}, {"b", c.b}, {"a", c.a}};
}

json toJson(const PointCloud2& m) {
  json fields = json::array();
  for (const auto& f : m.fields) {
    fields.push_back(
        {{"name", f.name}, {"offset", f.offset}, {"datatype", f.datatype}, {"count", f.count}});
  }
  return {{"header", toJson(m.header)}, {"height", m.height},    {"width", m.width},
          {"fields", fields},           {"is_bigendian", false}, {"point_step", m.point_step},
          {"row_step", m.row_step},     {"data", m.data},        {"is_dense", m.is_dense}};
}
json toJson(const Odometry& m) {
  return {{"header", toJson(m.header)},
          {"child_frame_id", m.child_frame_id},
          {"pose", {{"pose", toJson(m.pose)}, {"covariance", covariance(m.pose_covariance)}}},
          {"twist",
           {{"twist", {{"linear", xyz(m.linear_velocity)}, {"angular", xyz(m.angular_velocity)}}},
            {"covariance", covariance(m.twist_covariance)}}}};
}
json toJson(const Imu& m) {
  json out = test::imuFieldsJson(m);
  out["header"] = toJson(m.header);
  return out;
}
json toJson(const Path& m) {
  json poses = json::array();
  for (const auto& p : m.poses)
    poses.push_back({{"header", toJson(p.header)}, {"pose", toJson(p.pose)}});
  return {{"header", toJson(m.header)}, {"poses", poses}};
}
json toJson(const TFMessage& m) {
  json transforms = json::array();
  for (const auto& t : m.transforms) {
    transforms.push_back({{"header", toJson(t.header)},
                          {"child_frame_id", t.child_frame_id},
                          {"transform",
                           {{"translation", xyz(t.transform.translation())},
                            {"rotation", quaternion(t.transform)}}}});
  }
  return {{"transforms", transforms}};
}
json toJson(const MarkerArray& m) {
  json markers = json::array();
  for (const auto& k : m.markers) {
    json points = json::array(), colors = json::array();
    for (const auto& p : k.points) points.push_back(xyz(p));
    for (const auto& c : k.colors) colors.push_back(color(c));
    markers.push_back(
        {{"header", toJson(k.header)},
         {"ns", k.ns},
         {"id", k.id},
         {"type", k.type},
         {"action", k.action},
         {"pose", toJson(k.pose)},
         {"scale", xyz(k.scale)},
         {"color", color(k.color)},
         {"lifetime", time(k.lifetime)},
         {"frame_locked", k.frame_locked},
         {"points", points},
         {"colors", colors},
         {"texture_resource", ""},
         {"texture", {{"header", toJson(Header{})}, {"format", ""}, {"data", json::array()}}},
         {"uv_coordinates", json::array()},
         {"text", k.text},
         {"mesh_resource", ""},
         {"mesh_file", {{"filename", ""}, {"data", json::array()}}},
         {"mesh_use_embedded_materials", false}});
  }
  return {{"markers", markers}};
}

// ---- equality of what we decode with what was encoded ----

void expectSame(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, const std::string& what) {
  EXPECT_TRUE(a.matrix().isApprox(b.matrix(), 1e-12)) << what;
}
void expectSame(const Header& a, const Header& b) {
  EXPECT_EQ(a.stamp, b.stamp);
  EXPECT_EQ(a.frame_id, b.frame_id);
}
void expectSame(const PointCloud2& a, const PointCloud2& b) {
  expectSame(a.header, b.header);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.width, b.width);
  ASSERT_EQ(a.fields.size(), b.fields.size());
  for (std::size_t i = 0; i < a.fields.size(); ++i) {
    EXPECT_EQ(a.fields[i].name, b.fields[i].name);
    EXPECT_EQ(a.fields[i].offset, b.fields[i].offset);
    EXPECT_EQ(a.fields[i].datatype, b.fields[i].datatype);
    EXPECT_EQ(a.fields[i].count, b.fields[i].count);
  }
  EXPECT_EQ(a.point_step, b.point_step);
  EXPECT_EQ(a.row_step, b.row_step);
  EXPECT_EQ(a.data, b.data);
  EXPECT_EQ(a.is_dense, b.is_dense);
}
void expectSame(const Odometry& a, const Odometry& b) {
  expectSame(a.header, b.header);
  EXPECT_EQ(a.child_frame_id, b.child_frame_id);
  expectSame(a.pose, b.pose, "pose");
  EXPECT_EQ(a.pose_covariance, b.pose_covariance);
  EXPECT_EQ(a.linear_velocity, b.linear_velocity);
  EXPECT_EQ(a.angular_velocity, b.angular_velocity);
  EXPECT_EQ(a.twist_covariance, b.twist_covariance);
}
void expectSame(const Imu& a, const Imu& b) {
  expectSame(a.header, b.header);
  test::expectSameImuFields(a, b);
}
void expectSame(const Path& a, const Path& b) {
  expectSame(a.header, b.header);
  ASSERT_EQ(a.poses.size(), b.poses.size());
  for (std::size_t i = 0; i < a.poses.size(); ++i) {
    expectSame(a.poses[i].header, b.poses[i].header);
    expectSame(a.poses[i].pose, b.poses[i].pose, "pose " + std::to_string(i));
  }
}
void expectSame(const TFMessage& a, const TFMessage& b) {
  ASSERT_EQ(a.transforms.size(), b.transforms.size());
  for (std::size_t i = 0; i < a.transforms.size(); ++i) {
    expectSame(a.transforms[i].header, b.transforms[i].header);
    EXPECT_EQ(a.transforms[i].child_frame_id, b.transforms[i].child_frame_id);
    expectSame(a.transforms[i].transform, b.transforms[i].transform, "transform");
  }
}
void expectSame(const MarkerArray& a, const MarkerArray& b) {
  ASSERT_EQ(a.markers.size(), b.markers.size());
  for (std::size_t i = 0; i < a.markers.size(); ++i) {
    const Marker &x = a.markers[i], &y = b.markers[i];
    expectSame(x.header, y.header);
    EXPECT_EQ(x.ns, y.ns);
    EXPECT_EQ(x.id, y.id);
    EXPECT_EQ(x.type, y.type);
    EXPECT_EQ(x.action, y.action);
    expectSame(x.pose, y.pose, "marker pose");
    EXPECT_EQ(x.scale, y.scale);
    EXPECT_EQ(x.color, y.color);
    EXPECT_EQ(x.lifetime, y.lifetime);
    EXPECT_EQ(x.frame_locked, y.frame_locked);
    EXPECT_EQ(x.points, y.points);
    EXPECT_EQ(x.colors, y.colors);
    EXPECT_EQ(x.text, y.text);
  }
}

template <class M>
void expectRoundTrip(const M& m) {
  const std::vector<std::uint8_t> bytes = encode(m);
  ASSERT_GE(bytes.size(), 4u);
  EXPECT_EQ(bytes[0], 0x00);  // CDR, little-endian
  EXPECT_EQ(bytes[1], 0x01);
  expectSame(decode<M>(bytes), m);
}

TEST(Ros2Messages, EachMessageReadsBackAsWritten) {
  expectRoundTrip(cloudMessage());
  expectRoundTrip(odometryMessage());
  expectRoundTrip(imuMessage());
  expectRoundTrip(imuWithoutOrientation());
  expectRoundTrip(pathMessage());
  expectRoundTrip(tfMessage());
  expectRoundTrip(markerMessage());
}

TEST(Ros2Messages, TypeNamesAreRos2s) {
  EXPECT_EQ(typeName<PointCloud2>(), "sensor_msgs::msg::dds_::PointCloud2_");
  EXPECT_EQ(typeName<Odometry>(), "nav_msgs::msg::dds_::Odometry_");
  EXPECT_EQ(typeName<Imu>(), "sensor_msgs::msg::dds_::Imu_");
  EXPECT_EQ(typeName<Path>(), "nav_msgs::msg::dds_::Path_");
  EXPECT_EQ(typeName<TFMessage>(), "tf2_msgs::msg::dds_::TFMessage_");
  EXPECT_EQ(typeName<MarkerArray>(), "visualization_msgs::msg::dds_::MarkerArray_");
}

TEST(Ros2Messages, ACloudsPointsReadAsTheScan) {
  const PointCloud2 m = decode<PointCloud2>(encode(cloudMessage()));
  const core::PointCloud cloud = io::decodePointCloud2(m.view(), m.header.stamp, true);
  const core::PointCloud scan = test::kittiScan(0);
  ASSERT_EQ(cloud.size(), (scan.size() + 49) / 50);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_EQ(cloud.points[i], scan.points[50 * i]) << i;
    ASSERT_EQ(cloud.intensity[i], scan.intensity[50 * i]) << i;
  }
}

TEST(Ros2Messages, ACloudOfNoPointsReadsEmptyAtOnce) {
  // Width 0 and four billion rows: nothing to walk through (row after empty row was).
  PointCloud2 m = cloudMessage();
  m.width = 0;
  m.height = 4000000000u;
  m.data.clear();
  const PointCloud2 read = decode<PointCloud2>(encode(m));
  EXPECT_EQ(io::decodePointCloud2(read.view(), read.header.stamp, true).size(), 0u);
}

TEST(Ros2Messages, BigEndianBytesReadAlike) {
  // An odometry written big-endian by hand: the header says CDR_BE, every
  // number swapped (strings and octets are not).
  const Odometry m = odometryMessage();
  std::vector<std::uint8_t> le = encode(m);
  std::vector<std::uint8_t> be = {0x00, 0x00, 0x00, 0x00};
  std::size_t at = 4;
  const auto swapNext = [&](std::size_t n) {
    for (std::size_t k = 0; k < n; ++k) be.push_back(le[at + n - 1 - k]);
    at += n;
  };
  const auto copyNext = [&](std::size_t n) {
    be.insert(be.end(), le.begin() + static_cast<long>(at), le.begin() + static_cast<long>(at + n));
    at += n;
  };
  const auto string = [&](const std::string& s) {
    swapNext(4);
    copyNext(s.size() + 1);
    while ((at - 4) % 4 != 0) copyNext(1);
  };
  swapNext(4);  // sec
  swapNext(4);  // nanosec
  string(m.header.frame_id);
  string(m.child_frame_id);
  while ((at - 4) % 8 != 0) copyNext(1);
  while (at < le.size()) swapNext(8);  // 7 + 36 + 6 + 36 doubles
  expectSame(decode<Odometry>(be), m);
}

template <class M>
void expectOnlyErrors(const M& m, std::mt19937& rng) {
  const std::vector<std::uint8_t> bytes = encode(m);
  for (std::size_t n = 0; n < bytes.size(); n += std::max<std::size_t>(1, bytes.size() / 400)) {
    const std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<long>(n));
    EXPECT_THROW(decode<M>(cut), core::Error) << n << " of " << bytes.size() << " bytes";
  }
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<std::uint8_t> damaged = bytes;
    for (int k = 0; k < 8; ++k) damaged[rng() % damaged.size()] = static_cast<std::uint8_t>(rng());
    try {
      (void)decode<M>(damaged);
    } catch (const core::Error&) {
    }
  }
}

TEST(Ros2Messages, DamagedBytesEndInAnErrorNamingTheType) {
  std::mt19937 rng(30);
  expectOnlyErrors(cloudMessage(), rng);
  expectOnlyErrors(odometryMessage(), rng);
  expectOnlyErrors(imuMessage(), rng);
  expectOnlyErrors(pathMessage(), rng);
  expectOnlyErrors(tfMessage(), rng);
  expectOnlyErrors(markerMessage(), rng);
  try {
    (void)decode<Odometry>(std::vector<std::uint8_t>{0x00, 0x01, 0x00, 0x00, 0x05});
    FAIL() << "accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("nav_msgs::msg::dds_::Odometry_"), std::string::npos)
        << e.what();
  }
  // XCDR2 is not what ROS 2 writes.
  std::vector<std::uint8_t> xcdr2 = encode(odometryMessage());
  xcdr2[1] = 0x07;
  EXPECT_THROW(decode<Odometry>(xcdr2), core::Error);
}

TEST(Ros2Messages, AZeroOrientationIsRefused) {
  Odometry m = odometryMessage();
  std::vector<std::uint8_t> bytes = encode(m);
  // The orientation's four doubles follow the position's three, after the
  // header and child_frame_id (8-aligned): find them by value.
  const Eigen::Quaterniond q(m.pose.rotation());
  double w = q.w();
  std::uint8_t pattern[8];
  std::memcpy(pattern, &w, 8);
  const auto at = std::search(bytes.begin(), bytes.end(), pattern, pattern + 8);
  ASSERT_NE(at, bytes.end());
  std::fill(at - 24, at + 8, 0);
  EXPECT_THROW(decode<Odometry>(bytes), core::Error);
}

TEST(Ros2Messages, AnImusOrientationIsCheckedOnlyWhenItIsAnEstimate) {
  // A zero orientation said to be an estimate is refused, naming the field;
  // marked -1 (no estimate), it reads as it came.
  Imu m = imuWithoutOrientation();
  m.orientation_covariance(0, 0) = 1e-6;
  try {
    (void)decode<Imu>(encode(m));
    FAIL() << "accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("sensor_msgs/Imu orientation"), std::string::npos)
        << e.what();
  }
  const Imu bare = decode<Imu>(encode(imuWithoutOrientation()));
  EXPECT_FALSE(bare.hasOrientation());
  EXPECT_EQ(bare.orientation.coeffs(), Eigen::Vector4d::Zero());
}

TEST(Ros2Messages, AnImuReadsUpInTheLidarFrame) {
  // An IMU pitched 5 deg nose down and rolled 2 deg, turned 90 deg about z in
  // the LiDAR frame: up in the LiDAR frame is the world's z seen from the LiDAR.
  const Eigen::Matrix3d R_world_imu =
      (Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(5.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const Eigen::Matrix3d R_lidar_imu =
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Imu m = imuMessage();
  m.orientation = Eigen::Quaterniond(R_world_imu);
  const Eigen::Matrix3d R_world_lidar = R_world_imu * R_lidar_imu.transpose();
  const Eigen::Vector3d expected = R_world_lidar.transpose() * Eigen::Vector3d::UnitZ();
  const std::optional<Eigen::Vector3d> up = msg::upInLidar(decode<Imu>(encode(m)), R_lidar_imu);
  ASSERT_TRUE(up.has_value());
  EXPECT_LT((*up - expected).norm(), 1e-12);
  // Its yaw does not matter.
  m.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(2.0, Eigen::Vector3d::UnitZ())) *
                  Eigen::Quaterniond(R_world_imu);
  EXPECT_LT((*msg::upInLidar(m, R_lidar_imu) - expected).norm(), 1e-12);
  // No orientation, no reading: the acceleration holds the vehicle's own too.
  EXPECT_FALSE(msg::upInLidar(imuWithoutOrientation(), R_lidar_imu).has_value());
  // The message a player sends for a reading of up reads as that reading.
  const Eigen::Vector3d tilted = Eigen::Vector3d(0.05, -0.02, 1.0).normalized();
  const Imu played = decode<Imu>(encode(msg::imuOfUp(tilted, 1e-6, {kStamp, "a/lidar"})));
  EXPECT_LT((*msg::upInLidar(played, Eigen::Matrix3d::Identity()) - tilted).norm(), 1e-12);
  EXPECT_EQ(played.angular_velocity_covariance(0, 0), -1.0);
  EXPECT_EQ(played.linear_acceleration_covariance(0, 0), -1.0);
}

// ---- against Foxglove's implementation ----

template <class M>
void writePair(const fs::path& dir, const std::string& name, const std::string& type, const M& m) {
  const std::vector<std::uint8_t> bytes = encode(m);
  std::ofstream(dir / (name + ".cdr"), std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  std::ofstream(dir / (name + ".json")) << json{{"type", type}, {"message", toJson(m)}}.dump();
}

std::vector<std::uint8_t> readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

template <class M>
void expectTheirsReadAsOurs(const fs::path& dir, const std::string& name, const M& m) {
  SCOPED_TRACE(name);
  const std::vector<std::uint8_t> theirs = readBytes(dir / (name + ".foxglove.cdr"));
  ASSERT_FALSE(theirs.empty());
  expectSame(decode<M>(theirs), m);
  EXPECT_EQ(theirs, encode(m)) << "the same values, other bytes";
}

TEST(Ros2Messages, FoxglovesImplementationReadsOursAndWeReadTheirs) {
  const fs::path modules = DCL_NODE_MODULES;
  ASSERT_TRUE(fs::exists(modules / "@foxglove" / "rosmsg2-serialization"))
      << modules << " lacks Foxglove's packages: scripts/setup installs them";
  const fs::path dir =
      fs::path(::testing::TempDir()) / ("dcl_ros2_crosscheck_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  writePair(dir, "cloud", "sensor_msgs/PointCloud2", cloudMessage());
  writePair(dir, "odometry", "nav_msgs/Odometry", odometryMessage());
  writePair(dir, "imu", "sensor_msgs/Imu", imuMessage());
  writePair(dir, "imu_bare", "sensor_msgs/Imu", imuWithoutOrientation());
  writePair(dir, "path", "nav_msgs/Path", pathMessage());
  writePair(dir, "tf", "tf2_msgs/TFMessage", tfMessage());
  writePair(dir, "markers", "visualization_msgs/MarkerArray", markerMessage());
  const std::string command = std::string(DCL_NODE) + " " + DCL_SOURCE_DIR +
                              "/tests/ros/ros2_crosscheck.js " + modules.string() + " " +
                              dir.string() + " 2>&1";
  std::string output;
  if (FILE* pipe = ::popen(command.c_str(), "r")) {
    char line[512];
    while (std::fgets(line, sizeof(line), pipe) != nullptr) output += line;
    const int status = ::pclose(pipe);
    ASSERT_EQ(status, 0) << command << "\n" << output;
    std::printf("%s", output.c_str());
  } else {
    FAIL() << "cannot run " << command;
  }
  expectTheirsReadAsOurs(dir, "cloud", cloudMessage());
  expectTheirsReadAsOurs(dir, "odometry", odometryMessage());
  expectTheirsReadAsOurs(dir, "imu", imuMessage());
  expectTheirsReadAsOurs(dir, "imu_bare", imuWithoutOrientation());
  expectTheirsReadAsOurs(dir, "path", pathMessage());
  expectTheirsReadAsOurs(dir, "tf", tfMessage());
  expectTheirsReadAsOurs(dir, "markers", markerMessage());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace dcl::ros2
