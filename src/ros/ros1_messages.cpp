// ROS 1 messages to and from their serialisation, by hand: each value in
// field order, little-endian and packed; a string or a variable array as a
// uint32 count then its elements; a fixed array (a covariance) as its
// elements alone. Incoming bytes are read by a reader that checks every count
// against the bytes left before it allocates or reads anything, and names the
// type and the field it was reading when it refuses them.
#include <bit>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/ros/ros1_messages.hpp>

namespace dcl::ros1 {

namespace {

static_assert(std::endian::native == std::endian::little, "ROS 1 serialisation is little-endian");

using core::Error;

// The fewest bytes an element of each variable array takes (its strings and
// arrays empty): a count beyond the bytes left over this is refused at once.
constexpr std::size_t kHeaderBytes = 4 + 8 + 4;  // seq, stamp, frame_id's count
constexpr std::size_t kPoseBytes = 7 * 8;        // position, orientation
constexpr std::size_t kPointFieldBytes = 4 + 4 + 1 + 4;
constexpr std::size_t kPoseStampedBytes = kHeaderBytes + kPoseBytes;
constexpr std::size_t kTransformStampedBytes = kHeaderBytes + 4 + kPoseBytes;
constexpr std::size_t kPointBytes = 3 * 8;
constexpr std::size_t kColorBytes = 4 * 4;
// header, ns, id, type, action, pose, scale, color, lifetime, frame_locked,
// points, colors, text, mesh_resource, mesh_use_embedded_materials
constexpr std::size_t kMarkerBytes =
    kHeaderBytes + 4 + 3 * 4 + kPoseBytes + kPointBytes + kColorBytes + 8 + 1 + 4 * 4 + 1;

/// Where in a message a value is, for errors: "nav_msgs/Path: poses[2].header.stamp: ...".
class Place {
 public:
  explicit Place(std::string_view type) : type_(type) {}

  [[noreturn]] void fail(std::string_view field, std::string_view what) const {
    std::string where = prefix_ + std::string(field);
    if (!where.empty() && where.back() == '.') where.pop_back();
    throw Error(where.empty() ? fmt::format("{}: {}", type_, what)
                              : fmt::format("{}: {}: {}", type_, where, what));
  }

  /// While it lives, the fields named are inside `name` (element `index` of it).
  class Within {
   public:
    Within(Place& place, std::string_view name) : place_(place), size_(place.prefix_.size()) {
      place.prefix_.append(name).push_back('.');
    }
    Within(Place& place, std::string_view name, std::size_t index)
        : place_(place), size_(place.prefix_.size()) {
      fmt::format_to(std::back_inserter(place.prefix_), "{}[{}].", name, index);
    }
    ~Within() { place_.prefix_.resize(size_); }
    Within(const Within&) = delete;
    Within& operator=(const Within&) = delete;

   private:
    Place& place_;
    std::size_t size_;
  };

 private:
  std::string_view type_;
  std::string prefix_;
};

// ---- writing ----

class Writer : public Place {
 public:
  using Place::Place;

  template <class T>
  void put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    const std::size_t at = bytes_.size();
    bytes_.resize(at + sizeof(T));
    std::memcpy(bytes_.data() + at, &value, sizeof(T));
  }

  void putCount(std::size_t n, std::string_view field) {
    if (n > std::numeric_limits<std::uint32_t>::max()) {
      fail(field, fmt::format("{} elements, more than a uint32 count holds", n));
    }
    put(static_cast<std::uint32_t>(n));
  }

  void putBytes(std::span<const std::uint8_t> bytes, std::string_view field) {
    putCount(bytes.size(), field);
    bytes_.insert(bytes_.end(), bytes.begin(), bytes.end());
  }

  void putString(const std::string& s, std::string_view field) {
    putBytes({reinterpret_cast<const std::uint8_t*>(s.data()), s.size()}, field);
  }

  /// A time: uint32 seconds since the epoch and nanoseconds.
  void putTime(double seconds, std::string_view field) {
    const auto [sec, nsec] = split(seconds, 0.0, 4294967296.0, field, "a ROS 1 time (uint32 s)");
    put(static_cast<std::uint32_t>(sec));
    put(static_cast<std::uint32_t>(nsec));
  }

  /// A duration: int32 seconds and nanoseconds, these in [0, 10^9) as ROS 1 keeps them.
  void putDuration(double seconds, std::string_view field) {
    const auto [sec, nsec] =
        split(seconds, -2147483648.0, 2147483648.0, field, "a ROS 1 duration (int32 s)");
    put(static_cast<std::int32_t>(sec));
    put(static_cast<std::int32_t>(nsec));
  }

  void putHeader(const msg::Header& h, std::uint32_t seq) {
    const Within header(*this, "header");
    put(seq);
    putTime(h.stamp, "stamp");
    putString(h.frame_id, "frame_id");
  }

  void putVector(const Eigen::Vector3d& v) {
    for (double x : {v.x(), v.y(), v.z()}) put(x);
  }

  /// geometry_msgs/Pose, or Transform (translation, rotation).
  void putPose(const Eigen::Isometry3d& T) {
    putVector(T.translation());
    const Eigen::Quaterniond q(T.rotation());
    for (double x : {q.x(), q.y(), q.z(), q.w()}) put(x);
  }

  void putQuaternion(const Eigen::Quaterniond& q) {
    for (double x : {q.x(), q.y(), q.z(), q.w()}) put(x);
  }

  void putCovariance(const Eigen::Matrix3d& m) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) put(m(r, c));  // row-major
  }

  void putCovariance(const Eigen::Matrix<double, 6, 6>& m) {
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) put(m(r, c));  // row-major
  }

  void putColor(const msg::ColorRGBA& c) {
    for (float x : {c.r, c.g, c.b, c.a}) put(x);
  }

  void reserve(std::size_t n) { bytes_.reserve(n); }
  std::vector<std::uint8_t> take() && { return std::move(bytes_); }

 private:
  /// Whole seconds in [low, high) and nanoseconds in [0, 10^9).
  std::pair<std::int64_t, std::int64_t> split(double seconds, double low, double high,
                                              std::string_view field, std::string_view what) {
    const double whole = std::floor(seconds);
    if (!(whole >= low && whole < high))
      fail(field, fmt::format("{} s cannot be {}", seconds, what));
    auto sec = static_cast<std::int64_t>(whole);
    auto nsec = static_cast<std::int64_t>(std::llround((seconds - whole) * 1e9));
    if (nsec >= 1000000000) {
      ++sec;
      nsec -= 1000000000;
    }
    if (static_cast<double>(sec) >= high) {
      fail(field, fmt::format("{} s cannot be {}", seconds, what));
    }
    return {sec, nsec};
  }

  std::vector<std::uint8_t> bytes_;
};

// ---- reading ----

class Reader : public Place {
 public:
  Reader(std::string_view type, std::span<const std::uint8_t> bytes) : Place(type), bytes_(bytes) {}

  std::span<const std::uint8_t> take(std::size_t n, std::string_view field) {
    if (n > remaining()) {
      fail(field,
           fmt::format("truncated: {} bytes needed at byte {}, {} left", n, at_, remaining()));
    }
    const auto out = bytes_.subspan(at_, n);
    at_ += n;
    return out;
  }

  template <class T>
  T get(std::string_view field) {
    static_assert(std::is_arithmetic_v<T>);
    T value;
    std::memcpy(&value, take(sizeof(T), field).data(), sizeof(T));
    return value;
  }

  bool getBool(std::string_view field) {
    const auto b = get<std::uint8_t>(field);
    if (b > 1) fail(field, fmt::format("{} is not a bool (0 or 1)", b));
    return b == 1;
  }

  /// A variable array's count, refused when even its smallest elements would
  /// not fit in the bytes left.
  std::uint32_t getCount(std::string_view field, std::size_t element_bytes) {
    const auto n = get<std::uint32_t>(field);
    if (n > remaining() / element_bytes) {
      fail(field, fmt::format("count {} needs {} bytes at least, {} left", n,
                              std::uint64_t{n} * element_bytes, remaining()));
    }
    return n;
  }

  std::span<const std::uint8_t> getBytes(std::string_view field) {
    return take(getCount(field, 1), field);
  }

  std::string getString(std::string_view field) {
    const auto bytes = getBytes(field);
    return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
  }

  double getTime(std::string_view field) {
    const auto sec = get<std::uint32_t>(field);
    return seconds(sec, get<std::uint32_t>(field), field);
  }

  double getDuration(std::string_view field) {
    const auto sec = get<std::int32_t>(field);
    const auto nsec = get<std::int32_t>(field);
    if (nsec < 0) fail(field, fmt::format("nsec {} is negative", nsec));
    return seconds(sec, static_cast<std::uint32_t>(nsec), field);
  }

  msg::Header getHeader() {
    const Within header(*this, "header");
    msg::Header h;
    (void)get<std::uint32_t>("seq");
    h.stamp = getTime("stamp");
    h.frame_id = getString("frame_id");
    return h;
  }

  Eigen::Vector3d getVector(std::string_view field) {
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v[i] = get<double>(field);
    return v;
  }

  /// geometry_msgs/Pose, or Transform: `position` and `orientation` name the parts.
  Eigen::Isometry3d getPose(std::string_view position, std::string_view orientation) {
    const Eigen::Vector3d t = getVector(position);
    const Eigen::Quaterniond q = getQuaternion(orientation);
    if (!t.allFinite()) fail(position, "a value is not finite");
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = checkedRotation(q, orientation).toRotationMatrix();
    T.translation() = t;
    return T;
  }

  /// An orientation as it came (an IMU's without an estimate need not be one).
  Eigen::Quaterniond getQuaternion(std::string_view field) {
    Eigen::Quaterniond q;
    q.x() = get<double>(field);
    q.y() = get<double>(field);
    q.z() = get<double>(field);
    q.w() = get<double>(field);
    return q;
  }

  /// `q` normalised, refused unless its norm is within 1 % of 1: as the ROS 2
  /// codec, drivers send quaternions a little off unit norm; none send a zero
  /// one on purpose.
  Eigen::Quaterniond checkedRotation(const Eigen::Quaterniond& q, std::string_view field) const {
    const double norm = q.norm();
    if (!std::isfinite(norm)) fail(field, "a value is not finite");
    if (std::abs(norm - 1.0) > 1e-2) fail(field, fmt::format("the norm is {}, not 1", norm));
    return q.normalized();
  }

  Eigen::Matrix3d getCovariance3(std::string_view field) {
    Eigen::Matrix3d m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m(r, c) = get<double>(field);
    return m;
  }

  Eigen::Matrix<double, 6, 6> getCovariance(std::string_view field) {
    Eigen::Matrix<double, 6, 6> m;
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) m(r, c) = get<double>(field);
    return m;
  }

  msg::ColorRGBA getColor(std::string_view field) {
    msg::ColorRGBA c;
    for (float* x : {&c.r, &c.g, &c.b, &c.a}) *x = get<float>(field);
    return c;
  }

  void finish() {
    if (remaining() > 0) fail("", fmt::format("bytes left after the message: {}", remaining()));
  }

 private:
  [[nodiscard]] std::size_t remaining() const { return bytes_.size() - at_; }

  double seconds(std::int64_t sec, std::uint32_t nsec, std::string_view field) const {
    if (nsec >= 1000000000u) fail(field, fmt::format("nsec {} is not below 10^9", nsec));
    return static_cast<double>(sec) + 1e-9 * static_cast<double>(nsec);
  }

  std::span<const std::uint8_t> bytes_;
  std::size_t at_ = 0;
};

// ---- the messages, field by field in their definitions' order ----

void write(Writer& out, const msg::PointCloud2& m, std::uint32_t seq) {
  out.reserve(64 + 32 * m.fields.size() + m.data.size());
  out.putHeader(m.header, seq);
  out.put(m.height);
  out.put(m.width);
  out.putCount(m.fields.size(), "fields");
  for (const auto& f : m.fields) {
    out.putString(f.name, "fields.name");
    out.put(f.offset);
    out.put(f.datatype);
    out.put(f.count);
  }
  out.put(std::uint8_t{m.is_bigendian});
  out.put(m.point_step);
  out.put(m.row_step);
  out.putBytes(m.data, "data");
  out.put(std::uint8_t{m.is_dense});
}

void read(Reader& in, msg::PointCloud2& m) {
  m.header = in.getHeader();
  m.height = in.get<std::uint32_t>("height");
  m.width = in.get<std::uint32_t>("width");
  m.fields.resize(in.getCount("fields", kPointFieldBytes));
  for (std::size_t i = 0; i < m.fields.size(); ++i) {
    const Place::Within field(in, "fields", i);
    m.fields[i].name = in.getString("name");
    m.fields[i].offset = in.get<std::uint32_t>("offset");
    m.fields[i].datatype = in.get<std::uint8_t>("datatype");
    m.fields[i].count = in.get<std::uint32_t>("count");
  }
  m.is_bigendian = in.getBool("is_bigendian");
  m.point_step = in.get<std::uint32_t>("point_step");
  m.row_step = in.get<std::uint32_t>("row_step");
  const auto data = in.getBytes("data");
  m.data.assign(data.begin(), data.end());
  m.is_dense = in.getBool("is_dense");
}

void write(Writer& out, const msg::Imu& m, std::uint32_t seq) {
  out.putHeader(m.header, seq);
  out.putQuaternion(m.orientation);
  out.putCovariance(m.orientation_covariance);
  out.putVector(m.angular_velocity);
  out.putCovariance(m.angular_velocity_covariance);
  out.putVector(m.linear_acceleration);
  out.putCovariance(m.linear_acceleration_covariance);
}

void read(Reader& in, msg::Imu& m) {
  m.header = in.getHeader();
  m.orientation = in.getQuaternion("orientation");
  m.orientation_covariance = in.getCovariance3("orientation_covariance");
  // An estimate is checked as a pose's orientation is.
  if (m.hasOrientation()) m.orientation = in.checkedRotation(m.orientation, "orientation");
  m.angular_velocity = in.getVector("angular_velocity");
  m.angular_velocity_covariance = in.getCovariance3("angular_velocity_covariance");
  m.linear_acceleration = in.getVector("linear_acceleration");
  m.linear_acceleration_covariance = in.getCovariance3("linear_acceleration_covariance");
}

void write(Writer& out, const msg::Odometry& m, std::uint32_t seq) {
  out.putHeader(m.header, seq);
  out.putString(m.child_frame_id, "child_frame_id");
  out.putPose(m.pose);
  out.putCovariance(m.pose_covariance);
  out.putVector(m.linear_velocity);
  out.putVector(m.angular_velocity);
  out.putCovariance(m.twist_covariance);
}

void read(Reader& in, msg::Odometry& m) {
  m.header = in.getHeader();
  m.child_frame_id = in.getString("child_frame_id");
  {
    const Place::Within pose(in, "pose");
    m.pose = in.getPose("pose.position", "pose.orientation");
    m.pose_covariance = in.getCovariance("covariance");
  }
  const Place::Within twist(in, "twist");
  m.linear_velocity = in.getVector("twist.linear");
  m.angular_velocity = in.getVector("twist.angular");
  m.twist_covariance = in.getCovariance("covariance");
}

void write(Writer& out, const msg::PoseStamped& m, std::uint32_t seq) {
  out.putHeader(m.header, seq);
  out.putPose(m.pose);
}

void read(Reader& in, msg::PoseStamped& m) {
  m.header = in.getHeader();
  m.pose = in.getPose("pose.position", "pose.orientation");
}

void write(Writer& out, const msg::Path& m, std::uint32_t seq) {
  out.putHeader(m.header, seq);
  out.putCount(m.poses.size(), "poses");
  for (std::size_t i = 0; i < m.poses.size(); ++i) {
    const Place::Within pose(out, "poses", i);
    write(out, m.poses[i], 0);
  }
}

void read(Reader& in, msg::Path& m) {
  m.header = in.getHeader();
  m.poses.resize(in.getCount("poses", kPoseStampedBytes));
  for (std::size_t i = 0; i < m.poses.size(); ++i) {
    const Place::Within pose(in, "poses", i);
    read(in, m.poses[i]);
  }
}

void write(Writer& out, const msg::TFMessage& m, std::uint32_t /*seq: no header*/) {
  out.putCount(m.transforms.size(), "transforms");
  for (std::size_t i = 0; i < m.transforms.size(); ++i) {
    const Place::Within transform(out, "transforms", i);
    const msg::TransformStamped& t = m.transforms[i];
    out.putHeader(t.header, 0);
    out.putString(t.child_frame_id, "child_frame_id");
    out.putPose(t.transform);
  }
}

void read(Reader& in, msg::TFMessage& m) {
  m.transforms.resize(in.getCount("transforms", kTransformStampedBytes));
  for (std::size_t i = 0; i < m.transforms.size(); ++i) {
    const Place::Within transform(in, "transforms", i);
    msg::TransformStamped& t = m.transforms[i];
    t.header = in.getHeader();
    t.child_frame_id = in.getString("child_frame_id");
    t.transform = in.getPose("transform.translation", "transform.rotation");
  }
}

void write(Writer& out, const msg::Marker& m) {
  out.putHeader(m.header, 0);
  out.putString(m.ns, "ns");
  out.put(m.id);
  out.put(m.type);
  out.put(m.action);
  out.putPose(m.pose);
  out.putVector(m.scale);
  out.putColor(m.color);
  out.putDuration(m.lifetime, "lifetime");
  out.put(std::uint8_t{m.frame_locked});
  out.putCount(m.points.size(), "points");
  for (const auto& p : m.points) out.putVector(p);
  out.putCount(m.colors.size(), "colors");
  for (const auto& c : m.colors) out.putColor(c);
  out.putString(m.text, "text");
  out.putString({}, "mesh_resource");
  out.put(std::uint8_t{0});  // mesh_use_embedded_materials
}

void read(Reader& in, msg::Marker& m) {
  m.header = in.getHeader();
  m.ns = in.getString("ns");
  m.id = in.get<std::int32_t>("id");
  m.type = in.get<std::int32_t>("type");
  m.action = in.get<std::int32_t>("action");
  m.pose = in.getPose("pose.position", "pose.orientation");
  m.scale = in.getVector("scale");
  m.color = in.getColor("color");
  m.lifetime = in.getDuration("lifetime");
  m.frame_locked = in.getBool("frame_locked");
  m.points.resize(in.getCount("points", kPointBytes));
  for (auto& p : m.points) p = in.getVector("points");
  m.colors.resize(in.getCount("colors", kColorBytes));
  for (auto& c : m.colors) c = in.getColor("colors");
  m.text = in.getString("text");
  (void)in.getBytes("mesh_resource");
  (void)in.getBool("mesh_use_embedded_materials");
}

void write(Writer& out, const msg::MarkerArray& m, std::uint32_t /*seq: no header*/) {
  out.putCount(m.markers.size(), "markers");
  for (std::size_t i = 0; i < m.markers.size(); ++i) {
    const Place::Within marker(out, "markers", i);
    write(out, m.markers[i]);
  }
}

void read(Reader& in, msg::MarkerArray& m) {
  m.markers.resize(in.getCount("markers", kMarkerBytes));
  for (std::size_t i = 0; i < m.markers.size(); ++i) {
    const Place::Within marker(in, "markers", i);
    read(in, m.markers[i]);
  }
}

// ---- each type's name, MD5 sum and full definition, as genpy holds them ----
//
// From Debian's python3-*-msgs (ROS 1 Noetic's message packages): `_type`,
// `_md5sum` and `_full_text` of each message class, what rosbag and a ROS 1
// connection header carry, byte for byte: each type's own definition once,
// composed into the full texts as genpy composes them; the trailing spaces and
// the tabs in them are ROS 1's too (the tests compare them with genpy's).

/// One message type's own definition (its .msg file's text; a few end without
/// a newline, as theirs do).
struct Definition {
  std::string_view name;
  std::string_view text;
};
constexpr Definition kHeader{"std_msgs/Header",
                             R"def(# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data 
# in a particular coordinate frame.
# 
# sequence ID: consecutively increasing ID 
uint32 seq
#Two-integer timestamp that is expressed as:
# * stamp.sec: seconds (stamp_secs) since epoch (in Python the variable is called 'secs')
# * stamp.nsec: nanoseconds since stamp_secs (in Python the variable is called 'nsecs')
# time-handling sugar is provided by the client library
time stamp
#Frame this data is associated with
string frame_id
)def"};
constexpr Definition kPointField{
    "sensor_msgs/PointField", R"def(# This message holds the description of one point entry in the
# PointCloud2 message format.
uint8 INT8    = 1
uint8 UINT8   = 2
uint8 INT16   = 3
uint8 UINT16  = 4
uint8 INT32   = 5
uint8 UINT32  = 6
uint8 FLOAT32 = 7
uint8 FLOAT64 = 8

string name      # Name of field
uint32 offset    # Offset from start of point struct
uint8  datatype  # Datatype enumeration, see above
uint32 count     # How many elements in the field
)def"};
constexpr Definition kPoseWithCovariance{
    "geometry_msgs/PoseWithCovariance",
    R"def(# This represents a pose in free space with uncertainty.

Pose pose

# Row-major representation of the 6x6 covariance matrix
# The orientation parameters use a fixed-axis representation.
# In order, the parameters are:
# (x, y, z, rotation about X axis, rotation about Y axis, rotation about Z axis)
float64[36] covariance
)def"};
constexpr Definition kPose{
    "geometry_msgs/Pose",
    R"def(# A representation of pose in free space, composed of position and orientation. 
Point position
Quaternion orientation
)def"};
constexpr Definition kPoint{"geometry_msgs/Point",
                            R"def(# This contains the position of a point in free space
float64 x
float64 y
float64 z
)def"};
constexpr Definition kQuaternion{
    "geometry_msgs/Quaternion",
    R"def(# This represents an orientation in free space in quaternion form.

float64 x
float64 y
float64 z
float64 w
)def"};
constexpr Definition kTwistWithCovariance{
    "geometry_msgs/TwistWithCovariance",
    R"def(# This expresses velocity in free space with uncertainty.

Twist twist

# Row-major representation of the 6x6 covariance matrix
# The orientation parameters use a fixed-axis representation.
# In order, the parameters are:
# (x, y, z, rotation about X axis, rotation about Y axis, rotation about Z axis)
float64[36] covariance
)def"};
constexpr Definition kTwist{
    "geometry_msgs/Twist",
    R"def(# This expresses velocity in free space broken into its linear and angular parts.
Vector3  linear
Vector3  angular
)def"};
constexpr Definition kVector3{"geometry_msgs/Vector3",
                              R"def(# This represents a vector in free space. 
# It is only meant to represent a direction. Therefore, it does not
# make sense to apply a translation to it (e.g., when applying a 
# generic rigid transformation to a Vector3, tf2 will only apply the
# rotation). If you want your data to be translatable too, use the
# geometry_msgs/Point message instead.

float64 x
float64 y
float64 z)def"};
constexpr Definition kPoseStamped{"geometry_msgs/PoseStamped",
                                  R"def(# A Pose with reference coordinate frame and timestamp
Header header
Pose pose
)def"};
constexpr Definition kTransformStamped{
    "geometry_msgs/TransformStamped",
    R"def(# This expresses a transform from coordinate frame header.frame_id
# to the coordinate frame child_frame_id
#
# This message is mostly used by the 
# <a href="http://wiki.ros.org/tf">tf</a> package. 
# See its documentation for more information.

Header header
string child_frame_id # the frame id of the child frame
Transform transform
)def"};
constexpr Definition kTransform{
    "geometry_msgs/Transform",
    R"def(# This represents the transform between two coordinate frames in free space.

Vector3 translation
Quaternion rotation
)def"};
constexpr Definition kMarker{
    "visualization_msgs/Marker",
    R"def(# See http://www.ros.org/wiki/rviz/DisplayTypes/Marker and http://www.ros.org/wiki/rviz/Tutorials/Markers%3A%20Basic%20Shapes for more information on using this message with rviz

uint8 ARROW=0
uint8 CUBE=1
uint8 SPHERE=2
uint8 CYLINDER=3
uint8 LINE_STRIP=4
uint8 LINE_LIST=5
uint8 CUBE_LIST=6
uint8 SPHERE_LIST=7
uint8 POINTS=8
uint8 TEXT_VIEW_FACING=9
uint8 MESH_RESOURCE=10
uint8 TRIANGLE_LIST=11

uint8 ADD=0
uint8 MODIFY=0
uint8 DELETE=2
uint8 DELETEALL=3

Header header                        # header for time/frame information
string ns                            # Namespace to place this object in... used in conjunction with id to create a unique name for the object
int32 id 		                         # object ID useful in conjunction with the namespace for manipulating and deleting the object later
int32 type 		                       # Type of object
int32 action 	                       # 0 add/modify an object, 1 (deprecated), 2 deletes an object, 3 deletes all objects
geometry_msgs/Pose pose                 # Pose of the object
geometry_msgs/Vector3 scale             # Scale of the object 1,1,1 means default (usually 1 meter square)
std_msgs/ColorRGBA color             # Color [0.0-1.0]
duration lifetime                    # How long the object should last before being automatically deleted.  0 means forever
bool frame_locked                    # If this marker should be frame-locked, i.e. retransformed into its frame every timestep

#Only used if the type specified has some use for them (eg. POINTS, LINE_STRIP, ...)
geometry_msgs/Point[] points
#Only used if the type specified has some use for them (eg. POINTS, LINE_STRIP, ...)
#number of colors must either be 0 or equal to the number of points
#NOTE: alpha is not yet used
std_msgs/ColorRGBA[] colors

# NOTE: only used for text markers
string text

# NOTE: only used for MESH_RESOURCE markers
string mesh_resource
bool mesh_use_embedded_materials
)def"};
constexpr Definition kColorRGBA{"std_msgs/ColorRGBA", R"def(float32 r
float32 g
float32 b
float32 a
)def"};
constexpr Definition kPointCloud2{
    "sensor_msgs/PointCloud2",
    R"def(# This message holds a collection of N-dimensional points, which may
# contain additional information such as normals, intensity, etc. The
# point data is stored as a binary blob, its layout described by the
# contents of the "fields" array.

# The point cloud data may be organized 2d (image-like) or 1d
# (unordered). Point clouds organized as 2d images may be produced by
# camera depth sensors such as stereo or time-of-flight.

# Time of sensor data acquisition, and the coordinate frame ID (for 3d
# points).
Header header

# 2D structure of the point cloud. If the cloud is unordered, height is
# 1 and width is the length of the point cloud.
uint32 height
uint32 width

# Describes the channels and their layout in the binary data blob.
PointField[] fields

bool    is_bigendian # Is this data bigendian?
uint32  point_step   # Length of a point in bytes
uint32  row_step     # Length of a row in bytes
uint8[] data         # Actual point data, size is (row_step*height)

bool is_dense        # True if there are no invalid points
)def"};
constexpr Definition kImu{
    "sensor_msgs/Imu",
    R"def(# This is a message to hold data from an IMU (Inertial Measurement Unit)
#
# Accelerations should be in m/s^2 (not in g's), and rotational velocity should be in rad/sec
#
# If the covariance of the measurement is known, it should be filled in (if all you know is the 
# variance of each measurement, e.g. from the datasheet, just put those along the diagonal)
# A covariance matrix of all zeros will be interpreted as "covariance unknown", and to use the
# data a covariance will have to be assumed or gotten from some other source
#
# If you have no estimate for one of the data elements (e.g. your IMU doesn't produce an orientation 
# estimate), please set element 0 of the associated covariance matrix to -1
# If you are interpreting this message, please check for a value of -1 in the first element of each 
# covariance matrix, and disregard the associated estimate.

Header header

geometry_msgs/Quaternion orientation
float64[9] orientation_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance # Row major x, y z 
)def"};
constexpr Definition kOdometry{
    "nav_msgs/Odometry",
    R"def(# This represents an estimate of a position and velocity in free space.  
# The pose in this message should be specified in the coordinate frame given by header.frame_id.
# The twist in this message should be specified in the coordinate frame given by the child_frame_id
Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
)def"};
constexpr Definition kPath{"nav_msgs/Path",
                           R"def(#An array of poses that represents a Path for a robot to follow
Header header
geometry_msgs/PoseStamped[] poses
)def"};
constexpr Definition kTFMessage{"tf2_msgs/TFMessage",
                                R"def(geometry_msgs/TransformStamped[] transforms
)def"};
constexpr Definition kMarkerArray{"visualization_msgs/MarkerArray", R"def(Marker[] markers
)def"};
/// A type's full definition as genpy writes it: its own, then that of each
/// type it uses, each after a line of '=' and "MSG: <type>".
std::string fullText(const Definition& type, std::initializer_list<Definition> uses) {
  std::string text(type.text);
  for (const Definition& use : uses) {
    text += "\n" + std::string(80, '=') + "\nMSG: ";
    text += use.name;
    text += "\n";
    text += use.text;
  }
  return text;
}

}  // namespace

template <>
const MessageType& messageType<msg::PointCloud2>() {
  static const std::string text = fullText(kPointCloud2, {kHeader, kPointField});
  static const MessageType type{"sensor_msgs/PointCloud2", "1158d486dd51d683ce2f1be655c3c181",
                                text};
  return type;
}
template <>
const MessageType& messageType<msg::Imu>() {
  static const std::string text = fullText(kImu, {kHeader, kQuaternion, kVector3});
  static const MessageType type{"sensor_msgs/Imu", "6a62c6daae103f4ff57a132d6f95cec2", text};
  return type;
}
template <>
const MessageType& messageType<msg::Odometry>() {
  static const std::string text =
      fullText(kOdometry, {kHeader, kPoseWithCovariance, kPose, kPoint, kQuaternion,
                           kTwistWithCovariance, kTwist, kVector3});
  static const MessageType type{"nav_msgs/Odometry", "cd5e73d190d741a2f92e81eda573aca7", text};
  return type;
}
template <>
const MessageType& messageType<msg::PoseStamped>() {
  static const std::string text = fullText(kPoseStamped, {kHeader, kPose, kPoint, kQuaternion});
  static const MessageType type{"geometry_msgs/PoseStamped", "d3812c3cbc69362b77dc0b19b345f8f5",
                                text};
  return type;
}
template <>
const MessageType& messageType<msg::Path>() {
  static const std::string text =
      fullText(kPath, {kHeader, kPoseStamped, kPose, kPoint, kQuaternion});
  static const MessageType type{"nav_msgs/Path", "6227e2b7e9cce15051f669a5e197bbf7", text};
  return type;
}
template <>
const MessageType& messageType<msg::TFMessage>() {
  static const std::string text =
      fullText(kTFMessage, {kTransformStamped, kHeader, kTransform, kVector3, kQuaternion});
  static const MessageType type{"tf2_msgs/TFMessage", "94810edda583a504dfda3829e70d7eec", text};
  return type;
}
template <>
const MessageType& messageType<msg::MarkerArray>() {
  static const std::string text =
      fullText(kMarkerArray, {kMarker, kHeader, kPose, kPoint, kQuaternion, kVector3, kColorRGBA});
  static const MessageType type{"visualization_msgs/MarkerArray",
                                "d155b9ce5188fbaf89745847fd5882d7", text};
  return type;
}

template <class M>
M decode(std::span<const std::uint8_t> bytes) {
  Reader in(messageType<M>().name, bytes);
  M m;
  read(in, m);
  in.finish();
  return m;
}

#define DCL_ROS1_MESSAGE(M)                                               \
  template M decode<M>(std::span<const std::uint8_t>);                    \
  std::vector<std::uint8_t> encode(const M& message, std::uint32_t seq) { \
    Writer out(messageType<M>().name);                                    \
    write(out, message, seq);                                             \
    return std::move(out).take();                                         \
  }
DCL_ROS1_MESSAGE(msg::PointCloud2)
DCL_ROS1_MESSAGE(msg::Imu)
DCL_ROS1_MESSAGE(msg::Odometry)
DCL_ROS1_MESSAGE(msg::PoseStamped)
DCL_ROS1_MESSAGE(msg::Path)
DCL_ROS1_MESSAGE(msg::TFMessage)
DCL_ROS1_MESSAGE(msg::MarkerArray)
#undef DCL_ROS1_MESSAGE

}  // namespace dcl::ros1
