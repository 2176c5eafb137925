// ROS 2 messages to and from their wire form. The generated C types
// (idl/ros2/*.idl) carry the values; Cyclone DDS's CDR stream functions, the
// ones its writers and readers use, turn them into bytes and back. Incoming
// bytes are first checked and brought into this machine's byte order by
// dds_stream_normalize_data, which refuses any length or value that runs past
// the end, before anything is read from them.
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

#include <dds/dds.h>
#include <dds/ddsi/ddsi_cdrstream.h>
#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/ros/ros2_messages.hpp>

#include "ros2_wire.hpp"

namespace dcl::ros2 {
namespace detail {

namespace {

using core::Error;

// RTPS encapsulation identifiers (big-endian on the wire) and the CDR version.
constexpr std::uint16_t kCdrBigEndian = 0x0000;
constexpr std::uint16_t kCdrLittleEndian = 0x0001;
constexpr std::uint32_t kXcdr1 = 1;

/// A C string field pointing at `s` (the stream functions only read it).
char* cString(const std::string& s) {
  return const_cast<char*>(s.c_str());
}

builtin_interfaces_msg_dds__Time_ toTime(double seconds, std::string_view what) {
  const double whole = std::floor(seconds);
  if (!std::isfinite(seconds) || whole < std::numeric_limits<std::int32_t>::min() ||
      whole > std::numeric_limits<std::int32_t>::max()) {
    throw Error(fmt::format("{}: {} s cannot be a ROS 2 time (int32 seconds)", what, seconds));
  }
  auto sec = static_cast<std::int64_t>(whole);
  auto nanosec = static_cast<std::int64_t>(std::llround((seconds - whole) * 1e9));
  if (nanosec >= 1000000000) {
    ++sec;
    nanosec -= 1000000000;
  }
  return {static_cast<std::int32_t>(sec), static_cast<std::uint32_t>(nanosec)};
}

double fromTime(std::int32_t sec, std::uint32_t nanosec, std::string_view what) {
  if (nanosec >= 1000000000u) {
    throw Error(fmt::format("{}: nanosec {} is not below 10^9", what, nanosec));
  }
  return static_cast<double>(sec) + 1e-9 * static_cast<double>(nanosec);
}

std_msgs_msg_dds__Header_ toHeader(const Header& h) {
  return {toTime(h.stamp, "header.stamp"), cString(h.frame_id)};
}

Header fromHeader(const std_msgs_msg_dds__Header_& h) {
  return {fromTime(h.stamp.sec, h.stamp.nanosec, "header.stamp"),
          h.frame_id != nullptr ? std::string(h.frame_id) : std::string()};
}

geometry_msgs_msg_dds__Pose_ toPose(const Eigen::Isometry3d& T) {
  const Eigen::Vector3d t = T.translation();
  const Eigen::Quaterniond q(T.rotation());
  return {{t.x(), t.y(), t.z()}, {q.x(), q.y(), q.z(), q.w()}};
}

Eigen::Isometry3d fromPose(const geometry_msgs_msg_dds__Point_& p,
                           const geometry_msgs_msg_dds__Quaternion_& q, std::string_view what) {
  const Eigen::Vector3d t(p.x, p.y, p.z);
  Eigen::Quaterniond r(q.w, q.x, q.y, q.z);
  const double norm = r.norm();
  if (!t.allFinite() || !std::isfinite(norm)) {
    throw Error(fmt::format("{}: a value is not finite", what));
  }
  // Drivers send quaternions a little off unit norm; none send a zero one on purpose.
  if (std::abs(norm - 1.0) > 1e-2) {
    throw Error(fmt::format("{}: the orientation's norm is {}, not 1", what, norm));
  }
  r.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = r.toRotationMatrix();
  T.translation() = t;
  return T;
}

/// An IMU's orientation: checked as a pose's when `estimated`; otherwise
/// (orientation_covariance[0] = -1) anything, often zeros, kept as it came.
Eigen::Quaterniond fromOrientation(const geometry_msgs_msg_dds__Quaternion_& q, bool estimated,
                                   std::string_view what) {
  if (!estimated) return {q.w, q.x, q.y, q.z};
  return Eigen::Quaterniond(fromPose({0.0, 0.0, 0.0}, q, what).rotation());
}

void toCovariance(const Eigen::Matrix3d& m, double (&out)[9]) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out[3 * r + c] = m(r, c);
}

Eigen::Matrix3d fromCovariance(const double (&in)[9]) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = in[3 * r + c];
  return m;
}

void toCovariance(const Eigen::Matrix<double, 6, 6>& m, double (&out)[36]) {
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) out[6 * r + c] = m(r, c);
}

Eigen::Matrix<double, 6, 6> fromCovariance(const double (&in)[36]) {
  Eigen::Matrix<double, 6, 6> m;
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) m(r, c) = in[6 * r + c];
  return m;
}

template <class Seq, class T>
Seq sequenceOf(std::vector<T>& items) {
  Seq s{};
  s._maximum = s._length = static_cast<std::uint32_t>(items.size());
  s._buffer = items.data();
  s._release = false;
  return s;
}

std::vector<std::uint8_t> writeCdr(const void* sample, const dds_topic_descriptor_t& desc) {
  dds_ostreamLE_t os;
  dds_ostreamLE_init(&os, 0, kXcdr1);
  dds_stream_writeLE(&os, static_cast<const char*>(sample), desc.m_ops);
  std::vector<std::uint8_t> out(4 + std::size_t{os.x.m_index}, 0);
  out[0] = kCdrLittleEndian >> 8;
  out[1] = kCdrLittleEndian & 0xff;  // then two bytes of options, 0
  if (os.x.m_index > 0) std::memcpy(out.data() + 4, os.x.m_buffer, os.x.m_index);
  dds_ostreamLE_fini(&os);
  return out;
}

/// A sample read from bytes, freed with what the reader allocated in it.
template <class C>
class Sample {
 public:
  Sample(std::span<const std::uint8_t> bytes, const dds_topic_descriptor_t& desc) : desc_(desc) {
    std::memset(&value_, 0, sizeof(value_));
    const std::string_view type = desc.m_typename;
    if (bytes.size() <= 4) {  // no message is empty: a header holds 8 bytes at least
      throw Error(fmt::format("{}: {} bytes, none after the 4 of the encapsulation header", type,
                              bytes.size()));
    }
    const auto id = static_cast<std::uint16_t>(bytes[0] << 8 | bytes[1]);
    if (id != kCdrLittleEndian && id != kCdrBigEndian) {
      throw Error(
          fmt::format("{}: encapsulation 0x{:04x} is not plain CDR (ROS 2 writes 0x0000 "
                      "or 0x0001)",
                      type, id));
    }
    if (bytes.size() - 4 > std::numeric_limits<std::uint32_t>::max()) {
      throw Error(fmt::format("{}: {} bytes, too many", type, bytes.size()));
    }
    const bool swap = (id == kCdrBigEndian) == (std::endian::native == std::endian::little);
    data_.assign(bytes.begin() + 4, bytes.end());
    const auto size = static_cast<std::uint32_t>(data_.size());
    std::uint32_t offset = 0;
    if (dds_stream_normalize_data(data_.data(), &offset, size, swap, kXcdr1, desc.m_ops) ==
        nullptr) {
      throw Error(
          fmt::format("{}: the {} bytes do not hold one (a length or a value runs past "
                      "the end, or a boolean is neither 0 nor 1)",
                      type, size));
    }
    dds_istream_t in;
    dds_istream_init(&in, size, data_.data(), kXcdr1);
    dds_stream_read(&in, reinterpret_cast<char*>(&value_), desc.m_ops);
    dds_istream_fini(&in);
  }
  ~Sample() { dds_stream_free_sample(&value_, desc_.m_ops); }
  Sample(const Sample&) = delete;
  Sample& operator=(const Sample&) = delete;

  const C& operator*() const { return value_; }
  const C* operator->() const { return &value_; }

 private:
  const dds_topic_descriptor_t& desc_;
  std::vector<char> data_;
  C value_;
};

std::string str(const char* s) {
  return s != nullptr ? std::string(s) : std::string();
}

}  // namespace

// ---- sensor_msgs/PointCloud2 ----

Wire<PointCloud2>::Out::Out(const PointCloud2& m) {
  for (const auto& f : m.fields)
    fields_.push_back({cString(f.name), f.offset, f.datatype, f.count});
  c_.header = toHeader(m.header);
  c_.height = m.height;
  c_.width = m.width;
  c_.fields = sequenceOf<dds_sequence_sensor_msgs_msg_dds__PointField_>(fields_);
  c_.is_bigendian = m.is_bigendian;
  c_.point_step = m.point_step;
  c_.row_step = m.row_step;
  // The points are read where they are, not copied (the writers only read).
  c_.data._maximum = c_.data._length = static_cast<std::uint32_t>(m.data.size());
  c_.data._buffer = const_cast<std::uint8_t*>(m.data.data());
  c_.data._release = false;
  c_.is_dense = m.is_dense;
}

PointCloud2 Wire<PointCloud2>::in(const C& c) {
  PointCloud2 m;
  m.header = fromHeader(c.header);
  m.height = c.height;
  m.width = c.width;
  for (std::uint32_t i = 0; i < c.fields._length; ++i) {
    const auto& f = c.fields._buffer[i];
    m.fields.push_back({str(f.name), f.offset, f.datatype, f.count});
  }
  m.is_bigendian = c.is_bigendian;
  m.point_step = c.point_step;
  m.row_step = c.row_step;
  m.data.assign(c.data._buffer, c.data._buffer + c.data._length);
  m.is_dense = c.is_dense;
  return m;
}

// ---- sensor_msgs/Imu ----

Wire<Imu>::Out::Out(const Imu& m) {
  c_.header = toHeader(m.header);
  const Eigen::Quaterniond& q = m.orientation;
  c_.orientation = {q.x(), q.y(), q.z(), q.w()};
  toCovariance(m.orientation_covariance, c_.orientation_covariance);
  const Eigen::Vector3d& w = m.angular_velocity;
  c_.angular_velocity = {w.x(), w.y(), w.z()};
  toCovariance(m.angular_velocity_covariance, c_.angular_velocity_covariance);
  const Eigen::Vector3d& a = m.linear_acceleration;
  c_.linear_acceleration = {a.x(), a.y(), a.z()};
  toCovariance(m.linear_acceleration_covariance, c_.linear_acceleration_covariance);
}

Imu Wire<Imu>::in(const C& c) {
  Imu m;
  m.header = fromHeader(c.header);
  m.orientation_covariance = fromCovariance(c.orientation_covariance);
  m.orientation = fromOrientation(c.orientation, m.hasOrientation(), "sensor_msgs/Imu orientation");
  m.angular_velocity = {c.angular_velocity.x, c.angular_velocity.y, c.angular_velocity.z};
  m.angular_velocity_covariance = fromCovariance(c.angular_velocity_covariance);
  m.linear_acceleration = {c.linear_acceleration.x, c.linear_acceleration.y,
                           c.linear_acceleration.z};
  m.linear_acceleration_covariance = fromCovariance(c.linear_acceleration_covariance);
  return m;
}

// ---- nav_msgs/Odometry ----

Wire<Odometry>::Out::Out(const Odometry& m) {
  c_.header = toHeader(m.header);
  c_.child_frame_id = cString(m.child_frame_id);
  c_.pose.pose = toPose(m.pose);
  toCovariance(m.pose_covariance, c_.pose.covariance);
  const Eigen::Vector3d& v = m.linear_velocity;
  const Eigen::Vector3d& w = m.angular_velocity;
  c_.twist.twist = {{v.x(), v.y(), v.z()}, {w.x(), w.y(), w.z()}};
  toCovariance(m.twist_covariance, c_.twist.covariance);
}

Odometry Wire<Odometry>::in(const C& c) {
  Odometry m;
  m.header = fromHeader(c.header);
  m.child_frame_id = str(c.child_frame_id);
  m.pose = fromPose(c.pose.pose.position, c.pose.pose.orientation, "nav_msgs/Odometry pose");
  m.pose_covariance = fromCovariance(c.pose.covariance);
  const auto& t = c.twist.twist;
  m.linear_velocity = {t.linear.x, t.linear.y, t.linear.z};
  m.angular_velocity = {t.angular.x, t.angular.y, t.angular.z};
  m.twist_covariance = fromCovariance(c.twist.covariance);
  return m;
}

// ---- geometry_msgs/PoseStamped ----

Wire<PoseStamped>::Out::Out(const PoseStamped& m) {
  c_.header = toHeader(m.header);
  c_.pose = toPose(m.pose);
}

PoseStamped Wire<PoseStamped>::in(const C& c) {
  return {fromHeader(c.header),
          fromPose(c.pose.position, c.pose.orientation, "geometry_msgs/PoseStamped pose")};
}

// ---- nav_msgs/Path ----

Wire<Path>::Out::Out(const Path& m) {
  poses_.reserve(m.poses.size());
  for (const auto& p : m.poses) poses_.push_back({toHeader(p.header), toPose(p.pose)});
  c_.header = toHeader(m.header);
  c_.poses = sequenceOf<dds_sequence_geometry_msgs_msg_dds__PoseStamped_>(poses_);
}

Path Wire<Path>::in(const C& c) {
  Path m;
  m.header = fromHeader(c.header);
  m.poses.reserve(c.poses._length);
  for (std::uint32_t i = 0; i < c.poses._length; ++i) {
    const auto& p = c.poses._buffer[i];
    m.poses.push_back({fromHeader(p.header), fromPose(p.pose.position, p.pose.orientation,
                                                      fmt::format("nav_msgs/Path pose {}", i))});
  }
  return m;
}

// ---- tf2_msgs/TFMessage ----

Wire<TFMessage>::Out::Out(const TFMessage& m) {
  transforms_.reserve(m.transforms.size());
  for (const auto& t : m.transforms) {
    const auto pose = toPose(t.transform);
    transforms_.push_back(
        {toHeader(t.header),
         cString(t.child_frame_id),
         {{pose.position.x, pose.position.y, pose.position.z}, pose.orientation}});
  }
  c_.transforms = sequenceOf<dds_sequence_geometry_msgs_msg_dds__TransformStamped_>(transforms_);
}

TFMessage Wire<TFMessage>::in(const C& c) {
  TFMessage m;
  m.transforms.reserve(c.transforms._length);
  for (std::uint32_t i = 0; i < c.transforms._length; ++i) {
    const auto& t = c.transforms._buffer[i];
    const geometry_msgs_msg_dds__Point_ at{t.transform.translation.x, t.transform.translation.y,
                                           t.transform.translation.z};
    m.transforms.push_back(
        {fromHeader(t.header), str(t.child_frame_id),
         fromPose(at, t.transform.rotation, fmt::format("tf2_msgs/TFMessage transform {}", i))});
  }
  return m;
}

// ---- visualization_msgs/MarkerArray ----

Wire<MarkerArray>::Out::Out(const MarkerArray& m)
    : points_(m.markers.size()), colors_(m.markers.size()), markers_(m.markers.size()) {
  static const std::string kEmpty;
  for (std::size_t i = 0; i < m.markers.size(); ++i) {
    const Marker& k = m.markers[i];
    for (const auto& p : k.points) points_[i].push_back({p.x(), p.y(), p.z()});
    for (const auto& c : k.colors) colors_[i].push_back({c.r, c.g, c.b, c.a});
    auto& c = markers_[i];  // zeroed: empty texture, UV and mesh fields
    c.header = toHeader(k.header);
    c.ns = cString(k.ns);
    c.id = k.id;
    c.type = k.type;
    c.action = k.action;
    c.pose = toPose(k.pose);
    c.scale = {k.scale.x(), k.scale.y(), k.scale.z()};
    c.color = {k.color.r, k.color.g, k.color.b, k.color.a};
    const auto lifetime = toTime(k.lifetime, "visualization_msgs/Marker lifetime");
    c.lifetime = {lifetime.sec, lifetime.nanosec};
    c.frame_locked = k.frame_locked;
    c.points = sequenceOf<dds_sequence_geometry_msgs_msg_dds__Point_>(points_[i]);
    c.colors = sequenceOf<dds_sequence_std_msgs_msg_dds__ColorRGBA_>(colors_[i]);
    c.texture_resource = cString(kEmpty);
    c.texture.header.frame_id = cString(kEmpty);
    c.texture.format = cString(kEmpty);
    c.text = cString(k.text);
    c.mesh_resource = cString(kEmpty);
    c.mesh_file.filename = cString(kEmpty);
  }
  c_.markers = sequenceOf<dds_sequence_visualization_msgs_msg_dds__Marker_>(markers_);
}

MarkerArray Wire<MarkerArray>::in(const C& c) {
  MarkerArray m;
  for (std::uint32_t i = 0; i < c.markers._length; ++i) {
    const auto& k = c.markers._buffer[i];
    Marker out;
    out.header = fromHeader(k.header);
    out.ns = str(k.ns);
    out.id = k.id;
    out.type = k.type;
    out.action = k.action;
    out.pose = fromPose(k.pose.position, k.pose.orientation,
                        fmt::format("visualization_msgs/Marker {} pose", i));
    out.scale = {k.scale.x, k.scale.y, k.scale.z};
    out.color = {k.color.r, k.color.g, k.color.b, k.color.a};
    out.lifetime =
        fromTime(k.lifetime.sec, k.lifetime.nanosec, "visualization_msgs/Marker lifetime");
    out.frame_locked = k.frame_locked;
    for (std::uint32_t j = 0; j < k.points._length; ++j) {
      const auto& p = k.points._buffer[j];
      out.points.emplace_back(p.x, p.y, p.z);
    }
    for (std::uint32_t j = 0; j < k.colors._length; ++j) {
      const auto& col = k.colors._buffer[j];
      out.colors.push_back({col.r, col.g, col.b, col.a});
    }
    out.text = str(k.text);
    m.markers.push_back(std::move(out));
  }
  return m;
}

}  // namespace detail

// ---- bytes ----

template <class M>
std::string_view typeName() {
  return detail::Wire<M>::descriptor().m_typename;
}

template <class M>
M decode(std::span<const std::uint8_t> bytes) {
  using W = detail::Wire<M>;
  const detail::Sample<typename W::C> c(bytes, W::descriptor());
  return W::in(*c);
}

#define DCL_ROS2_MESSAGE(M)                                            \
  template std::string_view typeName<M>();                             \
  template M decode<M>(std::span<const std::uint8_t>);                 \
  std::vector<std::uint8_t> encode(const M& message) {                 \
    const detail::Wire<M>::Out out(message);                           \
    return detail::writeCdr(out.get(), detail::Wire<M>::descriptor()); \
  }
DCL_ROS2_MESSAGE(PointCloud2)
DCL_ROS2_MESSAGE(Imu)
DCL_ROS2_MESSAGE(Odometry)
DCL_ROS2_MESSAGE(PoseStamped)
DCL_ROS2_MESSAGE(Path)
DCL_ROS2_MESSAGE(TFMessage)
DCL_ROS2_MESSAGE(MarkerArray)
#undef DCL_ROS2_MESSAGE

}  // namespace dcl::ros2
