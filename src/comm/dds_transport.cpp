#include <algorithm>
#include <array>
#include <atomic>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>

#include <dds/dds.h>

#include <dcl/comm/dds_domain.hpp>
#include <dcl/comm/dds_transport.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>

#include "envelope.h"

namespace dcl::comm {

namespace {

/// One topic per QoS: on a shared topic a best-effort reader would match the
/// reliable writer too, and every reliable sample would arrive twice.
constexpr std::array<const char*, 2> kTopicNames = {"dcl_reliable", "dcl_best_effort"};

/// How long a reliable write may wait for acknowledgements to free the
/// writer's history. Transport::send must not stall the robot's loop; a write
/// refused here is counted, and Messenger sends the message again later.
constexpr dds_duration_t kMaxWriteBlocking = DDS_MSECS(10);

/// Largest serialised envelope a domain we configure accepts: the largest
/// message plus the envelope's header and routing fields. Bounds what a
/// hostile peer can make this process allocate.
constexpr std::size_t kMaxSampleBytes = kMaxMessageBytes + 64;

/// Samples taken per dds_take call.
constexpr std::uint32_t kTakeBatch = 64;

std::size_t index(Qos qos) {
  return qos == Qos::reliable ? 0 : 1;
}

DdsQos partitionQos(const std::string& swarm) {
  DdsQos qos(dds_create_qos());
  dds_qset_partition1(qos.get(), swarm.c_str());
  return qos;
}

/// Reader and writer QoS: the topic's reliability, KEEP_LAST(history), and
/// nothing from this participant (a robot does not hear itself).
DdsQos endpointQos(Qos qos, std::uint32_t history) {
  DdsQos q(dds_create_qos());
  if (qos == Qos::reliable) {
    dds_qset_reliability(q.get(), DDS_RELIABILITY_RELIABLE, kMaxWriteBlocking);
  } else {
    dds_qset_reliability(q.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
  }
  dds_qset_history(q.get(), DDS_HISTORY_KEEP_LAST, static_cast<std::int32_t>(history));
  dds_qset_ignorelocal(q.get(), DDS_IGNORELOCAL_PARTICIPANT);
  return q;
}

/// Returns a reader's loan however the copying ends.
class Loan {
 public:
  explicit Loan(dds_entity_t reader) : reader_(reader) {}
  ~Loan() {
    if (count_ > 0) dds_return_loan(reader_, samples.data(), count_);
  }
  Loan(const Loan&) = delete;
  Loan& operator=(const Loan&) = delete;

  /// Takes up to kTakeBatch samples; returns how many.
  std::int32_t take() {
    const dds_return_t n = dds_take(reader_, samples.data(), infos.data(), kTakeBatch, kTakeBatch);
    if (n < 0) ddsFail("dds_take", n);
    count_ = n;
    return n;
  }

  std::array<void*, kTakeBatch> samples{};
  std::array<dds_sample_info_t, kTakeBatch> infos{};

 private:
  dds_entity_t reader_;
  std::int32_t count_ = 0;
};

}  // namespace

void validate(const DdsConfig& config) {
  core::checkConfig(config, "dds config");
}

struct DdsTransport::Impl {
  Impl(core::RobotId robot, const DdsConfig& config)
      : self(robot),
        lease(config.domain, config.interface, kMaxSampleBytes),
        participant(config.domain) {
    const dds_entity_t pp = participant.handle();
    const DdsQos partition = partitionQos(config.swarm);
    const dds_entity_t publisher =
        ddsChecked(dds_create_publisher(pp, partition.get(), nullptr), "dds_create_publisher");
    const dds_entity_t subscriber =
        ddsChecked(dds_create_subscriber(pp, partition.get(), nullptr), "dds_create_subscriber");
    waitset = ddsChecked(dds_create_waitset(pp), "dds_create_waitset");
    for (const Qos qos : {Qos::reliable, Qos::best_effort}) {
      const std::size_t i = index(qos);
      const std::string name = kTopicNames[i];
      const dds_entity_t topic =
          ddsChecked(dds_create_topic(pp, &dcl_dds_Envelope_desc, name.c_str(), nullptr, nullptr),
                     "dds_create_topic(" + name + ")");
      const DdsQos endpoint = endpointQos(qos, config.history);
      writers[i] = ddsChecked(dds_create_writer(publisher, topic, endpoint.get(), nullptr),
                              "dds_create_writer(" + name + ")");
      readers[i] = ddsChecked(dds_create_reader(subscriber, topic, endpoint.get(), nullptr),
                              "dds_create_reader(" + name + ")");
      const dds_entity_t condition = ddsChecked(dds_create_readcondition(readers[i], DDS_ANY_STATE),
                                                "dds_create_readcondition(" + name + ")");
      const dds_return_t rc = dds_waitset_attach(waitset, condition, condition);
      if (rc < 0) ddsFail("dds_waitset_attach(" + name + ")", rc);
    }
  }

  void write(std::uint8_t receiver, MessageKind kind, std::span<const std::uint8_t> bytes) {
    dcl_dds_Envelope envelope{};
    envelope.sender = self.value();
    envelope.receiver = receiver;
    envelope.kind = static_cast<std::uint8_t>(kind);
    // DDS serialises the sample inside dds_write and keeps no pointer to it.
    envelope.payload._length = envelope.payload._maximum = static_cast<std::uint32_t>(bytes.size());
    envelope.payload._buffer = const_cast<std::uint8_t*>(bytes.data());
    envelope.payload._release = false;
    if (dds_write(writers[index(qosOf(kind))], &envelope) < 0) ++failed;
  }

  /// Whether a sample is meant for this robot and can be attributed at all.
  [[nodiscard]] bool accepts(const dcl_dds_Envelope& envelope) const {
    const core::RobotId sender(envelope.sender);
    return sender.valid() && sender != self && envelope.kind < kMessageKinds &&
           (envelope.receiver == 0 || envelope.receiver == self.value() + 1);
  }

  void takeAll(dds_entity_t reader, std::vector<Datagram>& out) const {
    for (;;) {
      Loan loan(reader);
      const std::int32_t n = loan.take();
      for (std::int32_t i = 0; i < n; ++i) {
        const auto k = static_cast<std::size_t>(i);
        if (!loan.infos[k].valid_data) continue;  // an instance's state change, no data
        const auto& envelope = *static_cast<const dcl_dds_Envelope*>(loan.samples[k]);
        if (!accepts(envelope)) continue;
        const std::uint8_t* bytes = envelope.payload._buffer;
        out.push_back({core::RobotId(envelope.sender), static_cast<MessageKind>(envelope.kind),
                       std::vector<std::uint8_t>(bytes, bytes + envelope.payload._length)});
      }
      if (n < static_cast<std::int32_t>(kTakeBatch)) return;
    }
  }

  core::RobotId self;
  // Destroyed in reverse order: the participant (and all under it) before
  // this transport's share of the domain is given back.
  DdsDomainLease lease;
  DdsParticipant participant;
  dds_entity_t waitset = 0;
  std::array<dds_entity_t, 2> writers{};
  std::array<dds_entity_t, 2> readers{};
  std::atomic<std::size_t> failed{0};
};

DdsTransport::DdsTransport(core::RobotId self, const DdsConfig& config) {
  validate(config);
  if (!self.valid()) throw core::Error("DdsTransport: invalid robot id");
  impl_ = std::make_unique<Impl>(self, config);
}

DdsTransport::~DdsTransport() = default;

core::RobotId DdsTransport::self() const {
  return impl_->self;
}

void DdsTransport::send(std::optional<core::RobotId> to, MessageKind kind,
                        std::span<const std::uint8_t> bytes) {
  if (to && !to->valid()) throw core::Error("DdsTransport::send: invalid receiver id");
  if (bytes.size() > kMaxMessageBytes) {
    ++impl_->failed;
    return;
  }
  impl_->write(to ? static_cast<std::uint8_t>(to->value() + 1) : std::uint8_t{0}, kind, bytes);
}

std::vector<Datagram> DdsTransport::receive() {
  // DDS keeps each sender's order on each QoS path; across the two paths and
  // across senders the order of arrival is not known (Messenger needs none).
  std::vector<Datagram> out;
  for (const dds_entity_t reader : impl_->readers) impl_->takeAll(reader, out);
  return out;
}

bool DdsTransport::wait(std::chrono::milliseconds timeout) {
  const dds_duration_t relative = DDS_MSECS(std::max<std::int64_t>(timeout.count(), 0));
  const dds_return_t rc = dds_waitset_wait(impl_->waitset, nullptr, 0, relative);
  if (rc < 0) ddsFail("dds_waitset_wait", rc);
  return rc > 0;
}

std::size_t DdsTransport::failedWrites() const {
  return impl_->failed.load();
}

}  // namespace dcl::comm
