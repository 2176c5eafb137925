// ROS stays in this file. ROS1's generated message headers do not compile as
// C++20 (std::allocator<void>::rebind), so messages are serialised here by hand
// (little-endian; strings and arrays prefixed by a uint32 length) into one raw
// message type that carries its own type name, md5sum and definition: rosbag
// only needs ros::message_traits and a ros::serialization::Serializer for it.
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>

#include <fmt/format.h>
#include <rosbag/bag.h>

#include <dcl/core/error.hpp>
#include <dcl/io/bag_writer.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/point_cloud2.hpp>

namespace dcl::io {

namespace {

static_assert(std::endian::native == std::endian::little, "ROS1 serialisation is little-endian");

/// A message type: its name, the md5sum of its definition, and the definition
/// (with the definitions of the messages it uses) as `rosmsg show` prints it.
struct MessageType {
  const char* name;
  const char* md5;
  const char* definition;
};

// The definitions as ROS stores them in bags: the message, then every message
// it uses after a line of '=' and "MSG: type" (comments left out).
constexpr const char* kCloudDefinition = R"(Header header
uint32 height
uint32 width
PointField[] fields
bool is_bigendian
uint32 point_step
uint32 row_step
uint8[] data
bool is_dense
================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
================================================================================
MSG: sensor_msgs/PointField
uint8 INT8    = 1
uint8 UINT8   = 2
uint8 INT16   = 3
uint8 UINT16  = 4
uint8 INT32   = 5
uint8 UINT32  = 6
uint8 FLOAT32 = 7
uint8 FLOAT64 = 8
string name
uint32 offset
uint8 datatype
uint32 count
)";

constexpr const char* kOdometryDefinition = R"(Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
================================================================================
MSG: geometry_msgs/PoseWithCovariance
Pose pose
float64[36] covariance
================================================================================
MSG: geometry_msgs/Pose
Point position
Quaternion orientation
================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
================================================================================
MSG: geometry_msgs/TwistWithCovariance
Twist twist
float64[36] covariance
================================================================================
MSG: geometry_msgs/Twist
Vector3 linear
Vector3 angular
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
)";

constexpr MessageType kCloudType{"sensor_msgs/PointCloud2", "1158d486dd51d683ce2f1be655c3c181",
                                 kCloudDefinition};
constexpr MessageType kOdometryType{"nav_msgs/Odometry", "cd5e73d190d741a2f92e81eda573aca7",
                                    kOdometryDefinition};

/// A serialised message and its type: what rosbag writes.
struct RawMessage {
  const MessageType* type = nullptr;
  std::vector<std::uint8_t> bytes;
};

}  // namespace

}  // namespace dcl::io

namespace ros::message_traits {

template <>
struct MD5Sum<dcl::io::RawMessage> {
  static const char* value(const dcl::io::RawMessage& m) { return m.type->md5; }
};
template <>
struct DataType<dcl::io::RawMessage> {
  static const char* value(const dcl::io::RawMessage& m) { return m.type->name; }
};
template <>
struct Definition<dcl::io::RawMessage> {
  static const char* value(const dcl::io::RawMessage& m) { return m.type->definition; }
};

}  // namespace ros::message_traits

namespace ros::serialization {

template <>
struct Serializer<dcl::io::RawMessage> {
  template <typename Stream>
  static void write(Stream& stream, const dcl::io::RawMessage& m) {
    if (!m.bytes.empty())
      std::memcpy(stream.advance(m.bytes.size()), m.bytes.data(), m.bytes.size());
  }
  static std::uint32_t serializedLength(const dcl::io::RawMessage& m) {
    return static_cast<std::uint32_t>(m.bytes.size());
  }
};

}  // namespace ros::serialization

namespace dcl::io {

namespace {

namespace fs = std::filesystem;

/// Appends ROS1-serialised values to a byte buffer.
struct Serialiser {
  std::vector<std::uint8_t> bytes;

  template <class T>
  void put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    const std::size_t at = bytes.size();
    bytes.resize(at + sizeof(T));
    std::memcpy(bytes.data() + at, &value, sizeof(T));
  }
  void putString(const std::string& s) {
    put(static_cast<std::uint32_t>(s.size()));
    bytes.insert(bytes.end(), s.begin(), s.end());
  }
  void putTime(const ros::Time& t) {
    put(t.sec);
    put(t.nsec);
  }
  void putHeader(std::uint32_t seq, const ros::Time& stamp, const std::string& frame_id) {
    put(seq);
    putTime(stamp);
    putString(frame_id);
  }
};

ros::Time rosTime(double stamp) {
  auto sec = static_cast<std::uint32_t>(std::floor(stamp));
  auto nsec = static_cast<std::uint32_t>(std::llround((stamp - std::floor(stamp)) * 1e9));
  if (nsec >= 1000000000u) {
    ++sec;
    nsec -= 1000000000u;
  }
  return {sec, nsec};
}

RawMessage cloudMessage(std::uint32_t seq, const ros::Time& stamp, const core::PointCloud& cloud,
                        const std::string& frame_id) {
  const PointCloud2Data points = encodePointCloud2(cloud);
  Serialiser s;
  const auto n = static_cast<std::uint32_t>(cloud.size());
  s.putHeader(seq, stamp, frame_id);
  s.put(std::uint32_t{1});  // height: unorganised
  s.put(n);                 // width
  s.put(static_cast<std::uint32_t>(points.fields.size()));
  for (const auto& f : points.fields) {
    s.putString(f.name);
    s.put(f.offset);
    s.put(f.datatype);
    s.put(f.count);
  }
  s.put(std::uint8_t{0});  // is_bigendian
  s.put(points.point_step);
  s.put(n * points.point_step);  // row_step
  s.put(static_cast<std::uint32_t>(points.data.size()));
  s.bytes.insert(s.bytes.end(), points.data.begin(), points.data.end());
  s.put(std::uint8_t{1});  // is_dense: every point is finite
  return {&kCloudType, std::move(s.bytes)};
}

RawMessage odometryMessage(std::uint32_t seq, const ros::Time& stamp, const Eigen::Isometry3d& T,
                           const std::string& frame_id, const std::string& child_frame_id) {
  Serialiser s;
  s.putHeader(seq, stamp, frame_id);
  s.putString(child_frame_id);
  const Eigen::Vector3d t = T.translation();
  const Eigen::Quaterniond q(T.rotation());
  for (double v : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) s.put(v);
  for (int i = 0; i < 36 + 6 + 36; ++i) s.put(0.0);  // pose covariance, twist, twist covariance
  return {&kOdometryType, std::move(s.bytes)};
}

}  // namespace

struct BagWriter::Impl {
  std::string path;
  TempFile tmp;
  rosbag::Bag bag;
  std::map<std::string, std::uint32_t> sequence;  // per topic
  /// The types of writeSerialised's messages, by name: their strings, and
  /// the MessageType (pointing into them) that rosbag is given.
  struct OwnedType {
    std::string name, md5, definition;
    MessageType type{};
  };
  std::map<std::string, OwnedType, std::less<>> types;
  bool closed = false;

  explicit Impl(std::string p) : path(std::move(p)), tmp(path) {}

  template <class F>
  void guarded(const char* what, F&& f) {
    try {
      f();
    } catch (const core::Error&) {
      throw;
    } catch (const std::exception& e) {
      throw core::FileError({path}, fmt::format("cannot {} the bag: {}", what, e.what()));
    }
  }

  void write(const std::string& topic, double stamp, const RawMessage& m) {
    if (!(stamp > 0.0))
      throw core::FileError({path}, fmt::format("stamp {} is not positive", stamp));
    guarded("write", [&] { bag.write(topic, rosTime(stamp), m); });
  }
};

BagWriter::BagWriter(std::string path) : impl_(std::make_unique<Impl>(path)) {
  impl_->guarded("create", [&] { impl_->bag.open(impl_->tmp.path(), rosbag::bagmode::Write); });
}

BagWriter::~BagWriter() {
  if (impl_->closed) return;
  try {
    impl_->bag.close();
  } catch (...) {  // NOLINT(bugprone-empty-catch): the bag is discarded anyway
  }
}

void BagWriter::writeCloud(const std::string& topic, double stamp, const core::PointCloud& cloud,
                           const std::string& frame_id) {
  if (!cloud.consistent()) throw core::FileError({impl_->path}, "inconsistent cloud channels");
  const std::uint32_t seq = impl_->sequence[topic]++;
  impl_->write(topic, stamp, cloudMessage(seq, rosTime(stamp), cloud, frame_id));
}

void BagWriter::writeOdometry(const std::string& topic, double stamp,
                              const Eigen::Isometry3d& T_frame_child, const std::string& frame_id,
                              const std::string& child_frame_id) {
  const std::uint32_t seq = impl_->sequence[topic]++;
  impl_->write(topic, stamp,
               odometryMessage(seq, rosTime(stamp), T_frame_child, frame_id, child_frame_id));
}

void BagWriter::writeSerialised(const std::string& topic, double stamp, std::string_view type,
                                std::string_view md5sum, std::string_view definition,
                                std::vector<std::uint8_t> bytes) {
  auto found = impl_->types.find(type);
  if (found == impl_->types.end()) {
    found = impl_->types.try_emplace(std::string(type)).first;
    Impl::OwnedType& owned = found->second;
    owned.name = type;
    owned.md5 = md5sum;
    owned.definition = definition;
    owned.type = {owned.name.c_str(), owned.md5.c_str(), owned.definition.c_str()};
  }
  impl_->write(topic, stamp, RawMessage{&found->second.type, std::move(bytes)});
}

void BagWriter::close() {
  if (impl_->closed) return;
  impl_->guarded("finish", [&] { impl_->bag.close(); });
  impl_->tmp.commit();
  impl_->closed = true;
}

}  // namespace dcl::io
