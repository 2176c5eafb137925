#pragma once

/// The one interface between a robot and its radio (DESIGN.md §4): encoded
/// messages out to one neighbour or to everyone in range, encoded messages
/// in. SimRadio (sim_radio.hpp) and DdsTransport (dds_transport.hpp) carry the
/// same bytes; Messenger (messenger.hpp) sits on either.

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <dcl/comm/messages.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::comm {

/// How hard the medium tries: reliable media retransmit lost packets while
/// the peer is reachable; best-effort ones may drop them.
enum class Qos : std::uint8_t { reliable, best_effort };

/// The QoS a message kind travels with: best effort for heartbeats and
/// descriptors (Messenger re-sends a descriptor a neighbour missed), reliable
/// for measurements, optimisation and summaries.
[[nodiscard]] Qos qosOf(MessageKind kind);

/// One message as it arrived.
struct Datagram {
  core::RobotId from;                         ///< the robot the medium says sent it
  MessageKind kind = MessageKind::heartbeat;  ///< as the sender declared it (metering only)
  std::vector<std::uint8_t> bytes;            ///< one encoded Message, not yet trusted
};

class Transport {
 public:
  virtual ~Transport() = default;

  /// The robot this endpoint belongs to.
  [[nodiscard]] virtual core::RobotId self() const = 0;

  /// Hands one encoded message to the medium for `to` (nullopt: every robot
  /// in range). Never blocks and never throws for a peer out of reach: the
  /// medium drops what it cannot carry and counts it.
  virtual void send(std::optional<core::RobotId> to, MessageKind kind,
                    std::span<const std::uint8_t> bytes) = 0;

  /// Everything that arrived since the last call, in arrival order.
  virtual std::vector<Datagram> receive() = 0;
};

}  // namespace dcl::comm
