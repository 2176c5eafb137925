// ROS 2 bags in MCAP: io::McapReader and io::McapWriter carry the messages,
// the ROS 2 codec (ros2_messages.hpp) turns them into values and back. An
// MCAP "cdr" message is a DDS sample's serialised payload: the 4-byte
// encapsulation header, then CDR, exactly what the codec reads and writes.
#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/point_cloud2.hpp>
#include <dcl/ros/ros2_bag.hpp>
#include <dcl/ros/ros2_messages.hpp>
#include <dcl/version.hpp>

namespace dcl::ros2 {

namespace {

constexpr std::string_view kCloudType = "sensor_msgs/msg/PointCloud2";
constexpr std::string_view kOdometryType = "nav_msgs/msg/Odometry";
constexpr std::string_view kPoseStampedType = "geometry_msgs/msg/PoseStamped";
constexpr std::string_view kImuType = "sensor_msgs/msg/Imu";

// The .msg definitions of ROS 2 (Humble and later), comments left out, as
// rosbag2 concatenates them into a schema.
constexpr std::string_view kHeaderMsg = "builtin_interfaces/Time stamp\nstring frame_id\n";
constexpr std::string_view kTimeMsg = "int32 sec\nuint32 nanosec\n";
constexpr std::string_view kPointFieldMsg = R"(uint8 INT8    = 1
uint8 UINT8   = 2
uint8 INT16   = 3
uint8 UINT16  = 4
uint8 INT32   = 5
uint8 UINT32  = 6
uint8 FLOAT32 = 7
uint8 FLOAT64 = 8
string name
uint32 offset
uint8  datatype
uint32 count
)";
constexpr std::string_view kPointCloud2Msg = R"(std_msgs/Header header
uint32 height
uint32 width
PointField[] fields
bool    is_bigendian
uint32  point_step
uint32  row_step
uint8[] data
bool is_dense
)";
constexpr std::string_view kOdometryMsg = R"(std_msgs/Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
)";
constexpr std::string_view kImuMsg = R"(std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
)";
constexpr std::string_view kPoseStampedMsg = "std_msgs/Header header\nPose pose\n";
constexpr std::string_view kPoseWithCovarianceMsg = "Pose pose\nfloat64[36] covariance\n";
constexpr std::string_view kTwistWithCovarianceMsg = "Twist twist\nfloat64[36] covariance\n";
constexpr std::string_view kPoseMsg = "Point position\nQuaternion orientation\n";
constexpr std::string_view kPointMsg = "float64 x\nfloat64 y\nfloat64 z\n";
constexpr std::string_view kQuaternionMsg = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n";
constexpr std::string_view kTwistMsg = "Vector3  linear\nVector3  angular\n";
constexpr std::string_view kVector3Msg = "float64 x\nfloat64 y\nfloat64 z\n";

/// A definition and the ones it uses, each after "MSG: pkg/Type".
std::string concatenated(
    std::string_view main,
    std::initializer_list<std::pair<std::string_view, std::string_view>> used) {
  std::string out(main);
  for (const auto& [type, msg] : used) {
    out += std::string(80, '=') + "\nMSG: " + std::string(type) + "\n" + std::string(msg);
  }
  return out;
}

/// "sensor_msgs/PointCloud2" for "sensor_msgs/msg/PointCloud2" and for itself.
std::string rosOneName(std::string_view type) {
  std::string out(type);
  if (const auto at = out.find("/msg/"); at != std::string::npos) out.erase(at, 4);
  return out;
}

[[noreturn]] void failTopic(const std::string& path, const std::string& topic,
                            const std::string& what) {
  throw core::FileError({path}, fmt::format("topic '{}': {}", topic, what));
}

[[noreturn]] void failMessage(const std::string& path, const std::string& topic, std::size_t i,
                              const std::string& what) {
  throw core::FileError({path}, fmt::format("topic '{}' message {}: {}", topic, i, what));
}

std::string typeOf(const io::McapReader& file, const io::McapChannel& c) {
  const io::McapSchema* schema = file.schemaOf(c);
  return schema != nullptr ? schema->name : std::string("(no schema)");
}

std::vector<io::BagTopic> topicsOf(const io::McapReader& file) {
  std::map<std::string, io::BagTopic> topics;
  std::map<std::uint16_t, std::string> names;
  for (const io::McapChannel& c : file.channels()) {
    io::BagTopic& t = topics[c.topic];
    t.name = c.topic;
    const std::string type = typeOf(file, c);
    if (t.type.empty()) t.type = type;
    if (t.type.find(type) == std::string::npos) t.type.append(",").append(type);
    names[c.id] = c.topic;
  }
  for (const io::McapMessageRef& m : file.messages()) ++topics[names[m.channel_id]].messages;
  std::vector<io::BagTopic> out;
  for (auto& [name, t] : topics) out.push_back(std::move(t));
  return out;
}

std::string describeTopics(const io::McapReader& file) {
  return io::describeTopics(topicsOf(file));
}

/// The messages of `topic`, in log-time order; throws unless the topic exists
/// and every channel on it carries CDR messages of one of `types`.
std::vector<io::McapMessageRef> topicMessages(const io::McapReader& file, const std::string& topic,
                                              const std::vector<std::string_view>& types) {
  std::vector<std::uint16_t> ids;
  for (const io::McapChannel& c : file.channels()) {
    if (!io::sameTopic(c.topic, topic)) continue;
    const std::string type = rosOneName(typeOf(file, c));
    const bool known = std::any_of(types.begin(), types.end(),
                                   [&](std::string_view t) { return rosOneName(t) == type; });
    if (!known) {
      std::string expected;
      for (const auto t : types) expected.append(expected.empty() ? "" : " or ").append(t);
      failTopic(file.path(), topic,
                fmt::format("type is {}, expected {}", typeOf(file, c), expected));
    }
    if (c.message_encoding != "cdr") {
      failTopic(file.path(), topic,
                fmt::format("message encoding '{}', expected cdr (ROS 2)", c.message_encoding));
    }
    ids.push_back(c.id);
  }
  if (ids.empty()) {
    failTopic(file.path(), topic,
              fmt::format("no such topic in the file; its topics: {}", describeTopics(file)));
  }
  return file.messages(ids);
}

std::uint64_t nanoseconds(const std::string& path, double stamp) {
  if (!(stamp >= 0.0) || stamp > 1.8e10) {
    throw core::FileError({path}, fmt::format("stamp {} s cannot be an MCAP time", stamp));
  }
  return static_cast<std::uint64_t>(std::llround(stamp * 1e9));
}

}  // namespace

const std::string& messageDefinition(std::string_view type) {
  static const std::string cloud =
      concatenated(kPointCloud2Msg, {{"std_msgs/Header", kHeaderMsg},
                                     {"builtin_interfaces/Time", kTimeMsg},
                                     {"sensor_msgs/PointField", kPointFieldMsg}});
  static const std::string odometry =
      concatenated(kOdometryMsg, {{"std_msgs/Header", kHeaderMsg},
                                  {"builtin_interfaces/Time", kTimeMsg},
                                  {"geometry_msgs/PoseWithCovariance", kPoseWithCovarianceMsg},
                                  {"geometry_msgs/Pose", kPoseMsg},
                                  {"geometry_msgs/Point", kPointMsg},
                                  {"geometry_msgs/Quaternion", kQuaternionMsg},
                                  {"geometry_msgs/TwistWithCovariance", kTwistWithCovarianceMsg},
                                  {"geometry_msgs/Twist", kTwistMsg},
                                  {"geometry_msgs/Vector3", kVector3Msg}});
  static const std::string pose =
      concatenated(kPoseStampedMsg, {{"std_msgs/Header", kHeaderMsg},
                                     {"builtin_interfaces/Time", kTimeMsg},
                                     {"geometry_msgs/Pose", kPoseMsg},
                                     {"geometry_msgs/Point", kPointMsg},
                                     {"geometry_msgs/Quaternion", kQuaternionMsg}});
  static const std::string imu =
      concatenated(kImuMsg, {{"std_msgs/Header", kHeaderMsg},
                             {"builtin_interfaces/Time", kTimeMsg},
                             {"geometry_msgs/Quaternion", kQuaternionMsg},
                             {"geometry_msgs/Vector3", kVector3Msg}});
  if (type == kCloudType) return cloud;
  if (type == kImuType) return imu;
  if (type == kOdometryType) return odometry;
  if (type == kPoseStampedType) return pose;
  throw core::Error(fmt::format("no ROS 2 message definition of {}", type));
}

std::vector<io::BagTopic> listMcapTopics(const std::string& path) {
  return topicsOf(io::McapReader(path));
}

// ---- clouds ----

struct McapCloudReader::Impl {
  std::string topic;
  io::BagCloudOptions options;
  io::McapReader file;
  std::vector<io::McapMessageRef> messages;
  std::size_t index = 0;

  Impl(const std::string& path, std::string topic_name, const io::BagCloudOptions& o)
      : topic(std::move(topic_name)), options(o), file(path) {}
};

McapCloudReader::McapCloudReader(const std::string& path, const std::string& topic,
                                 const io::BagCloudOptions& options)
    : impl_(std::make_unique<Impl>(path, topic, options)) {
  impl_->messages = topicMessages(impl_->file, topic, {kCloudType});
}

McapCloudReader::~McapCloudReader() = default;
McapCloudReader::McapCloudReader(McapCloudReader&&) noexcept = default;
McapCloudReader& McapCloudReader::operator=(McapCloudReader&&) noexcept = default;

std::size_t McapCloudReader::size() const {
  return impl_->messages.size();
}
std::size_t McapCloudReader::index() const {
  return impl_->index;
}

std::optional<io::StampedCloud> McapCloudReader::next() {
  if (impl_->index >= impl_->messages.size()) return std::nullopt;
  const std::size_t i = impl_->index++;
  const io::McapMessage m = impl_->file.read(impl_->messages[i]);
  try {
    const PointCloud2 msg = decode<PointCloud2>(m.data);
    return io::StampedCloud{msg.header.stamp, io::decodePointCloud2(msg.view(), msg.header.stamp,
                                                                    impl_->options.drop_nan)};
  } catch (const std::exception& e) {
    failMessage(impl_->file.path(), impl_->topic, i, e.what());
  }
}

std::vector<io::StampedCloud> readMcapClouds(const std::string& path, const std::string& topic,
                                             const io::BagCloudOptions& options) {
  McapCloudReader reader(path, topic, options);
  std::vector<io::StampedCloud> clouds;
  clouds.reserve(reader.size());
  while (auto cloud = reader.next()) clouds.push_back(std::move(*cloud));
  return clouds;
}

// ---- poses ----

core::Trajectory readMcapTrajectory(const std::string& path, const std::string& topic) {
  io::McapReader file(path);
  const auto messages = topicMessages(file, topic, {kOdometryType, kPoseStampedType});
  std::map<std::uint16_t, bool> is_odometry;
  for (const io::McapChannel& c : file.channels()) {
    is_odometry[c.id] = rosOneName(typeOf(file, c)) == rosOneName(kOdometryType);
  }
  core::Trajectory trajectory;
  trajectory.reserve(messages.size());
  for (std::size_t i = 0; i < messages.size(); ++i) {
    const io::McapMessage m = file.read(messages[i]);
    try {
      if (is_odometry[m.channel_id]) {
        const Odometry odometry = decode<Odometry>(m.data);
        trajectory.push_back(odometry.header.stamp, odometry.pose);
      } else {
        const PoseStamped pose = decode<PoseStamped>(m.data);
        trajectory.push_back(pose.header.stamp, pose.pose);
      }
    } catch (const std::exception& e) {
      failMessage(path, topic, i, e.what());
    }
  }
  return trajectory;
}

// ---- scan source ----

McapScanSource::McapScanSource(std::string path, std::string topic)
    : path_(std::move(path)), topic_(std::move(topic)) {
  McapCloudReader reader(path_, topic_);
  stamps_.reserve(reader.size());
  while (auto cloud = reader.next()) stamps_.push_back(cloud->stamp);
  if (stamps_.empty()) throw core::FileError({path_}, "topic '" + topic_ + "' has no messages");
  origin_ = stamps_.front();
  for (double& s : stamps_) s -= origin_;
}

McapScanSource::~McapScanSource() = default;

double McapScanSource::stamp(std::size_t i) const {
  if (i >= stamps_.size()) {
    throw core::Error(fmt::format("{}: no scan {} (it has {})", describe(), i, stamps_.size()));
  }
  return stamps_[i];
}

core::PointCloud McapScanSource::scan(std::size_t i) const {
  (void)stamp(i);  // in range
  const std::lock_guard lock(mutex_);
  if (!reader_ || reader_->index() > i) reader_ = std::make_unique<McapCloudReader>(path_, topic_);
  while (reader_->index() < i) reader_->next();
  auto cloud = reader_->next();
  if (!cloud) {
    throw core::FileError({path_}, fmt::format("topic '{}' ended before scan {}", topic_, i));
  }
  return std::move(cloud->cloud);
}

std::vector<msg::Imu> readMcapImu(const std::string& path, const std::string& topic) {
  io::McapReader file(path);
  const auto messages = topicMessages(file, topic, {kImuType});
  std::vector<msg::Imu> out;
  out.reserve(messages.size());
  for (std::size_t i = 0; i < messages.size(); ++i) {
    const io::McapMessage m = file.read(messages[i]);
    try {
      out.push_back(decode<Imu>(m.data));
    } catch (const core::Error& e) {
      failMessage(path, topic, i, e.what());
    }
  }
  return out;
}

std::string McapScanSource::describe() const {
  return "mcap " + path_ + " topic " + topic_;
}

// ---- writing ----

struct McapBagWriter::Impl {
  std::string path;
  io::McapWriter file;
  std::map<std::string, std::uint16_t> channels;  ///< by topic
  std::map<std::string, std::uint16_t> schemas;   ///< by type

  Impl(std::string p, io::McapWriteOptions options)
      : path(std::move(p)), file(path, std::move(options)) {}

  std::uint16_t channel(const std::string& topic, std::string_view type) {
    if (const auto found = channels.find(topic); found != channels.end()) return found->second;
    auto [schema, added] = schemas.try_emplace(std::string(type), 0);
    if (added) schema->second = file.addSchema(schema->first, "ros2msg", messageDefinition(type));
    return channels[topic] = file.addChannel(schema->second, topic, "cdr");
  }

  void write(const std::string& topic, std::string_view type, double stamp,
             const std::vector<std::uint8_t>& bytes) {
    const std::uint64_t time = nanoseconds(path, stamp);
    file.write(channel(topic, type), time, time, bytes);
  }
};

McapBagWriter::McapBagWriter(std::string path, io::McapWriteOptions options)
    : impl_(std::make_unique<Impl>(std::move(path), [&] {
        options.library = std::string("dcl-slam ") + kVersion;
        return options;
      }())) {}

McapBagWriter::~McapBagWriter() = default;

void McapBagWriter::writeCloud(const std::string& topic, double stamp,
                               const core::PointCloud& cloud, const std::string& frame_id) {
  impl_->write(topic, kCloudType, stamp, encode(toPointCloud2(cloud, {stamp, frame_id})));
}

void McapBagWriter::writeOdometry(const std::string& topic, double stamp,
                                  const Eigen::Isometry3d& T_frame_child,
                                  const std::string& frame_id, const std::string& child_frame_id) {
  Odometry m;
  m.header = {stamp, frame_id};
  m.child_frame_id = child_frame_id;
  m.pose = T_frame_child;
  impl_->write(topic, kOdometryType, stamp, encode(m));
}

void McapBagWriter::writePose(const std::string& topic, double stamp,
                              const Eigen::Isometry3d& T_frame_body, const std::string& frame_id) {
  impl_->write(topic, kPoseStampedType, stamp,
               encode(PoseStamped{{stamp, frame_id}, T_frame_body}));
}

void McapBagWriter::writeImu(const std::string& topic, const msg::Imu& imu) {
  impl_->write(topic, kImuType, imu.header.stamp, encode(imu));
}

void McapBagWriter::close() {
  impl_->file.close();
}

}  // namespace dcl::ros2
