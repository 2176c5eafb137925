#pragma once

// A process's DDS domains and participants, shared by the swarm's transport
// and the ROS 2 node (which may run in one process on one domain): the first
// share of a domain creates it with our configuration, the last deletes it.
// Cyclone's own log lines are kept, not printed, and named in our errors.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include <dds/dds.h>

namespace dcl::comm {

/// Throws core::Error naming `call`, Cyclone's return code and what Cyclone logged.
[[noreturn]] void ddsFail(const std::string& call, dds_return_t rc);

/// Returns `entity`, or throws (ddsFail) when it is an error code.
dds_entity_t ddsChecked(dds_entity_t entity, const std::string& call);

/// This process's share of DDS domain `domain`. The share that creates the
/// domain configures it: with `interface`, discovery by multicast on it and
/// samples of `max_sample_bytes` at most (what a hostile peer can make this
/// process allocate); with no interface, Cyclone's defaults (or the user's
/// CYCLONEDDS_URI). A later share must name the same interface and ask for no
/// larger samples than the domain was made for; throws core::Error otherwise.
class DdsDomainLease {
 public:
  DdsDomainLease(std::uint32_t domain, const std::string& interface, std::size_t max_sample_bytes);
  ~DdsDomainLease();
  DdsDomainLease(const DdsDomainLease&) = delete;
  DdsDomainLease& operator=(const DdsDomainLease&) = delete;

 private:
  std::uint32_t domain_;
};

/// A DDS participant; deleting it deletes everything created under it.
class DdsParticipant {
 public:
  explicit DdsParticipant(std::uint32_t domain);
  ~DdsParticipant();
  DdsParticipant(const DdsParticipant&) = delete;
  DdsParticipant& operator=(const DdsParticipant&) = delete;

  [[nodiscard]] dds_entity_t handle() const { return handle_; }

 private:
  dds_entity_t handle_;
};

struct DdsQosDeleter {
  void operator()(dds_qos_t* qos) const { dds_delete_qos(qos); }
};
/// A QoS object, deleted with its owner.
using DdsQos = std::unique_ptr<dds_qos_t, DdsQosDeleter>;

}  // namespace dcl::comm
