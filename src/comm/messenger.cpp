#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include <spdlog/spdlog.h>

#include <dcl/comm/messenger.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>

namespace dcl::comm {

namespace {

constexpr double kNever = -std::numeric_limits<double>::infinity();

/// One reliable message as it went out: resent byte for byte, so a receiver
/// files a retransmission under the sequence and stream of the original.
struct LogEntry {
  MessageKind kind = MessageKind::descriptor;
  std::vector<std::uint8_t> bytes;
};

/// One reliable stream of a sender as its receiver sees it: everything up to
/// `contiguous` delivered, and the sequences delivered above it. Acks name
/// `contiguous` and, as a bitmap, the 64 sequences past the first gap, so a
/// gap is never acknowledged and what arrived past it need not come again.
struct ReceiveStream {
  std::uint64_t contiguous = 0;
  std::set<std::uint64_t> above;  ///< at most `window` ahead of contiguous

  [[nodiscard]] bool has(std::uint64_t sequence) const {
    return sequence <= contiguous || above.contains(sequence);
  }

  /// Bit i: contiguous + 2 + i delivered (the selective part of an Ack).
  [[nodiscard]] std::uint64_t above_bits() const {
    std::uint64_t bits = 0;
    for (const std::uint64_t sequence : above) {
      const std::uint64_t bit = sequence - contiguous - 2;
      if (bit >= 64) break;
      bits |= std::uint64_t{1} << bit;
    }
    return bits;
  }

  void add(std::uint64_t sequence) {
    above.insert(sequence);
    while (!above.empty() && *above.begin() == contiguous + 1) {
      above.erase(above.begin());
      ++contiguous;
    }
  }
};

/// One of this robot's reliable streams as sent to one peer: the prefix it
/// acknowledged, and when each message above it last went to it (a message
/// without a time is due at once).
struct SendStream {
  std::uint64_t acked = 0;
  std::set<std::uint64_t> acked_above;  ///< acknowledged beyond a gap
  std::map<std::uint64_t, double> sent_at;

  /// Everything up to `upto`, and upto + 2 + i for every bit i of `above`, not past `last`.
  void acknowledge(std::uint64_t upto, std::uint64_t above, std::uint64_t last) {
    upto = std::min(upto, last);
    if (upto > acked) {
      acked = upto;
      sent_at.erase(sent_at.begin(), sent_at.upper_bound(upto));
      acked_above.erase(acked_above.begin(), acked_above.upper_bound(upto));
    }
    for (int bit = 0; bit < 64 && above >> bit != 0; ++bit) {
      const std::uint64_t sequence = upto + 2 + static_cast<std::uint64_t>(bit);
      if ((above >> bit & 1U) == 0 || sequence <= acked || sequence > last) continue;
      acked_above.insert(sequence);
      sent_at.erase(sequence);
    }
  }
  [[nodiscard]] bool isAcked(std::uint64_t sequence) const {
    return sequence <= acked || acked_above.contains(sequence);
  }
  void reset() {
    acked = 0;
    acked_above.clear();
    sent_at.clear();
  }
};

/// Everything this robot knows of another one, both ways.
struct Peer {
  // Receiving from it.
  std::uint32_t incarnation = 0;  ///< 0: never heard
  bool present = false;
  double last_heard = kNever;
  ReceiveStream broadcasts;
  ReceiveStream unicasts;  ///< its reliable messages to this robot
  std::uint64_t best_effort = 0;
  // Sending to it.
  SendStream our_broadcasts;
  SendStream our_unicasts;
  std::vector<LogEntry> unicast_log;  ///< sequence s at index s - 1; kept for its restarts

  /// It restarted: it forgot what it received from us and starts its streams again.
  void forget() {
    broadcasts = {};
    unicasts = {};
    best_effort = 0;
    our_broadcasts.reset();
    our_unicasts.reset();
  }
};

struct Drop {
  DropReason reason;
  std::string detail;
};

std::string robot(core::RobotId id) {
  return "robot " + core::robotName(id);
}

}  // namespace

void validate(const MessengerConfig& config) {
  core::checkConfig(config, "messenger config");
}

struct Messenger::Impl {
  Transport& transport;
  core::RobotId self;
  std::uint32_t incarnation;
  MessengerConfig config;
  std::vector<LogEntry> broadcast_log;  ///< sequence s at index s - 1, never trimmed
  std::uint64_t best_effort_sequence = 0;
  std::map<core::RobotId, Peer> peers;
  std::vector<NeighbourEvent> events;
  std::set<std::pair<core::RobotId, DropReason>> logged;
  MessengerStats stats;
  std::optional<double> next_heartbeat;  ///< nullopt: at the first poll
  double last_poll = kNever;
  std::uint32_t keyframes = 0;  ///< announced in heartbeats

  Impl(Transport& t, std::uint32_t life, const MessengerConfig& c)
      : transport(t), self(t.self()), incarnation(life), config(c) {
    validate(config);
    if (incarnation == 0) throw core::Error("messenger: incarnation must be > 0");
    if (!self.valid()) throw core::Error("messenger: the transport has no robot id");
  }

  // ---- sending -----------------------------------------------------------

  void send(std::optional<core::RobotId> to, Body body, double now) {
    const MessageKind kind = kindOf(body);
    if (kind == MessageKind::heartbeat)
      throw core::Error("messenger: heartbeats are the messenger's own, poll() sends them");
    if (to == self) throw core::Error("messenger: " + robot(self) + " cannot send to itself");
    const bool reliable = isReliable(kind);
    Message message{Header{kSchemaVersion, self, to, incarnation, nextSequence(to, reliable)},
                    std::move(body)};
    std::vector<std::uint8_t> bytes = encode(message);  // throws before any state changes
    transmit(to, kind, bytes, false);
    if (!reliable) {
      ++best_effort_sequence;
    } else if (to) {
      logUnicast(peers[*to], kind, std::move(bytes), now);
    } else {
      logBroadcast(kind, std::move(bytes), now);
    }
  }

  [[nodiscard]] std::uint64_t nextSequence(std::optional<core::RobotId> to, bool reliable) const {
    if (!reliable) return best_effort_sequence + 1;
    if (!to) return broadcast_log.size() + 1;
    const auto it = peers.find(*to);
    return (it == peers.end() ? 0 : it->second.unicast_log.size()) + 1;
  }

  void logBroadcast(MessageKind kind, std::vector<std::uint8_t> bytes, double now) {
    broadcast_log.push_back({kind, std::move(bytes)});
    for (auto& [id, peer] : peers) {
      if (peer.present) peer.our_broadcasts.sent_at[broadcast_log.size()] = now;
    }
  }

  static void logUnicast(Peer& peer, MessageKind kind, std::vector<std::uint8_t> bytes,
                         double now) {
    peer.unicast_log.push_back({kind, std::move(bytes)});
    peer.our_unicasts.sent_at[peer.unicast_log.size()] = now;
  }

  void transmit(std::optional<core::RobotId> to, MessageKind kind,
                std::span<const std::uint8_t> bytes, bool again) {
    transport.send(to, kind, bytes);
    const auto k = static_cast<std::size_t>(kind);
    ++(again ? stats.resent : stats.sent)[k];
    (again ? stats.resent_bytes : stats.sent_bytes)[k] += bytes.size();
  }

  void heartbeat(double now) {
    Heartbeat beat;
    beat.stamp = now;
    beat.keyframes = keyframes;
    for (const auto& [id, peer] : peers) {
      if (peer.incarnation == 0) continue;
      beat.acks.push_back({id, peer.incarnation, peer.broadcasts.contiguous,
                           peer.unicasts.contiguous, peer.broadcasts.above_bits(),
                           peer.unicasts.above_bits()});
    }
    const Message message{
        Header{kSchemaVersion, self, std::nullopt, incarnation, ++best_effort_sequence},
        std::move(beat)};
    transmit(std::nullopt, MessageKind::heartbeat, encode(message), false);
  }

  /// Whatever a present neighbour has not acknowledged goes to it again once
  /// retransmit_after has passed since it last went (or at once, never sent).
  /// A broadcast goes to one neighbour as a unicast on the medium but keeps
  /// its broadcast header, so the neighbour files it in the broadcast stream.
  void retransmit(double now) {
    for (auto& [id, peer] : peers) {
      if (!peer.present) continue;
      resend(id, peer.our_broadcasts, broadcast_log, now);
      resend(id, peer.our_unicasts, peer.unicast_log, now);
    }
  }

  void resend(core::RobotId to, SendStream& stream, const std::vector<LogEntry>& log, double now) {
    for (std::uint64_t sequence = stream.acked + 1; sequence <= log.size(); ++sequence) {
      if (stream.isAcked(sequence)) continue;
      const auto [at, never_sent] = stream.sent_at.try_emplace(sequence, now);
      if (!never_sent && now - at->second < config.retransmit_after) continue;
      at->second = now;
      const LogEntry& entry = log[sequence - 1];
      transmit(to, entry.kind, entry.bytes, true);
    }
  }

  // ---- receiving ---------------------------------------------------------

  std::vector<Message> receive(double now) {
    std::vector<Message> delivered;
    for (const Datagram& datagram : transport.receive()) {
      if (std::optional<Message> message = accept(datagram, now))
        delivered.push_back(std::move(*message));
    }
    return delivered;
  }

  std::optional<Message> accept(const Datagram& datagram, double now) {
    if (datagram.from == self) return std::nullopt;  // its own broadcast, echoed by the medium
    Decoded decoded = decode(datagram.bytes);
    if (!decoded.message) {
      drop(datagram.from, {decoded.reason, std::move(decoded.detail)});
      return std::nullopt;
    }
    Message& message = *decoded.message;
    if (std::optional<Drop> why = judge(datagram.from, message)) {
      drop(datagram.from, std::move(*why));
      return std::nullopt;
    }
    Peer& peer = hear(datagram.from, message.header.incarnation, now);
    record(peer, message);
    if (const auto* beat = std::get_if<Heartbeat>(&message.body)) takeAcks(peer, *beat);
    const auto k = static_cast<std::size_t>(message.kind());
    ++stats.delivered[k];
    stats.received_bytes[k] += datagram.bytes.size();
    return std::move(message);
  }

  /// Why a decoded message is not delivered, if it is not; changes nothing,
  /// so that what is dropped leaves no trace but the counters. A larger
  /// incarnation is judged against the empty state it is about to reset to.
  [[nodiscard]] std::optional<Drop> judge(core::RobotId from, const Message& message) const {
    const Header& h = message.header;
    if (h.sender != from)
      return Drop{DropReason::sender_mismatch,
                  "the header names " + robot(h.sender) + ", the medium " + robot(from)};
    if (h.receiver && *h.receiver != self) return Drop{DropReason::not_for_me, ""};
    const auto it = peers.find(from);
    const Peer* known = it == peers.end() ? nullptr : &it->second;
    if (known && h.incarnation < known->incarnation)
      return Drop{DropReason::stale_incarnation, "incarnation " + std::to_string(h.incarnation) +
                                                     ", current " +
                                                     std::to_string(known->incarnation)};
    if (known && h.incarnation > known->incarnation) known = nullptr;
    return judgeSequence(known, h, message.kind());
  }

  [[nodiscard]] std::optional<Drop> judgeSequence(const Peer* known, const Header& h,
                                                  MessageKind kind) const {
    const std::string sequence = "sequence " + std::to_string(h.sequence);
    if (!isReliable(kind)) {
      if (known && h.sequence <= known->best_effort)
        return Drop{DropReason::duplicate, "best-effort " + sequence + " not newer than " +
                                               std::to_string(known->best_effort)};
      return std::nullopt;
    }
    static const ReceiveStream kEmpty;
    const ReceiveStream& stream =
        !known ? kEmpty : (h.receiver ? known->unicasts : known->broadcasts);
    if (stream.has(h.sequence))
      return Drop{DropReason::duplicate, std::string(name(kind)) + " " + sequence};
    if (h.sequence - stream.contiguous > config.window)
      return Drop{DropReason::out_of_window,
                  sequence + ", only " + std::to_string(stream.contiguous) + " contiguous"};
    return std::nullopt;
  }

  /// Presence and restarts: a neighbour (re)appearing gets everything it has
  /// not acknowledged at once; a new incarnation forgot everything, both ways.
  Peer& hear(core::RobotId from, std::uint32_t life, double now) {
    Peer& peer = peers[from];
    if (!peer.present) {
      peer.present = true;
      peer.our_broadcasts.sent_at.clear();
      peer.our_unicasts.sent_at.clear();
      events.push_back({NeighbourEvent::Type::appeared, from, now});
    }
    if (peer.incarnation != life) {
      if (peer.incarnation != 0) {
        peer.forget();
        events.push_back({NeighbourEvent::Type::restarted, from, now});
      }
      peer.incarnation = life;
    }
    peer.last_heard = now;
    return peer;
  }

  static void record(Peer& peer, const Message& message) {
    const Header& h = message.header;
    if (!isReliable(message.kind())) {
      peer.best_effort = h.sequence;
    } else {
      (h.receiver ? peer.unicasts : peer.broadcasts).add(h.sequence);
    }
  }

  /// Acknowledgements of this life only: a neighbour that has not yet heard
  /// of a restart still acknowledges the previous life's streams.
  void takeAcks(Peer& peer, const Heartbeat& beat) {
    for (const Ack& ack : beat.acks) {
      if (ack.peer != self || ack.incarnation != incarnation) continue;
      peer.our_broadcasts.acknowledge(ack.broadcast, ack.broadcast_above, broadcast_log.size());
      peer.our_unicasts.acknowledge(ack.unicast, ack.unicast_above, peer.unicast_log.size());
    }
  }

  void drop(core::RobotId from, Drop why) {
    const auto r = static_cast<std::size_t>(why.reason);
    ++stats.dropped[r];
    ++stats.dropped_from[from][r];
    if (why.reason == DropReason::not_for_me || !logged.emplace(from, why.reason).second) return;
    const bool routine =
        why.reason == DropReason::duplicate || why.reason == DropReason::out_of_window;
    spdlog::log(routine ? spdlog::level::debug : spdlog::level::warn,
                "{}: dropped a message from {}: {}: {} (further ones counted, not logged)",
                robot(self), robot(from), name(why.reason), why.detail);
  }

  // ---- timers ------------------------------------------------------------

  void expire(double now) {
    for (auto& [id, peer] : peers) {
      if (!peer.present || now - peer.last_heard < config.neighbour_timeout) continue;
      peer.present = false;
      events.push_back({NeighbourEvent::Type::lost, id, now});
    }
  }

  /// Keeps the heartbeat's phase under regular polls; after a long gap it
  /// restarts from now rather than sending the missed ones in a burst.
  void beat(double now) {
    if (next_heartbeat && now < *next_heartbeat) return;
    heartbeat(now);
    next_heartbeat = next_heartbeat.value_or(now) + config.heartbeat_period;
    if (*next_heartbeat <= now) next_heartbeat = now + config.heartbeat_period;
  }

  std::vector<Message> poll(double now) {
    if (!std::isfinite(now)) throw core::Error("messenger: poll time is not finite");
    if (now < last_poll)
      throw core::Error("messenger: poll time " + std::to_string(now) + " s is before the last, " +
                        std::to_string(last_poll) + " s");
    last_poll = now;
    std::vector<Message> delivered = receive(now);
    expire(now);
    beat(now);
    retransmit(now);
    return delivered;
  }

  [[nodiscard]] std::size_t unacknowledged(core::RobotId id) const {
    const auto it = peers.find(id);
    if (it == peers.end()) return broadcast_log.size();
    const Peer& peer = it->second;
    return (broadcast_log.size() - peer.our_broadcasts.acked -
            peer.our_broadcasts.acked_above.size()) +
           (peer.unicast_log.size() - peer.our_unicasts.acked -
            peer.our_unicasts.acked_above.size());
  }
};

Messenger::Messenger(Transport& transport, std::uint32_t incarnation, const MessengerConfig& config)
    : impl_(std::make_unique<Impl>(transport, incarnation, config)) {}

Messenger::~Messenger() = default;

core::RobotId Messenger::self() const {
  return impl_->self;
}

void Messenger::send(std::optional<core::RobotId> to, Body body, double now) {
  impl_->send(to, std::move(body), now);
}

std::vector<Message> Messenger::poll(double now) {
  return impl_->poll(now);
}

std::vector<NeighbourEvent> Messenger::takeEvents() {
  return std::exchange(impl_->events, {});
}

std::set<core::RobotId> Messenger::neighbours() const {
  std::set<core::RobotId> out;
  for (const auto& [id, peer] : impl_->peers) {
    if (peer.present) out.insert(id);
  }
  return out;
}

void Messenger::setKeyframes(std::uint32_t keyframes) {
  impl_->keyframes = keyframes;
}

std::size_t Messenger::unacknowledged(core::RobotId peer) const {
  return impl_->unacknowledged(peer);
}

const MessengerStats& Messenger::stats() const {
  return impl_->stats;
}

}  // namespace dcl::comm
