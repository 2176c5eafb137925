#pragma once

/// An in-process radio for swarm runs and tests (DESIGN.md §4): deterministic,
/// driven by simulated time. A link joins two robots while they are within
/// the communication range of each other (positions set from ground truth)
/// or, with a schedule, during scripted rendezvous. A link can cap its
/// bandwidth, add latency and lose messages at a given rate (a seeded
/// generator: the same run gives the same losses). Every byte is metered per
/// robot, per peer, per message kind and over time, and every transmission
/// is logged with its fate.
///
/// Timing of a message of n bytes sent at t over the link a -> b: it leaves
/// when the link has finished the messages queued before it, takes
/// n / bandwidth seconds, arrives `latency` later, and is delivered by the
/// first advanceTo() at or after that time if the link still exists then. A
/// broadcast is one transmission, queued on the link to every robot in range
/// at t; a unicast to a robot out of range is not transmitted at all.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include <dcl/comm/transport.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::comm {

struct SimRadioConfig {
  static constexpr double kMinMeterInterval = 0.01;  ///< s, the finest traffic bins

  /// m, robots closer than this are linked (0: always linked). The paper's
  /// experiments assume robots talk once near each other; ~50 m is a
  /// typical ad-hoc WiFi range among buildings.
  double range = 50.0;
  /// bytes/s per directed link (0: unlimited).
  double bandwidth = 0.0;
  /// s, added to every delivery.
  double latency = 0.0;
  /// Share of messages lost per receiver, [0, 1).
  double drop_rate = 0.0;
  /// Seed of the loss generator.
  std::uint64_t seed = 1;
  /// s, width of the traffic-over-time bins.
  double meter_interval = 1.0;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("range", range, "m, robots closer than this are linked (0: always)").nonNegative();
    v.field("bandwidth", bandwidth, "bytes/s per directed link (0: unlimited)").nonNegative();
    v.field("latency", latency, "s, added to every delivery").nonNegative();
    v.field("drop_rate", drop_rate, "share of messages lost per receiver, [0, 1)")
        .within(0.0, 1.0, core::Interval::open_high);
    v.field("seed", seed, "seed of the loss generator");
    // A bin per interval of the run and robot: finer would hold more bins than the run has events.
    v.field("meter_interval", meter_interval, "s, width of the traffic-over-time bins")
        .atLeast(kMinMeterInterval);
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const SimRadioConfig& config);

/// A scripted link: robots a and b can talk during [start, end).
struct Rendezvous {
  core::RobotId a;
  core::RobotId b;
  double start = 0.0;
  double end = 0.0;
};

/// What became of one message on one link.
enum class Fate : std::uint8_t {
  delivered,
  lost,         ///< the loss rate took it
  link_down,    ///< the link broke before it arrived
  unreachable,  ///< a unicast to a robot out of range: never transmitted
};

/// One entry of the traffic log: a message on one link (a broadcast heard by
/// nobody is one entry with no receiver).
struct TrafficEvent {
  double sent = 0.0;     ///< s
  double arrival = 0.0;  ///< s, when it arrived or would have
  core::RobotId from;
  std::optional<core::RobotId> to;  ///< nullopt: a broadcast nobody was in range of
  bool broadcast = false;
  MessageKind kind = MessageKind::heartbeat;
  std::size_t bytes = 0;
  Fate fate = Fate::delivered;

  bool operator==(const TrafficEvent&) const = default;
};

/// Byte counts of one robot.
struct RobotTraffic {
  std::size_t sent = 0;      ///< bytes transmitted (a broadcast once)
  std::size_t received = 0;  ///< bytes delivered to it
  std::size_t messages_sent = 0;
  std::size_t messages_received = 0;
  std::map<core::RobotId, std::size_t> received_from;     ///< bytes delivered, per sender
  std::map<core::RobotId, std::size_t> delivered_to;      ///< bytes it delivered, per receiver
  std::array<std::size_t, kMessageKinds> sent_by_kind{};  ///< bytes transmitted, per kind
  std::array<std::size_t, kMessageKinds> received_by_kind{};
  std::vector<std::size_t> sent_over_time;  ///< bytes transmitted per meter_interval, from t = 0
};

class SimRadio {
 public:
  /// Throws core::Error when the configuration is out of range.
  explicit SimRadio(const SimRadioConfig& config = {});
  ~SimRadio();
  SimRadio(const SimRadio&) = delete;
  SimRadio& operator=(const SimRadio&) = delete;

  /// Robot `robot`'s endpoint, made on first use; valid as long as the radio.
  Transport& endpoint(core::RobotId robot);

  /// Where a robot is now (ground truth); links follow these unless a schedule is set.
  void setPosition(core::RobotId robot, const Eigen::Vector3d& p_world);
  /// Links from now on follow `schedule` instead of positions.
  void setSchedule(std::vector<Rendezvous> schedule);

  /// Moves simulated time on to `time` (never back; throws core::Error) and
  /// delivers everything that has arrived by then to its endpoint, in
  /// arrival order (ties in the order sent).
  void advanceTo(double time);
  [[nodiscard]] double now() const;

  /// True when a and b are linked now.
  [[nodiscard]] bool linked(core::RobotId a, core::RobotId b) const;

  /// Traffic of `robot` so far (zeros for a robot never heard of).
  [[nodiscard]] RobotTraffic traffic(core::RobotId robot) const;
  /// Every message on every link so far, in the order sent.
  [[nodiscard]] const std::vector<TrafficEvent>& log() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::comm
