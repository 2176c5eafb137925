#pragma once

/// One robot's side of the conversation with its neighbours, on any
/// Transport: it numbers and encodes what the robot sends, validates and
/// de-duplicates what arrives, keeps track of who is in range, and makes sure
/// a neighbour gets every reliable message meant for it exactly once, however
/// often it goes out of range or restarts.
///
/// Neighbours. A robot becomes a neighbour when anything valid is heard from
/// it and stops being one after `neighbour_timeout` seconds of silence. Every
/// robot sends a heartbeat each `heartbeat_period` seconds carrying, for every
/// robot it has heard, how far it has received that robot's reliable streams.
///
/// Reliable kinds (isReliable) are kept in the sender's log per stream: its
/// broadcasts, and its messages to each receiver. A neighbour's heartbeat
/// acknowledges a prefix of each stream and, selectively, what it received in
/// the 64 sequences past the first gap; whatever a present neighbour has not
/// acknowledged is sent to it again `retransmit_after` seconds after it was
/// last sent, and at once when the neighbour (re)appears. A robot that never
/// heard a broadcast stream gets it from the beginning: a teammate met late
/// still receives every descriptor. The receiver delivers each sequence
/// number once, in whatever order it arrives; anything at or below what it
/// has delivered is a duplicate.
///
/// Best-effort kinds (heartbeats, DGS exchanges) are sent once and delivered
/// only when newer than the last one delivered from that sender.
///
/// Restarts. Each process life has an incarnation number, larger than the
/// previous one's (Messenger's user picks it: a counter in simulation, the
/// start time on a real robot). A message from a larger incarnation resets
/// what is known of its sender, both ways: its streams start again, and
/// everything logged for it is sent again (it lost its memory); a message from
/// a smaller one is dropped.
///
/// Hostile input. Every datagram is decoded and validated (messages.hpp);
/// what fails, and duplicates, are counted per reason and peer and logged once
/// per peer and reason; nothing of it reaches the robot or changes the
/// messenger's state.

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <vector>

#include <dcl/comm/messages.hpp>
#include <dcl/comm/transport.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::comm {

struct MessengerConfig {
  /// s between heartbeats.
  double heartbeat_period = 1.0;
  /// s of silence after which a neighbour is gone.
  double neighbour_timeout = 3.5;
  /// s after which an unacknowledged reliable message is sent again.
  double retransmit_after = 2.5;
  /// Sequence numbers a receiver accepts ahead of what it has delivered
  /// contiguously; bounds its memory of out-of-order arrivals.
  std::uint64_t window = 4096;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("heartbeat_period", heartbeat_period, "s between heartbeats").positive();
    v.field("neighbour_timeout", neighbour_timeout, "s of silence after which a neighbour is gone")
        .greaterThan(heartbeat_period, "heartbeat_period");
    v.field("retransmit_after", retransmit_after, "s before an unacknowledged message is re-sent")
        .positive();
    v.field("window", window, "sequence numbers accepted ahead of the contiguous ones").positive();
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const MessengerConfig& config);

/// A change among the neighbours.
struct NeighbourEvent {
  enum class Type : std::uint8_t {
    appeared,   ///< heard for the first time, or again after a timeout
    lost,       ///< silent for neighbour_timeout
    restarted,  ///< heard from a new incarnation: it forgot everything
  };
  Type type = Type::appeared;
  core::RobotId robot;
  double time = 0.0;  ///< s
};

/// What the messenger has done, for metrics.json and diagnostics.
struct MessengerStats {
  std::array<std::size_t, kMessageKinds> sent{};        ///< messages, first transmissions
  std::array<std::size_t, kMessageKinds> sent_bytes{};  ///< their bytes
  std::array<std::size_t, kMessageKinds> resent{};      ///< retransmissions
  std::array<std::size_t, kMessageKinds> resent_bytes{};
  std::array<std::size_t, kMessageKinds> delivered{};       ///< messages handed to the robot
  std::array<std::size_t, kMessageKinds> received_bytes{};  ///< bytes of the delivered ones
  std::array<std::size_t, kDropReasons> dropped{};          ///< by reason, all peers
  std::map<core::RobotId, std::array<std::size_t, kDropReasons>> dropped_from;  ///< per peer
};

class Messenger {
 public:
  /// The messenger of the robot `transport` belongs to, in its life
  /// `incarnation` (> 0). Throws core::Error for an invalid configuration.
  Messenger(Transport& transport, std::uint32_t incarnation, const MessengerConfig& config = {});
  ~Messenger();
  Messenger(const Messenger&) = delete;
  Messenger& operator=(const Messenger&) = delete;

  [[nodiscard]] core::RobotId self() const;

  /// Numbers, encodes and sends `body` to `to` (nullopt: every robot in
  /// range), now; reliable kinds are also logged for retransmission.
  /// Heartbeats are the messenger's own (poll sends them); passing one throws
  /// core::Error, as does a body encode() refuses.
  void send(std::optional<core::RobotId> to, Body body, double now);

  /// Takes in what arrived and runs the timers at `now` (s, non-decreasing):
  /// heartbeat, neighbour expiry, retransmissions. Returns the messages
  /// delivered, each once, heartbeats included.
  std::vector<Message> poll(double now);

  /// The keyframe count the heartbeats announce (the robot's, as it grows).
  void setKeyframes(std::uint32_t keyframes);

  /// The neighbour changes since the last call.
  std::vector<NeighbourEvent> takeEvents();
  /// Robots heard within neighbour_timeout.
  [[nodiscard]] std::set<core::RobotId> neighbours() const;
  /// Reliable messages to `peer` (its broadcasts included) it has not acknowledged.
  [[nodiscard]] std::size_t unacknowledged(core::RobotId peer) const;

  [[nodiscard]] const MessengerStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::comm
