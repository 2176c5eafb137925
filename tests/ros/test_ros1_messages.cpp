// ROS 1 messages: our encoder and decoder against each other, and against ROS
// 1's own serialiser, genpy, with the message classes of Debian's
// python3-*-msgs (ros1_crosscheck.py; scripts/setup installs them): it reads
// our bytes to the values we wrote, we read its bytes to the values it was
// given, and its types' names, MD5 sums and definitions are ours. Damaged
// bytes only ever end in core::Error, before any allocation they could not
// fill.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <new>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/point_cloud2.hpp>
#include <dcl/ros/ros1_messages.hpp>

#include "../common/kitti_test_data.hpp"
#include "imu_test_messages.hpp"

// The largest allocation made while a LargestAllocation lives (the test's
// own thread and any other; none but the decoder's run meanwhile).
namespace {
std::atomic<bool> g_tracking{false};
std::atomic<std::size_t> g_largest{0};
}  // namespace

// Out of line: inlined, the compiler would see free() given what new returned.
[[gnu::noinline]] void* operator new(std::size_t n) {
  if (g_tracking.load(std::memory_order_relaxed)) {
    std::size_t seen = g_largest.load(std::memory_order_relaxed);
    while (n > seen && !g_largest.compare_exchange_weak(seen, n)) {
    }
  }
  if (void* p = std::malloc(n > 0 ? n : 1)) return p;
  throw std::bad_alloc();
}
[[gnu::noinline]] void operator delete(void* p) noexcept {
  std::free(p);
}
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace dcl::ros1 {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using msg::ColorRGBA;
using msg::Header;
using msg::Imu;
using msg::Marker;
using msg::MarkerArray;
using msg::Odometry;
using msg::Path;
using msg::PointCloud2;
using msg::PoseStamped;
using msg::TFMessage;

class LargestAllocation {
 public:
  LargestAllocation() {
    g_largest = 0;
    g_tracking = true;
  }
  ~LargestAllocation() { g_tracking = false; }
  LargestAllocation(const LargestAllocation&) = delete;
  LargestAllocation& operator=(const LargestAllocation&) = delete;
  [[nodiscard]] std::size_t bytes() const { return g_largest; }
};

/// Stamps whose fractions are exact in binary, so that seconds and
/// nanoseconds read the same in both directions.
constexpr double kStamp = 1317384506.25;

Eigen::Isometry3d pose(double x, double y, double z, double yaw, double pitch, double roll) {
  return core::makePose(Eigen::Vector3d(x, y, z),
                        Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                           Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                           Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX())));
}

/// Every `step`th point of a real KITTI scan, with its intensities.
PointCloud2 cloudMessage(std::size_t step = 50) {
  const core::PointCloud scan = test::kittiScan(0);
  core::PointCloud few;
  for (std::size_t i = 0; i < scan.size(); i += step) {
    few.points.push_back(scan.points[i]);
    few.intensity.push_back(scan.intensity[i]);
  }
  return msg::toPointCloud2(few, {kStamp, "velodyne"});
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
  m.twist_covariance(5, 3) = -0.0004;
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

PoseStamped poseMessage() {
  return {{kStamp + 0.75, "map"}, pose(-7.5, 2.0, 1.5, -2.8, 0.05, 0.02)};
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
  loops.pose = pose(0.5, 0, 0, 0.25, 0, 0);
  loops.scale = {0.2, 0.0, 0.0};
  loops.color = {0.1F, 0.8F, 0.3F, 1.0F};
  loops.lifetime = -1.5;  // a duration: negative ones are ROS 1's too
  loops.frame_locked = true;
  loops.points = {{0, 0, 0}, {10, 5, 0.5}, {20, 0, 1}, {25, -5, 1}};
  loops.colors = {{1, 0, 0, 1}, {0, 0, 1, 1}, {1, 0, 0, 1}, {0, 0.5F, 0.5F, 1}};
  loops.text = "a-b";
  Marker clear;
  clear.header = {kStamp, "map"};
  clear.action = Marker::kDeleteAll;
  clear.lifetime = 2.25;
  MarkerArray m;
  m.markers = {clear, loops};
  return m;
}

// ---- the values as genpy names them ----

json time(double seconds) {
  const double whole = std::floor(seconds);
  return {{"secs", static_cast<std::int64_t>(whole)},
          {"nsecs", static_cast<std::int64_t>(std::llround((seconds - whole) * 1e9))}};
}
json toJson(const Header& h, std::uint32_t seq) {
  return {{"seq", seq}, {"stamp", time(h.stamp)}, {"frame_id", h.frame_id}};
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

json toJson(const PointCloud2& m, std::uint32_t seq) {
  json fields = json::array();
  for (const auto& f : m.fields) {
    fields.push_back(
        {{"name", f.name}, {"offset", f.offset}, {"datatype", f.datatype}, {"count", f.count}});
  }
  return {{"header", toJson(m.header, seq)},
          {"height", m.height},
          {"width", m.width},
          {"fields", fields},
          {"is_bigendian", m.is_bigendian},
          {"point_step", m.point_step},
          {"row_step", m.row_step},
          {"data", m.data},
          {"is_dense", m.is_dense}};
}
json toJson(const Odometry& m, std::uint32_t seq) {
  return {{"header", toJson(m.header, seq)},
          {"child_frame_id", m.child_frame_id},
          {"pose", {{"pose", toJson(m.pose)}, {"covariance", covariance(m.pose_covariance)}}},
          {"twist",
           {{"twist", {{"linear", xyz(m.linear_velocity)}, {"angular", xyz(m.angular_velocity)}}},
            {"covariance", covariance(m.twist_covariance)}}}};
}
json toJson(const Imu& m, std::uint32_t seq) {
  json out = test::imuFieldsJson(m);
  out["header"] = toJson(m.header, seq);
  return out;
}
json toJson(const PoseStamped& m, std::uint32_t seq) {
  return {{"header", toJson(m.header, seq)}, {"pose", toJson(m.pose)}};
}
json toJson(const Path& m, std::uint32_t seq) {
  json poses = json::array();
  for (const auto& p : m.poses) poses.push_back(toJson(p, 0));
  return {{"header", toJson(m.header, seq)}, {"poses", poses}};
}
json toJson(const TFMessage& m, std::uint32_t /*seq*/) {
  json transforms = json::array();
  for (const auto& t : m.transforms) {
    transforms.push_back({{"header", toJson(t.header, 0)},
                          {"child_frame_id", t.child_frame_id},
                          {"transform",
                           {{"translation", xyz(t.transform.translation())},
                            {"rotation", quaternion(t.transform)}}}});
  }
  return {{"transforms", transforms}};
}
json toJson(const MarkerArray& m, std::uint32_t /*seq*/) {
  json markers = json::array();
  for (const auto& k : m.markers) {
    json points = json::array(), colors = json::array();
    for (const auto& p : k.points) points.push_back(xyz(p));
    for (const auto& c : k.colors) colors.push_back(color(c));
    markers.push_back({{"header", toJson(k.header, 0)},
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
                       {"text", k.text},
                       {"mesh_resource", ""},
                       {"mesh_use_embedded_materials", false}});
  }
  return {{"markers", markers}};
}

/// Field by field: the same names, the same lengths, the same values.
void expectSameJson(const json& actual, const json& expected, const std::string& where) {
  if (expected.is_object()) {
    ASSERT_TRUE(actual.is_object()) << where << ": " << actual.dump();
    for (const auto& [key, value] : expected.items()) {
      ASSERT_TRUE(actual.contains(key)) << where << "." << key << " missing";
      expectSameJson(actual[key], value, where + "." + key);
    }
    EXPECT_EQ(actual.size(), expected.size()) << where << ": other fields " << actual.dump();
  } else if (expected.is_array()) {
    ASSERT_TRUE(actual.is_array()) << where << ": " << actual.dump();
    ASSERT_EQ(actual.size(), expected.size()) << where;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      expectSameJson(actual[i], expected[i], where + "[" + std::to_string(i) + "]");
    }
  } else {
    EXPECT_EQ(actual, expected) << where;  // numbers compare by value, whatever their JSON type
  }
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
  EXPECT_EQ(a.is_bigendian, b.is_bigendian);
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
void expectSame(const PoseStamped& a, const PoseStamped& b) {
  expectSame(a.header, b.header);
  expectSame(a.pose, b.pose, "pose");
}
void expectSame(const Path& a, const Path& b) {
  expectSame(a.header, b.header);
  ASSERT_EQ(a.poses.size(), b.poses.size());
  for (std::size_t i = 0; i < a.poses.size(); ++i) expectSame(a.poses[i], b.poses[i]);
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

/// What decoding `bytes` as an M throws; fails the test when it does not.
template <class M>
std::string refusal(std::span<const std::uint8_t> bytes) {
  try {
    (void)decode<M>(bytes);
  } catch (const core::Error& e) {
    return e.what();
  }
  ADD_FAILURE() << messageType<M>().name << ": " << bytes.size() << " bytes accepted";
  return {};
}

/// What encoding `m` throws; fails the test when it does not.
template <class M>
std::string encodeRefusal(const M& m) {
  try {
    (void)encode(m);
  } catch (const core::Error& e) {
    return e.what();
  }
  ADD_FAILURE() << messageType<M>().name << ": encoded";
  return {};
}

std::uint32_t u32At(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, bytes.data() + at, 4);
  return v;
}
void setU32(std::vector<std::uint8_t>& bytes, std::size_t at, std::uint32_t v) {
  std::memcpy(bytes.data() + at, &v, 4);
}
void setF64(std::vector<std::uint8_t>& bytes, std::size_t at, double v) {
  std::memcpy(bytes.data() + at, &v, 8);
}

/// Where the values after a std_msgs/Header start (seq, stamp, frame_id).
std::size_t afterHeader(const std::vector<std::uint8_t>& bytes, std::size_t at = 0) {
  return at + 16 + u32At(bytes, at + 12);
}

// ---- our encoder and decoder ----

template <class M>
void expectRoundTrip(const M& m) {
  SCOPED_TRACE(messageType<M>().name);
  expectSame(decode<M>(encode(m, 41)), m);
}

TEST(Ros1Messages, EachMessageReadsBackAsWritten) {
  expectRoundTrip(cloudMessage());
  expectRoundTrip(odometryMessage());
  expectRoundTrip(imuMessage());
  expectRoundTrip(imuWithoutOrientation());
  expectRoundTrip(poseMessage());
  expectRoundTrip(pathMessage());
  expectRoundTrip(tfMessage());
  expectRoundTrip(markerMessage());
  expectRoundTrip(Path{{kStamp, ""}, {}});
  expectRoundTrip(TFMessage{});
  expectRoundTrip(MarkerArray{});
}

TEST(Ros1Messages, TheBytesAreRos1sLayout) {
  // Odometry: header (seq, sec, nsec, frame_id), child_frame_id, 7 pose
  // doubles, 36 covariances, 6 twist doubles, 36 covariances; nothing else.
  const Odometry m = odometryMessage();
  const std::vector<std::uint8_t> bytes = encode(m, 1234);
  EXPECT_EQ(bytes.size(), 4 + 8 + 4 + 4 + 4 + 9 + 8 * (7 + 36 + 6 + 36));
  EXPECT_EQ(u32At(bytes, 0), 1234u);
  EXPECT_EQ(u32At(bytes, 4), 1317384506u);
  EXPECT_EQ(u32At(bytes, 8), 750000000u);
  EXPECT_EQ(u32At(bytes, 12), 4u);
  EXPECT_EQ(std::string(bytes.begin() + 16, bytes.begin() + 20), "odom");
  double x;
  std::memcpy(&x, bytes.data() + afterHeader(bytes) + 4 + 9, 8);
  EXPECT_EQ(x, 12.5);
  // Types without a header of their own put seq nowhere: the same bytes whatever it is.
  EXPECT_EQ(encode(tfMessage(), 5), encode(tfMessage(), 6));
  EXPECT_EQ(encode(markerMessage(), 5), encode(markerMessage(), 6));
}

TEST(Ros1Messages, TypesAreNamedAsRos1NamesThem) {
  // The MD5 sums the bag reader (io/rosbag.cpp) knows these types by.
  EXPECT_EQ(messageType<PointCloud2>().name, "sensor_msgs/PointCloud2");
  EXPECT_EQ(messageType<PointCloud2>().md5sum, "1158d486dd51d683ce2f1be655c3c181");
  EXPECT_EQ(messageType<Odometry>().name, "nav_msgs/Odometry");
  EXPECT_EQ(messageType<Odometry>().md5sum, "cd5e73d190d741a2f92e81eda573aca7");
  EXPECT_EQ(messageType<Imu>().name, "sensor_msgs/Imu");
  EXPECT_EQ(messageType<Imu>().md5sum, "6a62c6daae103f4ff57a132d6f95cec2");
  EXPECT_EQ(messageType<PoseStamped>().name, "geometry_msgs/PoseStamped");
  EXPECT_EQ(messageType<PoseStamped>().md5sum, "d3812c3cbc69362b77dc0b19b345f8f5");
  EXPECT_EQ(messageType<Path>().name, "nav_msgs/Path");
  EXPECT_EQ(messageType<TFMessage>().name, "tf2_msgs/TFMessage");
  EXPECT_EQ(messageType<MarkerArray>().name, "visualization_msgs/MarkerArray");
}

TEST(Ros1Messages, ACloudsPointsReadAsTheScan) {
  const PointCloud2 m = decode<PointCloud2>(encode(cloudMessage()));
  const core::PointCloud cloud = io::decodePointCloud2(m.view(), m.header.stamp, true);
  const core::PointCloud scan = test::kittiScan(0);
  ASSERT_EQ(cloud.size(), (scan.size() + 49) / 50);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_EQ(cloud.points[i], scan.points[50 * i]) << i;
    ASSERT_EQ(cloud.intensity[i], scan.intensity[50 * i]) << i;
  }
}

TEST(Ros1Messages, AnOrientationAlmostUnitIsNormalisedAZeroOneRefused) {
  const PoseStamped m = poseMessage();
  std::vector<std::uint8_t> bytes = encode(m);
  const std::size_t orientation = afterHeader(bytes) + 24;
  const Eigen::Quaterniond q(m.pose.rotation());
  const Eigen::Vector4d off = 1.004 * q.coeffs();  // x y z w, 0.4% long
  for (int i = 0; i < 4; ++i) setF64(bytes, orientation + 8 * i, off[i]);
  const PoseStamped read = decode<PoseStamped>(bytes);
  expectSame(read.pose, m.pose, "normalised");
  EXPECT_TRUE(read.pose.linear().isUnitary(1e-12));

  for (int i = 0; i < 4; ++i) setF64(bytes, orientation + 8 * i, 0.0);
  EXPECT_EQ(refusal<PoseStamped>(bytes),
            "geometry_msgs/PoseStamped: pose.orientation: the norm is 0, not 1");
  setF64(bytes, orientation + 24, std::nan(""));
  EXPECT_EQ(refusal<PoseStamped>(bytes),
            "geometry_msgs/PoseStamped: pose.orientation: a value is not finite");
  bytes = encode(m);
  setF64(bytes, orientation - 8, INFINITY);
  EXPECT_EQ(refusal<PoseStamped>(bytes),
            "geometry_msgs/PoseStamped: pose.position: a value is not finite");
}

TEST(Ros1Messages, StampsThatAreNotRos1TimesAreRefused) {
  for (double stamp : {-0.5, 4294967296.0, 1e300, double(NAN), double(INFINITY)}) {
    PoseStamped m = poseMessage();
    m.header.stamp = stamp;
    const std::string what = encodeRefusal(m);
    EXPECT_EQ(what.rfind("geometry_msgs/PoseStamped: header.stamp: ", 0), 0u) << what;
  }
  PoseStamped last = poseMessage();
  last.header.stamp = 4294967295.5;  // in the last second ROS 1 can say
  EXPECT_EQ(decode<PoseStamped>(encode(last)).header.stamp, last.header.stamp);

  Path path = pathMessage();
  path.poses[2].header.stamp = -1.0;
  EXPECT_EQ(encodeRefusal(path),
            "nav_msgs/Path: poses[2].header.stamp: -1 s cannot be a ROS 1 time (uint32 s)");
  MarkerArray markers = markerMessage();
  markers.markers[1].lifetime = 3e9;  // beyond int32 seconds
  EXPECT_EQ(encodeRefusal(markers),
            "visualization_msgs/MarkerArray: markers[1].lifetime: 3000000000 s cannot be a ROS 1 "
            "duration (int32 s)");

  // Read: nanoseconds of a whole second or more are not ROS 1's.
  std::vector<std::uint8_t> bytes = encode(poseMessage());
  setU32(bytes, 8, 1000000000u);
  EXPECT_EQ(refusal<PoseStamped>(bytes),
            "geometry_msgs/PoseStamped: header.stamp: nsec 1000000000 is not below 10^9");
}

TEST(Ros1Messages, ABooleanIsZeroOrOne) {
  std::vector<std::uint8_t> bytes = encode(cloudMessage(500));
  bytes.back() = 2;  // is_dense
  EXPECT_EQ(refusal<PointCloud2>(bytes),
            "sensor_msgs/PointCloud2: is_dense: 2 is not a bool (0 or 1)");
}

// ---- refusals ----

template <class M>
void expectEveryCutRefused(const M& m) {
  const std::vector<std::uint8_t> bytes = encode(m, 3);
  const std::string type(messageType<M>().name);
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::string what = refusal<M>(std::span(bytes).first(n));
    ASSERT_EQ(what.rfind(type + ": ", 0), 0u) << n << " of " << bytes.size() << ": " << what;
  }
}

TEST(Ros1Messages, BytesCutShortAreRefusedAtEveryLength) {
  expectEveryCutRefused(cloudMessage(500));
  expectEveryCutRefused(odometryMessage());
  expectEveryCutRefused(imuMessage());
  expectEveryCutRefused(poseMessage());
  expectEveryCutRefused(pathMessage());
  expectEveryCutRefused(tfMessage());
  expectEveryCutRefused(markerMessage());
}

TEST(Ros1Messages, ARefusalNamesTheTypeAndTheField) {
  const std::vector<std::uint8_t> odometry = encode(odometryMessage());
  const std::size_t covariance = afterHeader(odometry) + 4 + 9 + 7 * 8;
  EXPECT_EQ(refusal<Odometry>(std::span(odometry).first(covariance + 100)),
            fmt::format("nav_msgs/Odometry: pose.covariance: truncated: 8 bytes needed at byte "
                        "{}, 4 left",
                        covariance + 96));
  // An orientation said to be an estimate must be one; marked -1, it need not.
  Imu zero = imuWithoutOrientation();
  zero.orientation_covariance(0, 0) = 1e-6;
  EXPECT_EQ(refusal<Imu>(encode(zero)), "sensor_msgs/Imu: orientation: the norm is 0, not 1");
  EXPECT_FALSE(decode<Imu>(encode(imuWithoutOrientation())).hasOrientation());
  const std::vector<std::uint8_t> path = encode(pathMessage());
  const std::string cut = refusal<Path>(std::span(path).first(path.size() - 3));
  EXPECT_EQ(cut.rfind("nav_msgs/Path: poses[2].pose.orientation: truncated", 0), 0u) << cut;
  const std::vector<std::uint8_t> markers = encode(markerMessage());
  EXPECT_EQ(refusal<MarkerArray>(std::span(markers).first(markers.size() - 7)),
            "visualization_msgs/MarkerArray: markers[1].text: count 3 needs 3 bytes at least, 1 "
            "left");
}

TEST(Ros1Messages, TrailingBytesAreRefused) {
  std::vector<std::uint8_t> bytes = encode(odometryMessage());
  bytes.push_back(0);
  EXPECT_EQ(refusal<Odometry>(bytes), "nav_msgs/Odometry: bytes left after the message: 1");
  bytes = encode(cloudMessage(500));
  bytes.insert(bytes.end(), {1, 2, 3});
  EXPECT_EQ(refusal<PointCloud2>(bytes),
            "sensor_msgs/PointCloud2: bytes left after the message: 3");
  bytes = encode(tfMessage());
  bytes.push_back(0);
  (void)refusal<TFMessage>(bytes);
  bytes = encode(markerMessage());
  bytes.push_back(0);
  (void)refusal<MarkerArray>(bytes);
}

TEST(Ros1Messages, ACountBeyondTheBytesIsRefusedBeforeAllocating) {
  const auto expectRefusedSmall = [](auto decodeIt, const std::string& start) {
    const LargestAllocation largest;
    const std::string what = decodeIt();
    EXPECT_EQ(what.rfind(start, 0), 0u) << what;
    EXPECT_LT(largest.bytes(), 64u * 1024u) << start;
  };
  // The cloud's data: four billion bytes said, a few hundred there.
  std::vector<std::uint8_t> cloud = encode(cloudMessage(500));
  const std::size_t data = cloud.size() - 1 - cloudMessage(500).data.size() - 4;
  ASSERT_EQ(u32At(cloud, data), cloudMessage(500).data.size());
  setU32(cloud, data, 0xffffffffu);
  expectRefusedSmall(
      [&] { return refusal<PointCloud2>(cloud); },
      "sensor_msgs/PointCloud2: data: count 4294967295 needs 4294967295 bytes at least");
  // Poses, markers and a marker's points: each element larger than a byte.
  std::vector<std::uint8_t> path = encode(pathMessage());
  setU32(path, afterHeader(path), 100000000u);
  expectRefusedSmall([&] { return refusal<Path>(path); },
                     "nav_msgs/Path: poses: count 100000000 needs 7200000000 bytes at least");
  std::vector<std::uint8_t> markers = encode(markerMessage());
  setU32(markers, 0, 0xfffffff0u);
  expectRefusedSmall(
      [&] { return refusal<MarkerArray>(markers); },
      "visualization_msgs/MarkerArray: markers: count 4294967280 needs 661424961120 bytes");
  // Just past what fits: 3 bytes of the 4 frame_id needs.
  std::vector<std::uint8_t> tf = encode(tfMessage());
  setU32(tf, 16, 0xffffffffu);  // the first transform's frame_id
  expectRefusedSmall([&] { return refusal<TFMessage>(tf); },
                     "tf2_msgs/TFMessage: transforms[0].header.frame_id: count 4294967295 needs");
  tf = encode(tfMessage());
  setU32(tf, 0, static_cast<std::uint32_t>(tf.size() / 76 + 1));
  expectRefusedSmall([&] { return refusal<TFMessage>(tf); },
                     "tf2_msgs/TFMessage: transforms: count ");
}

template <class M>
void expectOnlyErrors(const M& m, std::mt19937& rng) {
  const std::vector<std::uint8_t> bytes = encode(m);
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<std::uint8_t> damaged = bytes;
    for (int k = 0; k < 8; ++k) damaged[rng() % damaged.size()] = static_cast<std::uint8_t>(rng());
    try {
      (void)decode<M>(damaged);
    } catch (const core::Error& e) {
      ASSERT_EQ(std::string(e.what()).rfind(std::string(messageType<M>().name) + ": ", 0), 0u)
          << e.what();
    }
  }
}

TEST(Ros1Messages, DamagedBytesEndInAnErrorNamingTheType) {
  std::mt19937 rng(31);
  expectOnlyErrors(cloudMessage(), rng);
  expectOnlyErrors(odometryMessage(), rng);
  expectOnlyErrors(imuMessage(), rng);
  expectOnlyErrors(poseMessage(), rng);
  expectOnlyErrors(pathMessage(), rng);
  expectOnlyErrors(tfMessage(), rng);
  expectOnlyErrors(markerMessage(), rng);
}

// ---- against genpy, ROS 1's own serialiser ----

/// Debian's interpreter, which has the python3-*-msgs packages; DCL_ROS_PYTHON overrides it.
std::string python() {
  const char* custom = std::getenv("DCL_ROS_PYTHON");
  return custom ? custom : "/usr/bin/python3";
}

std::vector<std::uint8_t> readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// A folder of its own, removed with what it holds however the test ends.
class TempFolder {
 public:
  explicit TempFolder(const std::string& name)
      : path_(fs::path(::testing::TempDir()) / (name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempFolder() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// One message for genpy: its type, our bytes and the values they hold.
template <class M>
void writeCase(const fs::path& dir, const std::string& name, const M& m, std::uint32_t seq) {
  std::ofstream(dir / (name + ".type")) << messageType<M>().name;
  const std::vector<std::uint8_t> bytes = encode(m, seq);
  std::ofstream(dir / (name + ".ros1"), std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  std::ofstream(dir / (name + ".json")) << toJson(m, seq).dump();
}

/// genpy's view of case `name`: its type as genpy holds it, and what it read
/// from our bytes, field by field; then its own bytes of the same values, read by us.
template <class M>
void expectAlike(const json& genpy, const fs::path& dir, const std::string& name, const M& m,
                 std::uint32_t seq) {
  SCOPED_TRACE(name);
  ASSERT_TRUE(genpy.contains(name));
  const json& theirs = genpy[name];
  const MessageType& type = messageType<M>();
  EXPECT_EQ(theirs["type"].get<std::string>(), type.name);
  EXPECT_EQ(theirs["md5sum"].get<std::string>(), type.md5sum);
  EXPECT_EQ(theirs["definition"].get<std::string>(), type.definition);
  expectSameJson(theirs["read"], toJson(m, seq), std::string(type.name));
  const std::vector<std::uint8_t> written = readBytes(dir / (name + ".genpy.ros1"));
  ASSERT_FALSE(written.empty());
  expectSame(decode<M>(written), m);
  EXPECT_EQ(written, encode(m, seq)) << "the same values, other bytes";
}

TEST(Ros1Messages, GenpyReadsOursAndWeReadGenpys) {
  const TempFolder dir("dcl_ros1_crosscheck");
  writeCase(dir.path(), "cloud", cloudMessage(), 17);
  writeCase(dir.path(), "odometry", odometryMessage(), 4242);
  writeCase(dir.path(), "imu", imuMessage(), 77);
  writeCase(dir.path(), "imu_bare", imuWithoutOrientation(), 78);
  writeCase(dir.path(), "pose", poseMessage(), 0xfffffffeu);
  writeCase(dir.path(), "path", pathMessage(), 9);
  writeCase(dir.path(), "tf", tfMessage(), 0);
  writeCase(dir.path(), "markers", markerMessage(), 0);
  const std::string command = "'" + python() + "' '" + DCL_SOURCE_DIR +
                              "/tests/ros/ros1_crosscheck.py' '" + dir.path().string() + "'";
  std::string output;
  FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr) << "cannot run " << command;
  char chunk[4096];
  for (std::size_t n; (n = std::fread(chunk, 1, sizeof(chunk), pipe)) > 0;) output.append(chunk, n);
  ASSERT_EQ(::pclose(pipe), 0) << command
                               << " failed (scripts/setup installs Debian's python3-*-msgs)";
  const json genpy = json::parse(output);
  expectAlike(genpy, dir.path(), "cloud", cloudMessage(), 17);
  expectAlike(genpy, dir.path(), "odometry", odometryMessage(), 4242);
  expectAlike(genpy, dir.path(), "imu", imuMessage(), 77);
  expectAlike(genpy, dir.path(), "imu_bare", imuWithoutOrientation(), 78);
  expectAlike(genpy, dir.path(), "pose", poseMessage(), 0xfffffffeu);
  expectAlike(genpy, dir.path(), "path", pathMessage(), 9);
  expectAlike(genpy, dir.path(), "tf", tfMessage(), 0);
  expectAlike(genpy, dir.path(), "markers", markerMessage(), 0);
}

}  // namespace
}  // namespace dcl::ros1
