#include <algorithm>
#include <cmath>
#include <functional>
#include <iterator>
#include <memory>
#include <queue>
#include <random>
#include <set>
#include <string>
#include <utility>

#include <dcl/comm/sim_radio.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>

namespace dcl::comm {
namespace {

using core::RobotId;

/// SplitMix64's finaliser: spreads the seed and a robot id over all 64 bits,
/// so that neighbouring seeds or robots get unrelated loss streams.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27U)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31U);
}

/// A uniform number in [0, 1) from the generator's top 53 bits. The standard
/// distributions differ between library implementations; this does not, so a
/// seed gives the same losses everywhere.
double unitInterval(std::mt19937_64& generator) {
  return static_cast<double>(generator() >> 11U) * 0x1.0p-53;
}

std::string seconds(double t) {
  return std::to_string(t) + " s";
}

/// A transmission on its way: when it arrives, its log entry (which also
/// orders ties: the log is in the order sent) and its bytes, shared by the
/// receivers of a broadcast.
struct InFlight {
  double arrival = 0.0;
  std::size_t entry = 0;
  std::shared_ptr<const std::vector<std::uint8_t>> bytes;

  /// The priority queue's order: the earliest arrival, then the earliest sent, on top.
  bool operator>(const InFlight& other) const {
    return arrival != other.arrival ? arrival > other.arrival : entry > other.entry;
  }
};

}  // namespace

void validate(const SimRadioConfig& config) {
  core::checkConfig(config, "sim radio config");
}

struct SimRadio::Impl {
  /// A robot's side of the radio: sends go to the medium, deliveries wait in
  /// the inbox until the robot asks.
  class Endpoint final : public Transport {
   public:
    Endpoint(Impl& radio, RobotId robot) : radio_(radio), self_(robot) {}
    [[nodiscard]] RobotId self() const override { return self_; }
    void send(std::optional<RobotId> to, MessageKind kind,
              std::span<const std::uint8_t> bytes) override {
      radio_.transmit(self_, to, kind, bytes);
    }
    std::vector<Datagram> receive() override { return std::exchange(inbox_, {}); }
    void deliver(Datagram datagram) { inbox_.push_back(std::move(datagram)); }

   private:
    Impl& radio_;
    RobotId self_;
    std::vector<Datagram> inbox_;
  };

  SimRadioConfig config;
  double now = 0.0;
  std::set<RobotId> robots;  ///< every robot heard of, in id order (broadcast order)
  std::map<RobotId, std::unique_ptr<Endpoint>> endpoints;
  std::map<RobotId, Eigen::Vector3d> positions;
  std::optional<std::vector<Rendezvous>> schedule;
  std::map<std::pair<RobotId, RobotId>, double> link_free;  ///< s, when a directed link is idle
  std::map<RobotId, std::mt19937_64> loss_streams;          ///< per receiver
  std::priority_queue<InFlight, std::vector<InFlight>, std::greater<>> in_flight;
  std::vector<TrafficEvent> log;
  std::map<RobotId, RobotTraffic> traffic;

  explicit Impl(const SimRadioConfig& c) : config(c) { validate(config); }

  Endpoint& endpoint(RobotId robot) {
    auto& slot = endpoints[robot];
    if (!slot) {
      slot = std::make_unique<Endpoint>(*this, robot);
      robots.insert(robot);
    }
    return *slot;
  }

  /// Whether a and b can talk at `t`: the schedule is a function of time, so
  /// it is asked at `t`; positions are only known as last set.
  [[nodiscard]] bool linkedAt(RobotId a, RobotId b, double t) const {
    if (a == b) return false;
    if (schedule) {
      return std::any_of(schedule->begin(), schedule->end(), [&](const Rendezvous& r) {
        const bool pair = (r.a == a && r.b == b) || (r.a == b && r.b == a);
        return pair && r.start <= t && t < r.end;
      });
    }
    if (config.range == 0.0) return robots.contains(a) && robots.contains(b);
    const auto pa = positions.find(a);
    const auto pb = positions.find(b);
    if (pa == positions.end() || pb == positions.end()) return false;
    return (pa->second - pb->second).norm() < config.range;
  }

  /// Each receiver's losses come from its own stream: what one robot loses
  /// does not depend on how much the others hear.
  std::mt19937_64& lossStream(RobotId receiver) {
    auto it = loss_streams.find(receiver);
    if (it == loss_streams.end()) {
      const std::uint64_t seed = mix(config.seed ^ mix(receiver.value()));
      it = loss_streams.emplace(receiver, std::mt19937_64(seed)).first;
    }
    return it->second;
  }

  [[nodiscard]] std::size_t bin(double t) const {
    return static_cast<std::size_t>(std::floor(t / config.meter_interval));
  }

  void meterSent(RobotId from, MessageKind kind, std::size_t n) {
    RobotTraffic& t = traffic[from];
    t.sent += n;
    ++t.messages_sent;
    t.sent_by_kind[static_cast<std::size_t>(kind)] += n;
    const std::size_t b = bin(now);
    if (t.sent_over_time.size() <= b) t.sent_over_time.resize(b + 1, 0);
    t.sent_over_time[b] += n;
  }

  void meterDelivered(const TrafficEvent& e) {
    RobotTraffic& sender = traffic[e.from];
    sender.delivered_to[*e.to] += e.bytes;
    RobotTraffic& receiver = traffic[*e.to];
    receiver.received += e.bytes;
    ++receiver.messages_received;
    receiver.received_from[e.from] += e.bytes;
    receiver.received_by_kind[static_cast<std::size_t>(e.kind)] += e.bytes;
  }

  /// Queues one message on the link from -> to behind what the link is still
  /// sending; decides its loss now, so the loss stream follows the send order.
  void enqueue(TrafficEvent event, const std::shared_ptr<const std::vector<std::uint8_t>>& bytes) {
    double& free = link_free[{event.from, *event.to}];
    const double start = std::max(now, free);
    const double transmission =
        config.bandwidth > 0.0 ? static_cast<double>(event.bytes) / config.bandwidth : 0.0;
    free = start + transmission;
    event.arrival = free + config.latency;
    const bool lost = unitInterval(lossStream(*event.to)) < config.drop_rate;
    event.fate = lost ? Fate::lost : Fate::delivered;
    log.push_back(event);
    if (!lost) in_flight.push({event.arrival, log.size() - 1, bytes});
  }

  void transmit(RobotId from, std::optional<RobotId> to, MessageKind kind,
                std::span<const std::uint8_t> data) {
    if (static_cast<std::size_t>(kind) >= kMessageKinds)
      throw core::Error("sim radio: robot " + core::robotName(from) + " sent message kind " +
                        std::to_string(static_cast<int>(kind)) + ", which does not exist");
    TrafficEvent event{now, now, from, to, !to.has_value(), kind, data.size(), Fate::unreachable};
    std::vector<RobotId> receivers;
    if (to) {
      if (linkedAt(from, *to, now)) receivers.push_back(*to);
    } else {
      std::copy_if(robots.begin(), robots.end(), std::back_inserter(receivers),
                   [&](RobotId r) { return linkedAt(from, r, now); });
    }
    if (receivers.empty()) {
      log.push_back(event);  // never on the air: nobody to carry it to
      return;
    }
    meterSent(from, kind, data.size());
    const auto bytes = std::make_shared<const std::vector<std::uint8_t>>(data.begin(), data.end());
    for (RobotId receiver : receivers) {
      event.to = receiver;
      enqueue(event, bytes);
    }
  }

  /// Hands a message that has arrived to its receiver if the link still holds.
  void settle(const InFlight& message) {
    TrafficEvent& e = log[message.entry];
    if (!linkedAt(e.from, *e.to, e.arrival)) {
      e.fate = Fate::link_down;
      return;
    }
    endpoint(*e.to).deliver(Datagram{e.from, e.kind, *message.bytes});
    meterDelivered(e);
  }

  void advanceTo(double time) {
    if (!std::isfinite(time)) throw core::Error("sim radio: advanceTo needs a finite time");
    if (time < now)
      throw core::Error("sim radio: cannot go back in time from " + seconds(now) + " to " +
                        seconds(time));
    now = time;
    while (!in_flight.empty() && in_flight.top().arrival <= now) {
      const InFlight message = in_flight.top();
      in_flight.pop();
      settle(message);
    }
  }
};

SimRadio::SimRadio(const SimRadioConfig& config) : impl_(std::make_unique<Impl>(config)) {}

SimRadio::~SimRadio() = default;

Transport& SimRadio::endpoint(core::RobotId robot) {
  if (!robot.valid()) throw core::Error("sim radio: endpoint of an invalid robot id");
  return impl_->endpoint(robot);
}

void SimRadio::setPosition(core::RobotId robot, const Eigen::Vector3d& p_world) {
  if (!robot.valid()) throw core::Error("sim radio: position of an invalid robot id");
  if (!p_world.allFinite())
    throw core::Error("sim radio: position of robot " + core::robotName(robot) + " is not finite");
  impl_->positions[robot] = p_world;
  impl_->robots.insert(robot);
}

void SimRadio::setSchedule(std::vector<Rendezvous> schedule) {
  for (std::size_t i = 0; i < schedule.size(); ++i) {
    const Rendezvous& r = schedule[i];
    const auto fail = [i](const std::string& what) {
      throw core::Error("sim radio schedule: rendezvous " + std::to_string(i) + ": " + what);
    };
    if (!r.a.valid() || !r.b.valid()) fail("invalid robot id");
    if (r.a == r.b) fail("robot " + core::robotName(r.a) + " meets itself");
    if (!std::isfinite(r.start) || !std::isfinite(r.end)) fail("start and end must be finite");
    if (r.end < r.start) fail("end " + seconds(r.end) + " is before start " + seconds(r.start));
  }
  for (const Rendezvous& r : schedule) impl_->robots.insert({r.a, r.b});
  impl_->schedule = std::move(schedule);
}

void SimRadio::advanceTo(double time) {
  impl_->advanceTo(time);
}

double SimRadio::now() const {
  return impl_->now;
}

bool SimRadio::linked(core::RobotId a, core::RobotId b) const {
  return impl_->linkedAt(a, b, impl_->now);
}

RobotTraffic SimRadio::traffic(core::RobotId robot) const {
  const auto it = impl_->traffic.find(robot);
  RobotTraffic t = it == impl_->traffic.end() ? RobotTraffic{} : it->second;
  // Every robot's series covers the run so far, silent stretches included.
  const std::size_t bins = impl_->bin(impl_->now) + 1;
  if (t.sent_over_time.size() < bins) t.sent_over_time.resize(bins, 0);
  return t;
}

const std::vector<TrafficEvent>& SimRadio::log() const {
  return impl_->log;
}

}  // namespace dcl::comm
