// A ROS 2 participant on DDS (ros2_node.hpp): typed writers and readers of the
// generated message types, converted to and from dcl::ros2's values.
#include <algorithm>
#include <array>
#include <cctype>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include <dcl/comm/dds_domain.hpp>
#include <dcl/core/error.hpp>
#include <dcl/ros/ros2_node.hpp>

#include "rmw_dds_common.h"
#include "ros2_wire.hpp"

namespace dcl::ros2 {

namespace {

using comm::ddsChecked;
using comm::ddsFail;
using comm::DdsQos;
using core::Error;

/// How long a reliable write may wait for room in a reader's history.
constexpr dds_duration_t kMaxWriteBlocking = DDS_MSECS(100);
/// Samples taken per dds_take call.
constexpr std::uint32_t kTakeBatch = 16;
/// Where ROS 2 participants say which nodes they hold (rmw_dds_common).
constexpr const char* kDiscoveryTopic = "ros_discovery_info";

using Gid = rmw_dds_common_msg_dds__Gid_;

/// An entity's DDS GUID as ROS 2 gives it: its 16 bytes, then zeros.
Gid gidOf(dds_entity_t entity) {
  dds_guid_t guid{};
  const dds_return_t rc = dds_get_guid(entity, &guid);
  if (rc < 0) ddsFail("dds_get_guid", rc);
  Gid gid{};
  std::copy(std::begin(guid.v), std::end(guid.v), std::begin(gid.data));
  return gid;
}

/// ROS 2's QoS profiles (rmw_qos_profile_sensor_data, _default, and a latched topic's).
DdsQos ddsQos(Qos qos, bool writer) {
  DdsQos q(dds_create_qos());
  // ROS 2 writes XCDR1 (plain CDR); a reader takes XCDR2 too.
  const dds_data_representation_id_t representations[] = {DDS_DATA_REPRESENTATION_XCDR1,
                                                          DDS_DATA_REPRESENTATION_XCDR2};
  dds_qset_data_representation(q.get(), writer ? 1 : 2, representations);
  switch (qos) {
    case Qos::sensor_data:
      dds_qset_reliability(q.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
      dds_qset_history(q.get(), DDS_HISTORY_KEEP_LAST, 5);
      dds_qset_durability(q.get(), DDS_DURABILITY_VOLATILE);
      break;
    case Qos::reliable:
      dds_qset_reliability(q.get(), DDS_RELIABILITY_RELIABLE, kMaxWriteBlocking);
      dds_qset_history(q.get(), DDS_HISTORY_KEEP_LAST, 10);
      dds_qset_durability(q.get(), DDS_DURABILITY_VOLATILE);
      break;
    case Qos::transient_local:
      dds_qset_reliability(q.get(), DDS_RELIABILITY_RELIABLE, kMaxWriteBlocking);
      dds_qset_history(q.get(), DDS_HISTORY_KEEP_LAST, 1);
      dds_qset_durability(q.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
      break;
  }
  return q;
}

bool validPart(std::string_view part) {
  if (part.empty() || std::isdigit(static_cast<unsigned char>(part.front()))) return false;
  for (const char c : part) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return false;
  }
  return true;
}

/// Returns a reader's loan however the delivery ends.
class Loan {
 public:
  explicit Loan(dds_entity_t reader) : reader_(reader) {
    const dds_return_t n = dds_take(reader_, samples.data(), infos.data(), kTakeBatch, kTakeBatch);
    if (n < 0) ddsFail("dds_take", n);
    count = n;
  }
  ~Loan() {
    if (count > 0) dds_return_loan(reader_, samples.data(), count);
  }
  Loan(const Loan&) = delete;
  Loan& operator=(const Loan&) = delete;

  std::array<void*, kTakeBatch> samples{};
  std::array<dds_sample_info_t, kTakeBatch> infos{};
  std::int32_t count = 0;

 private:
  dds_entity_t reader_;
};

}  // namespace

std::string ddsTopicName(const std::string& ros_name) {
  std::string_view name = ros_name;
  if (!name.empty() && name.front() == '/') name.remove_prefix(1);
  std::string_view rest = name;
  while (true) {
    const std::size_t slash = rest.find('/');
    if (!validPart(rest.substr(0, slash))) {
      throw Error(
          fmt::format("'{}' is not a ROS 2 topic name (parts of letters, digits and '_', "
                      "not starting with a digit, between single '/')",
                      ros_name));
    }
    if (slash == std::string_view::npos) break;
    rest.remove_prefix(slash + 1);
  }
  return "rt/" + std::string(name);
}

struct Node::Impl {
  explicit Impl(const NodeConfig& config)
      : lease(config.domain, config.interface, NodeConfig::kMaxSampleBytes),
        participant(config.domain),
        waitset(ddsChecked(dds_create_waitset(participant.handle()), "dds_create_waitset")),
        node_name(config.name) {
    const dds_entity_t topic =
        ddsChecked(dds_create_topic(participant.handle(),
                                    &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
                                    kDiscoveryTopic, nullptr, nullptr),
                   std::string("dds_create_topic(") + kDiscoveryTopic + ")");
    const DdsQos q = ddsQos(Qos::transient_local, /*writer=*/true);
    discovery = ddsChecked(dds_create_writer(participant.handle(), topic, q.get(), nullptr),
                           std::string("dds_create_writer(") + kDiscoveryTopic + ")");
    announce();
  }

  /// Says on ros_discovery_info which readers and writers this node has, as
  /// rmw_cyclonedds does after each change, so that ROS 2's tools name it.
  void announce() {
    std::vector<Gid> readers;
    std::vector<Gid> writer_gids;
    for (const auto& s : subscriptions) readers.push_back(gidOf(s.reader));
    for (const auto& [name, w] : writers) writer_gids.push_back(gidOf(w.writer));
    rmw_dds_common_msg_dds__NodeEntitiesInfo_ node{};
    node.node_namespace[0] = '/';
    node_name.copy(node.node_name, sizeof(node.node_name) - 1);
    node.reader_gid_seq = {static_cast<std::uint32_t>(readers.size()),
                           static_cast<std::uint32_t>(readers.size()), readers.data(), false};
    node.writer_gid_seq = {static_cast<std::uint32_t>(writer_gids.size()),
                           static_cast<std::uint32_t>(writer_gids.size()), writer_gids.data(),
                           false};
    rmw_dds_common_msg_dds__ParticipantEntitiesInfo_ info{};
    info.gid = gidOf(participant.handle());
    info.node_entities_info_seq = {1, 1, &node, false};
    const dds_return_t rc = dds_write(discovery, &info);
    if (rc < 0) ddsFail(std::string("dds_write(") + kDiscoveryTopic + ")", rc);
  }

  /// The DDS topic of `ros_name` for messages of `descriptor`.
  dds_entity_t topic(const std::string& ros_name, const dds_topic_descriptor_t& descriptor) {
    const std::string name = ddsTopicName(ros_name);
    const auto it = topics.find(name);
    if (it != topics.end()) {
      if (it->second.second != &descriptor) {
        throw Error(fmt::format("ROS 2 topic {}: already used for {}, not {}", ros_name,
                                it->second.second->m_typename, descriptor.m_typename));
      }
      return it->second.first;
    }
    const dds_entity_t t = ddsChecked(
        dds_create_topic(participant.handle(), &descriptor, name.c_str(), nullptr, nullptr),
        "dds_create_topic(" + name + ")");
    topics.emplace(name, std::make_pair(t, &descriptor));
    return t;
  }

  struct Writer {
    dds_entity_t writer = 0;
    Qos qos = Qos::reliable;
    const dds_topic_descriptor_t* descriptor = nullptr;
  };
  struct Subscription {
    std::string topic;
    dds_entity_t reader = 0;
    /// Takes what arrived and hands it on; returns the messages delivered.
    std::function<std::size_t(dds_entity_t, std::pair<std::size_t, std::string>&)> deliver;
  };

  // Destroyed in reverse order: the participant (and all under it) before
  // this node's share of the domain is given back.
  comm::DdsDomainLease lease;
  comm::DdsParticipant participant;
  dds_entity_t waitset;
  std::map<std::string, std::pair<dds_entity_t, const dds_topic_descriptor_t*>> topics;
  std::map<std::string, Writer> writers;  // by ROS topic name
  std::vector<Subscription> subscriptions;
  std::map<std::string, std::pair<std::size_t, std::string>> refused;
  std::string node_name;
  dds_entity_t discovery = 0;  ///< the writer of ros_discovery_info
};

Node::Node(const NodeConfig& config) {
  core::checkConfig(config, "ros2 config");
  impl_ = std::make_unique<Impl>(config);
}

Node::~Node() = default;

template <class M>
void Node::advertise(const std::string& topic, Qos qos) {
  const dds_topic_descriptor_t& descriptor = detail::Wire<M>::descriptor();
  if (const auto it = impl_->writers.find(topic); it != impl_->writers.end()) {
    if (it->second.qos != qos || it->second.descriptor != &descriptor) {
      throw Error(
          fmt::format("ROS 2 topic {}: advertised already, with another type or QoS", topic));
    }
    return;
  }
  const dds_entity_t t = impl_->topic(topic, descriptor);
  const DdsQos q = ddsQos(qos, /*writer=*/true);
  const dds_entity_t writer =
      ddsChecked(dds_create_writer(impl_->participant.handle(), t, q.get(), nullptr),
                 "dds_create_writer(" + topic + ")");
  impl_->writers.emplace(topic, Impl::Writer{writer, qos, &descriptor});
  impl_->announce();
}

template <class M>
void Node::publish(const std::string& topic, const M& message) {
  const auto it = impl_->writers.find(topic);
  if (it == impl_->writers.end() || it->second.descriptor != &detail::Wire<M>::descriptor()) {
    throw Error(fmt::format("ROS 2 topic {}: not advertised for {}", topic, typeName<M>()));
  }
  const typename detail::Wire<M>::Out out(message);
  const dds_return_t rc = dds_write(it->second.writer, out.get());
  if (rc < 0) ddsFail("dds_write(" + topic + ")", rc);
}

template <class M>
void Node::subscribe(const std::string& topic, Qos qos, std::function<void(M&&)> callback,
                     std::int32_t depth) {
  using W = detail::Wire<M>;
  const dds_entity_t t = impl_->topic(topic, W::descriptor());
  const DdsQos q = ddsQos(qos, /*writer=*/false);
  if (depth > 0) dds_qset_history(q.get(), DDS_HISTORY_KEEP_LAST, depth);
  const dds_entity_t reader =
      ddsChecked(dds_create_reader(impl_->participant.handle(), t, q.get(), nullptr),
                 "dds_create_reader(" + topic + ")");
  const dds_entity_t condition = ddsChecked(dds_create_readcondition(reader, DDS_ANY_STATE),
                                            "dds_create_readcondition(" + topic + ")");
  const dds_return_t rc = dds_waitset_attach(impl_->waitset, condition, condition);
  if (rc < 0) ddsFail("dds_waitset_attach(" + topic + ")", rc);
  auto deliver = [callback = std::move(callback)](dds_entity_t r,
                                                  std::pair<std::size_t, std::string>& refused) {
    std::size_t delivered = 0;
    for (;;) {
      const Loan loan(r);
      for (std::int32_t i = 0; i < loan.count; ++i) {
        const auto k = static_cast<std::size_t>(i);
        if (!loan.infos[k].valid_data) continue;  // an instance's state change, no data
        M message;
        try {
          message = W::in(*static_cast<const typename W::C*>(loan.samples[k]));
        } catch (const Error& e) {
          ++refused.first;
          refused.second = e.what();
          continue;
        }
        callback(std::move(message));
        ++delivered;
      }
      if (loan.count < static_cast<std::int32_t>(kTakeBatch)) return delivered;
    }
  };
  impl_->subscriptions.push_back({topic, reader, std::move(deliver)});
  impl_->announce();
}

std::size_t Node::spin(std::chrono::milliseconds timeout) {
  const dds_return_t rc = dds_waitset_wait(impl_->waitset, nullptr, 0,
                                           DDS_MSECS(std::max<std::int64_t>(0, timeout.count())));
  if (rc < 0) ddsFail("dds_waitset_wait", rc);
  std::size_t delivered = 0;
  for (auto& s : impl_->subscriptions) {
    std::pair<std::size_t, std::string> refused{0, {}};
    delivered += s.deliver(s.reader, refused);
    if (refused.first > 0) {
      auto& total = impl_->refused[s.topic];
      total.first += refused.first;
      total.second = refused.second;
    }
  }
  return delivered;
}

std::map<std::string, std::pair<std::size_t, std::string>> Node::refused() const {
  return impl_->refused;
}

std::size_t Node::matched(const std::string& topic) const {
  std::size_t n = 0;
  if (const auto it = impl_->writers.find(topic); it != impl_->writers.end()) {
    dds_publication_matched_status_t status{};
    if (dds_get_publication_matched_status(it->second.writer, &status) == 0) {
      n += status.current_count;
    }
  }
  for (const auto& s : impl_->subscriptions) {
    if (s.topic != topic) continue;
    dds_subscription_matched_status_t status{};
    if (dds_get_subscription_matched_status(s.reader, &status) == 0) n += status.current_count;
  }
  return n;
}

#define DCL_ROS2_NODE_MESSAGE(M)                                                       \
  template void Node::advertise<M>(const std::string&, Qos);                           \
  template void Node::publish<M>(const std::string&, const M&);                        \
  template void Node::subscribe<M>(const std::string&, Qos, std::function<void(M &&)>, \
                                   std::int32_t);
DCL_ROS2_NODE_MESSAGE(PointCloud2)
DCL_ROS2_NODE_MESSAGE(Imu)
DCL_ROS2_NODE_MESSAGE(Odometry)
DCL_ROS2_NODE_MESSAGE(Path)
DCL_ROS2_NODE_MESSAGE(TFMessage)
DCL_ROS2_NODE_MESSAGE(MarkerArray)
#undef DCL_ROS2_NODE_MESSAGE

}  // namespace dcl::ros2
