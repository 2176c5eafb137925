// ROS1 bags are read by our own bounded reader of the record layer
// (bag_file.hpp); messages are decoded from their ROS1 serialisation
// (little-endian, strings and arrays prefixed by a uint32 length) by the
// bounds-checked ByteReader, after checking each connection's md5sum names the
// definition decoded here.
#include <algorithm>
#include <array>
#include <map>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/point_cloud2.hpp>
#include <dcl/io/rosbag.hpp>

#include "bag_file.hpp"
#include "point_fields.hpp"

namespace dcl::io {

namespace {

/// A message type this file decodes, with the md5sum of its definition.
struct KnownType {
  std::string_view name;
  std::string_view md5;
};
constexpr KnownType kCloudMessage = {"sensor_msgs/PointCloud2", "1158d486dd51d683ce2f1be655c3c181"};
constexpr KnownType kOdometryMessage = {"nav_msgs/Odometry", "cd5e73d190d741a2f92e81eda573aca7"};
constexpr KnownType kPoseStampedType = {"geometry_msgs/PoseStamped",
                                        "d3812c3cbc69362b77dc0b19b345f8f5"};
constexpr KnownType kPoseCovarianceType = {"geometry_msgs/PoseWithCovarianceStamped",
                                           "953b798c0f514ff060a53a3498ce6246"};

bool onTopic(const detail::BagConnection& c, const std::string& topic) {
  return sameTopic(c.topic, topic);
}

[[noreturn]] void failTopic(const std::string& path, const std::string& topic,
                            const std::string& what) {
  throw core::FileError({path}, fmt::format("topic '{}': {}", topic, what));
}

[[noreturn]] void failMessage(const std::string& path, const std::string& topic, std::size_t i,
                              const std::string& what) {
  throw core::FileError({path}, fmt::format("topic '{}' message {}: {}", topic, i, what));
}

std::vector<BagTopic> topicsOf(const detail::BagFile& bag) {
  std::map<std::string, BagTopic> topics;
  for (const auto& c : bag.connections()) {
    BagTopic& t = topics[c.topic];
    t.name = c.topic;
    if (t.type.empty()) t.type = c.type;
    if (t.type.find(c.type) == std::string::npos) t.type.append(",").append(c.type);
  }
  for (const auto& m : bag.messages([](const detail::BagConnection&) { return true; })) {
    ++topics[bag.connections()[m.connection].topic].messages;
  }
  std::vector<BagTopic> out;
  for (auto& [name, t] : topics) out.push_back(std::move(t));
  return out;
}

std::string describeTopics(const detail::BagFile& bag) {
  return describeTopics(topicsOf(bag));
}

/// The messages of `topic`, in time order; throws unless the topic exists and
/// every connection on it has one of `types`.
std::vector<detail::BagMessage> topicMessages(const detail::BagFile& bag, const std::string& topic,
                                              const std::vector<KnownType>& types) {
  bool found = false;
  for (const auto& c : bag.connections()) {
    if (!onTopic(c, topic)) continue;
    found = true;
    const auto known = std::find_if(types.begin(), types.end(),
                                    [&](const KnownType& t) { return t.name == c.type; });
    std::string expected;
    for (const auto& t : types) expected.append(expected.empty() ? "" : " or ").append(t.name);
    if (known == types.end()) {
      failTopic(bag.path(), topic, fmt::format("type is {}, expected {}", c.type, expected));
    }
    if (known->md5 != c.md5sum) {
      failTopic(bag.path(), topic,
                fmt::format("{} with md5sum {}, not the known definition {}", c.type, c.md5sum,
                            known->md5));
    }
  }
  if (!found) {
    failTopic(bag.path(), topic,
              fmt::format("no such topic in the bag; its topics: {}", describeTopics(bag)));
  }
  return bag.messages([&](const detail::BagConnection& c) { return onTopic(c, topic); });
}

// ---- ROS1 serialisation ----

std::string readString(ByteReader& in, const char* what) {
  const auto n = in.read<std::uint32_t>(what);
  const auto bytes = in.take(n, what);
  return {bytes.data(), bytes.size()};
}

/// A std_msgs/Header; returns its stamp in seconds.
double readHeaderStamp(ByteReader& in) {
  in.skip(4, "header.seq");
  const auto secs = in.read<std::uint32_t>("header.stamp.sec");
  const auto nsecs = in.read<std::uint32_t>("header.stamp.nsec");
  readString(in, "header.frame_id");
  return secs + nsecs * 1e-9;
}

struct RosCloud {
  double stamp = 0.0;
  PointCloud2View view;
};

std::vector<PointField> readFields(ByteReader& in) {
  const auto n = in.read<std::uint32_t>("fields length");
  std::vector<PointField> fields;
  fields.reserve(std::min<std::size_t>(n, in.remaining() / 13));  // 13 bytes a field at least
  for (std::uint32_t i = 0; i < n; ++i) {
    PointField f;
    f.name = readString(in, "field name");
    f.offset = in.read<std::uint32_t>("field offset");
    f.datatype = in.read<std::uint8_t>("field datatype");
    f.count = in.read<std::uint32_t>("field count");
    fields.push_back(std::move(f));
  }
  return fields;
}

RosCloud readCloud(ByteReader& in) {
  RosCloud c;
  c.stamp = readHeaderStamp(in);
  PointCloud2View& v = c.view;
  v.height = in.read<std::uint32_t>("height");
  v.width = in.read<std::uint32_t>("width");
  v.fields = readFields(in);
  v.is_bigendian = in.read<std::uint8_t>("is_bigendian") != 0;
  v.point_step = in.read<std::uint32_t>("point_step");
  v.row_step = in.read<std::uint32_t>("row_step");
  const std::span<const char> data = in.take(in.read<std::uint32_t>("data length"), "data");
  v.data = {reinterpret_cast<const std::uint8_t*>(data.data()), data.size()};
  in.skip(1, "is_dense");
  return c;
}

// ---- poses ----

Eigen::Isometry3d readPose(ByteReader& in) {
  std::array<double, 7> v{};  // position x y z, orientation x y z w
  in.readInto(v.data(), sizeof(v), "pose");
  const Eigen::Vector3d t(v[0], v[1], v[2]);
  const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (!t.allFinite() || !q.coeffs().allFinite() || q.norm() < 1e-9) {
    in.fail(fmt::format("pose ({} {} {}; {} {} {} {}) is not a rigid transform", v[0], v[1], v[2],
                        v[3], v[4], v[5], v[6]));
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = t;
  return T;
}

std::pair<double, Eigen::Isometry3d> readStampedPose(ByteReader& in, std::string_view type) {
  const double stamp = readHeaderStamp(in);
  if (type == kOdometryMessage.name) readString(in, "child_frame_id");
  return {stamp, readPose(in)};
}

}  // namespace

bool sameTopic(std::string_view a, std::string_view b) {
  const auto bare = [](std::string_view topic) {
    while (!topic.empty() && topic.front() == '/') topic.remove_prefix(1);
    return topic;
  };
  return bare(a) == bare(b);
}

std::string describeTopics(const std::vector<BagTopic>& topics) {
  std::string list;
  for (const auto& t : topics) {
    list.append(list.empty() ? "" : ", ").append(t.name).append(" (").append(t.type).append(")");
  }
  return list.empty() ? "none" : list;
}

std::vector<BagTopic> listBagTopics(const std::string& path) {
  return topicsOf(detail::BagFile(path));
}

struct BagCloudReader::Impl {
  std::string topic;
  BagCloudOptions options;
  detail::BagFile bag;
  std::vector<detail::BagMessage> messages;
  std::size_t index = 0;

  Impl(const std::string& path, std::string topic_name, const BagCloudOptions& o)
      : topic(std::move(topic_name)), options(o), bag(path) {}
};

BagCloudReader::BagCloudReader(const std::string& path, const std::string& topic,
                               const BagCloudOptions& options)
    : impl_(std::make_unique<Impl>(path, topic, options)) {
  impl_->messages = topicMessages(impl_->bag, topic, {kCloudMessage});
}

BagCloudReader::~BagCloudReader() = default;
BagCloudReader::BagCloudReader(BagCloudReader&&) noexcept = default;
BagCloudReader& BagCloudReader::operator=(BagCloudReader&&) noexcept = default;

std::size_t BagCloudReader::size() const {
  return impl_->messages.size();
}
std::size_t BagCloudReader::index() const {
  return impl_->index;
}

std::optional<StampedCloud> BagCloudReader::next() {
  if (impl_->index >= impl_->messages.size()) return std::nullopt;
  const std::size_t i = impl_->index++;
  const std::span<const char> bytes = impl_->bag.read(impl_->messages[i]);
  try {
    ByteReader in(bytes, "message bytes");
    const RosCloud msg = readCloud(in);
    return StampedCloud{msg.stamp, decodePointCloud2(msg.view, msg.stamp, impl_->options.drop_nan)};
  } catch (const std::exception& e) {
    failMessage(impl_->bag.path(), impl_->topic, i, e.what());
  }
}

std::vector<StampedCloud> readBagClouds(const std::string& path, const std::string& topic,
                                        const BagCloudOptions& options) {
  BagCloudReader reader(path, topic, options);
  std::vector<StampedCloud> clouds;
  clouds.reserve(reader.size());
  while (auto cloud = reader.next()) clouds.push_back(std::move(*cloud));
  return clouds;
}

std::vector<RawBagMessage> readBagMessages(const std::string& path, const std::string& topic,
                                           std::string_view type, std::string_view md5sum) {
  detail::BagFile bag(path);
  const auto messages = topicMessages(bag, topic, {KnownType{type, md5sum}});
  std::vector<RawBagMessage> out;
  out.reserve(messages.size());
  for (const auto& m : messages) {
    const std::span<const char> bytes = bag.read(m);
    RawBagMessage& raw = out.emplace_back();
    raw.time = static_cast<double>(m.time) * 1e-9;
    raw.bytes.assign(reinterpret_cast<const std::uint8_t*>(bytes.data()),
                     reinterpret_cast<const std::uint8_t*>(bytes.data()) + bytes.size());
  }
  return out;
}

core::Trajectory readBagTrajectory(const std::string& path, const std::string& topic) {
  detail::BagFile bag(path);
  const auto messages =
      topicMessages(bag, topic, {kOdometryMessage, kPoseStampedType, kPoseCovarianceType});
  core::Trajectory trajectory;
  trajectory.reserve(messages.size());
  for (std::size_t i = 0; i < messages.size(); ++i) {
    const std::span<const char> bytes = bag.read(messages[i]);
    try {
      ByteReader in(bytes, "message bytes");
      const auto [stamp, pose] =
          readStampedPose(in, bag.connections()[messages[i].connection].type);
      trajectory.push_back(stamp, pose);
    } catch (const std::exception& e) {
      failMessage(path, topic, i, e.what());
    }
  }
  return trajectory;
}

}  // namespace dcl::io
