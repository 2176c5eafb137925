// `dcl-slam ping`: joins a swarm over Cyclone DDS as one robot, broadcasts
// numbered test messages through the Messenger and reports which robots were
// heard and what arrived from each: the check a robotics engineer runs before
// trusting the network between robot processes (same machine or not).
#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <ratio>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/comm/dds_transport.hpp>
#include <dcl/comm/messenger.hpp>
#include <dcl/core/error.hpp>

#include "commands.hpp"
#include "printing.hpp"
#include "process.hpp"
#include "robot_outputs.hpp"

namespace dcl::apps {

namespace {

using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

/// The most test messages one run sends: the Messenger keeps every reliable
/// broadcast for late joiners, so the log must stay small.
constexpr std::size_t kMaxMessages = 100'000;
/// s, the longest the loop sleeps: how soon a signal is noticed (and a
/// heartbeat sent, when heartbeat_period is shorter still).
constexpr double kMaxSleep = 0.1;

struct PingOptions {
  int robot = -1;
  std::size_t messages = 10;
  double period = 0.5;            ///< s between two test messages
  double duration = 10.0;         ///< s from joining to the summary
  std::uint32_t incarnation = 0;  ///< 0: from the clock (clockIncarnation)
  comm::DdsConfig dds;
  bool json = false;
};

// ---- payload -----------------------------------------------------------------

/// The text of test message `number`: it names its robot and the run's count,
/// so a receiver can tell a test message from a SLAM robot's descriptor and
/// knows when it has them all.
std::string payloadPrefix(core::RobotId robot, std::uint64_t number) {
  return fmt::format("dcl-slam ping: robot {}, message {} of ", robot.value(), number);
}

std::vector<std::uint8_t> payload(core::RobotId robot, std::uint64_t number, std::size_t count) {
  const std::string text = payloadPrefix(robot, number) + std::to_string(count);
  return {text.begin(), text.end()};
}

/// The count a test message announces, or nullopt when it is no test message
/// of `sender` (a descriptor of a SLAM robot in the same swarm, or a mismatch).
std::optional<std::size_t> pingCount(core::RobotId sender, const comm::DescriptorMessage& m) {
  const std::string_view text(reinterpret_cast<const char*>(m.descriptor.data()),
                              m.descriptor.size());
  const std::string prefix = payloadPrefix(sender, m.keyframe.value());
  if (!text.starts_with(prefix)) return std::nullopt;
  std::size_t count = 0;
  const char* first = text.data() + prefix.size();
  const char* last = text.data() + text.size();
  const auto [end, error] = std::from_chars(first, last, count);
  if (error != std::errc{} || end != last || first == last || m.keyframe.value() >= count)
    return std::nullopt;
  return count;
}

// ---- what arrived ------------------------------------------------------------

/// One process life of a peer as this robot heard it.
struct Life {
  std::uint32_t incarnation = 0;
  std::size_t count = 0;                        ///< messages it announced
  std::map<std::uint64_t, std::size_t> copies;  ///< message number -> deliveries
  std::optional<double> complete_at;            ///< s, when the last missing one arrived

  [[nodiscard]] std::size_t duplicates() const {
    std::size_t n = 0;
    for (const auto& [number, times] : copies) n += times - 1;
    return n;
  }
};

/// Everything one run has seen, beyond the messenger's own counters.
struct PingLog {
  std::map<core::RobotId, std::vector<Life>> lives;  ///< per peer, oldest first
  std::vector<comm::NeighbourEvent> events;
  std::set<core::RobotId> heard;
  std::size_t others = 0;  ///< delivered messages that are not test messages

  /// Files one delivered message; returns the life it completed, if it did.
  const Life* add(const comm::Message& m, double now) {
    const auto* descriptor = std::get_if<comm::DescriptorMessage>(&m.body);
    if (!descriptor) return nullptr;  // heartbeats count in the messenger's statistics
    const core::RobotId from = m.header.sender;
    const std::optional<std::size_t> count = pingCount(from, *descriptor);
    if (!count) {
      ++others;
      return nullptr;
    }
    Life& life = lifeOf(from, m.header.incarnation);
    life.count = *count;
    ++life.copies[descriptor->keyframe.value()];
    if (life.complete_at || life.copies.size() < life.count) return nullptr;
    life.complete_at = now;
    return &life;
  }

  Life& lifeOf(core::RobotId peer, std::uint32_t incarnation) {
    std::vector<Life>& of = lives[peer];
    const auto it = std::find_if(of.begin(), of.end(),
                                 [&](const Life& l) { return l.incarnation == incarnation; });
    if (it != of.end()) return *it;
    Life& life = of.emplace_back();
    life.incarnation = incarnation;
    return life;
  }

  [[nodiscard]] std::size_t duplicates() const {
    std::size_t n = 0;
    for (const auto& [peer, of] : lives) {
      for (const Life& life : of) n += life.duplicates();
    }
    return n;
  }
};

// ---- human-readable lines ------------------------------------------------------

std::string_view eventName(comm::NeighbourEvent::Type type) {
  switch (type) {
    case comm::NeighbourEvent::Type::appeared:
      return "appeared";
    case comm::NeighbourEvent::Type::lost:
      return "lost";
    case comm::NeighbourEvent::Type::restarted:
      return "restarted";
  }
  return "unknown";
}

void printLine(const std::string& line) {
  fmt::print("{}\n", line);
  std::fflush(stdout);  // lines as they happen, also into a pipe
}

/// "0-4, 7, 9-10".
std::string ranges(const std::vector<std::uint64_t>& sorted) {
  std::string out;
  for (std::size_t i = 0; i < sorted.size();) {
    std::size_t j = i;
    while (j + 1 < sorted.size() && sorted[j + 1] == sorted[j] + 1) ++j;
    if (!out.empty()) out += ", ";
    out += j == i ? fmt::format("{}", sorted[i]) : fmt::format("{}-{}", sorted[i], sorted[j]);
    i = j + 1;
  }
  return out.empty() ? "none" : out;
}

std::vector<std::uint64_t> numbers(const Life& life) {
  std::vector<std::uint64_t> out;
  for (const auto& [number, times] : life.copies) out.push_back(number);
  return out;
}

// ---- the run -------------------------------------------------------------------

struct PingRun {
  const PingOptions& options;
  core::RobotId self;
  std::uint32_t incarnation;
  comm::DdsTransport transport;
  comm::Messenger messenger;
  PingLog log;
  double max_sleep;      ///< s, see kMaxSleep
  std::size_t next = 0;  ///< the next message number to send
  Clock::time_point start = Clock::now();
  double started_at = 0.0;  ///< s since the Unix epoch

  PingRun(const PingOptions& o, const comm::MessengerConfig& config)
      : options(o),
        self(static_cast<std::uint8_t>(o.robot)),
        incarnation(o.incarnation > 0 ? o.incarnation : clockIncarnation()),
        transport(self, o.dds),
        messenger(transport, incarnation, config),
        max_sleep(std::min(kMaxSleep, config.heartbeat_period)) {
    start = Clock::now();
    started_at =
        std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  }

  /// s from the start at which message `number` is due.
  [[nodiscard]] double due(std::size_t number) const {
    return static_cast<double>(number) * options.period;
  }

  void sendDue(double now) {
    for (; next < options.messages && due(next) <= now; ++next) {
      comm::DescriptorMessage m{
          core::KeyframeId(next), now,          payload(self, next, options.messages),
          std::nullopt,           std::nullopt, {}};
      messenger.send(std::nullopt, std::move(m), now);
    }
  }

  void take(double now) {
    const std::vector<comm::Message> delivered = messenger.poll(now);
    for (const comm::NeighbourEvent& e : messenger.takeEvents()) {
      log.events.push_back(e);
      log.heard.insert(e.robot);
      if (!options.json)
        printLine(
            fmt::format("{:8.2f} s  robot {} {}", e.time, e.robot.value(), eventName(e.type)));
    }
    for (const comm::Message& m : delivered) {
      const Life* complete = log.add(m, now);
      if (complete && !options.json)
        printLine(fmt::format("{:8.2f} s  robot {}: all {} messages delivered (incarnation {})",
                              now, m.header.sender.value(), complete->count,
                              complete->incarnation));
    }
  }

  /// Sleeps until a sample arrives, the next message is due, the run ends,
  /// or a heartbeat may be due (the messenger's timers and a signal need a look).
  void sleep(double now) {
    double until = std::min(options.duration, now + max_sleep);
    if (next < options.messages) until = std::min(until, due(next));
    const double ms = std::ceil(std::max(0.0, until - secondsSince(start)) * 1000.0);
    transport.wait(std::chrono::milliseconds(static_cast<std::int64_t>(ms)));
  }

  /// Runs until --duration or a signal; returns the seconds it ran.
  double run() {
    for (double now = secondsSince(start); now < options.duration && stopSignal() == 0;
         now = secondsSince(start)) {
      sendDue(now);
      take(now);
      sleep(now);
    }
    return secondsSince(start);
  }
};

// ---- the summary -----------------------------------------------------------------

Json perKind(const std::array<std::size_t, comm::kMessageKinds>& counts) {
  Json j = Json::object();
  for (std::size_t k = 0; k < counts.size(); ++k)
    j[std::string(comm::name(static_cast<comm::MessageKind>(k)))] = counts[k];
  return j;
}

Json perReason(const std::array<std::size_t, comm::kDropReasons>& counts) {
  Json j = Json::object();
  for (std::size_t r = 0; r < counts.size(); ++r)
    j[std::string(comm::name(static_cast<comm::DropReason>(r)))] = counts[r];
  return j;
}

Json robotList(const std::set<core::RobotId>& robots) {
  Json j = Json::array();
  for (const core::RobotId r : robots) j.push_back(r.value());
  return j;
}

Json livesJson(const std::vector<Life>& of) {
  Json j = Json::array();
  for (const Life& life : of) {
    j.push_back({{"incarnation", life.incarnation},
                 {"count", life.count},
                 {"received", numbers(life)},
                 {"duplicates", life.duplicates()},
                 {"complete_at", life.complete_at ? Json(*life.complete_at) : Json(nullptr)}});
  }
  return j;
}

Json eventsJson(const std::vector<comm::NeighbourEvent>& events) {
  Json j = Json::array();
  for (const comm::NeighbourEvent& e : events)
    j.push_back({{"type", eventName(e.type)}, {"robot", e.robot.value()}, {"time", e.time}});
  return j;
}

Json summary(const PingRun& r, double seconds) {
  const comm::MessengerStats& stats = r.messenger.stats();
  Json received = Json::object();
  Json lives = Json::object();
  for (const auto& [peer, of] : r.log.lives) {
    received[std::to_string(peer.value())] = numbers(of.back());  // its latest life
    lives[std::to_string(peer.value())] = livesJson(of);
  }
  return {{"robot", r.self.value()},
          {"incarnation", r.incarnation},
          {"swarm", r.options.dds.swarm},
          {"domain", r.options.dds.domain},
          {"started_at", r.started_at},
          {"duration", seconds},
          {"interrupted", stopSignal() != 0},
          {"messages", r.options.messages},
          {"neighbours", robotList(r.log.heard)},
          {"present", robotList(r.messenger.neighbours())},
          {"received", received},
          {"lives", lives},
          {"duplicates", r.log.duplicates()},
          {"other_messages", r.log.others},
          {"events", eventsJson(r.log.events)},
          {"sent", perKind(stats.sent)},
          {"resent", perKind(stats.resent)},
          {"delivered", perKind(stats.delivered)},
          {"dropped", perReason(stats.dropped)},
          {"failed_writes", r.transport.failedWrites()}};
}

/// "descriptor 5, heartbeat 10" (non-zero entries only), or "none".
std::string nonZero(const Json& counts) {
  std::string out;
  for (const auto& [key, value] : counts.items()) {
    if (value.get<std::size_t>() == 0) continue;
    out += fmt::format("{}{} {}", out.empty() ? "" : ", ", key, value.get<std::size_t>());
  }
  return out.empty() ? "none" : out;
}

std::string robots(const Json& list) {
  std::string out;
  for (const Json& r : list) out += fmt::format("{}{}", out.empty() ? "" : ", ", r.get<int>());
  return out.empty() ? "none" : out;
}

void printLife(const std::string& peer, const Json& life) {
  const auto got = life["received"].get<std::vector<std::uint64_t>>();
  const std::size_t duplicates = life["duplicates"].get<std::size_t>();
  printLine(
      fmt::format("  robot {} (incarnation {}): {} of {} messages delivered ({}){}, {}", peer,
                  life["incarnation"].get<std::uint32_t>(), got.size(),
                  life["count"].get<std::size_t>(), ranges(got),
                  life["complete_at"].is_null()
                      ? std::string()
                      : fmt::format(", complete after {:.2f} s", life["complete_at"].get<double>()),
                  duplicates == 0 ? "none twice" : fmt::format("{} DELIVERED TWICE", duplicates)));
}

void printPingSummary(const Json& m) {
  printLine(fmt::format("ping summary: robot {} (incarnation {}), {:.1f} s{}",
                        m["robot"].get<int>(), m["incarnation"].get<std::uint32_t>(),
                        m["duration"].get<double>(),
                        m["interrupted"].get<bool>() ? ", interrupted" : ""));
  printLine(fmt::format("  neighbours heard: {} (present at the end: {})", robots(m["neighbours"]),
                        robots(m["present"])));
  for (const auto& [peer, of] : m["lives"].items()) {
    for (const Json& life : of) printLife(peer, life);
  }
  if (m["other_messages"].get<std::size_t>() > 0)
    printLine(fmt::format("  {} other messages (not from a ping) delivered",
                          m["other_messages"].get<std::size_t>()));
  printLine(fmt::format("  sent: {}", nonZero(m["sent"])));
  printLine(fmt::format("  resent: {}", nonZero(m["resent"])));
  printLine(fmt::format("  delivered: {}", nonZero(m["delivered"])));
  printLine(fmt::format("  dropped: {}", nonZero(m["dropped"])));
  printLine(fmt::format("  DDS failed writes: {}", m["failed_writes"].get<std::size_t>()));
}

// ---- the command -------------------------------------------------------------------

void validate(const PingOptions& o) {
  if (o.robot < 0 || o.robot > 254) throw core::Error("--robot must be in 0..254");
  if (o.messages > kMaxMessages)
    throw core::Error(fmt::format("--messages must be at most {}", kMaxMessages));
  if (!(o.period >= 0.0) || !std::isfinite(o.period))
    throw core::Error("--period must be a finite number >= 0");
  if (!(o.duration > 0.0) || !std::isfinite(o.duration))
    throw core::Error("--duration must be a finite number > 0");
  try {
    comm::validate(o.dds);
  } catch (const core::Error& e) {
    throw core::Error(std::string(e.what()) +
                      " (from --domain, --swarm, --interface or the config's dds section)");
  }
}

void runPing(const PingOptions& o, const comm::MessengerConfig& config) {
  validate(o);
  const StopSignals signals;
  PingRun r(o, config);
  if (!o.json)
    printLine(fmt::format(
        "ping: robot {} (incarnation {}) in swarm '{}', DDS domain {}{}: {} messages every {} s "
        "for {} s",
        r.self.value(), r.incarnation, o.dds.swarm, o.dds.domain,
        o.dds.interface.empty() ? std::string() : " on " + o.dds.interface, o.messages, o.period,
        o.duration));
  const double seconds = r.run();
  const Json m = summary(r, seconds);
  if (o.json) return printLine(m.dump(2));
  printPingSummary(m);
}

}  // namespace

void addPingCommand(CLI::App& app, const AppConfig& app_config) {
  auto* cmd = app.add_subcommand(
      "ping",
      "join a swarm over Cyclone DDS as one robot, broadcast numbered test messages and report "
      "the neighbours heard and what arrived from each (exactly once, across restarts)");
  auto o = std::make_shared<PingOptions>();
  o->dds = app_config.dds;
  cmd->add_option("--robot", o->robot, "this robot's id, 0..254")->required();
  cmd->add_option("--messages", o->messages, "test messages to broadcast")->capture_default_str();
  cmd->add_option("--period", o->period, "s between two test messages, from the start")
      ->capture_default_str();
  cmd->add_option("--duration", o->duration,
                  "s to run before the summary (SIGINT, SIGTERM: sooner)")
      ->capture_default_str();
  cmd->add_option("--domain", o->dds.domain, "DDS domain id (default: dds.domain)")
      ->capture_default_str();
  cmd->add_option("--swarm", o->dds.swarm, "swarm name, the DDS partition (default: dds.swarm)")
      ->capture_default_str();
  cmd->add_option("--interface", o->dds.interface,
                  "network interface with multicast discovery, e.g. lo (default: dds.interface)");
  cmd->add_option("--incarnation", o->incarnation,
                  "this process life's number, larger than the last one's (default, or 0: tenths "
                  "of a second since 2024-01-01 UTC)");
  cmd->add_flag("--json", o->json, "print the summary as one JSON object, and nothing else");
  cmd->callback([o, &app_config] { runPing(*o, app_config.messenger); });
}

}  // namespace dcl::apps
