#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <numbers>
#include <random>
#include <utility>

#include <gtest/gtest.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <dcl/comm/messenger.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/place/descriptor_codec.hpp>

#include "../common/keys.hpp"

namespace dcl::comm {
namespace {

using core::RobotId;

using dcl::test::robot;

// ---------------------------------------------------------------- an in-memory medium

/// What a medium does to the datagrams it carries, each fault on a fixed
/// pattern so that every run is the same.
struct Faults {
  std::vector<bool> loss;   ///< cycled over deliveries; true: that delivery is lost
  int duplicate_every = 0;  ///< every n-th delivery arrives twice (0: never)
  int delay_every = 0;      ///< every n-th delivery arrives one receive() late (0: never)
  bool shuffle = false;     ///< each receive() hands its batch out in a seeded random order
  bool reverse = false;     ///< each receive() hands its batch out last first
  bool shared = false;      ///< unicasts reach every robot in range (a shared radio channel)
};

/// N endpoints on one medium that a test can partition, make lossy, reorder,
/// duplicate and inject raw bytes into. A datagram lands in its receiver's
/// inbox when it is sent, if the two are linked at that moment.
class Medium {
 public:
  struct Sent {
    RobotId from;
    std::optional<RobotId> to;
    MessageKind kind;
    std::vector<std::uint8_t> bytes;
  };

  explicit Medium(int robots)
      : linked_(static_cast<std::size_t>(robots), std::vector<bool>(robots, true)),
        inbox_(static_cast<std::size_t>(robots)),
        held_(static_cast<std::size_t>(robots)) {
    for (int r = 0; r < robots; ++r) endpoints_.push_back(std::make_unique<Endpoint>(*this, r));
  }

  Transport& endpoint(int r) { return *endpoints_[static_cast<std::size_t>(r)]; }

  void link(int a, int b, bool up) {
    linked_[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)] = up;
    linked_[static_cast<std::size_t>(b)][static_cast<std::size_t>(a)] = up;
  }

  void inject(int to, Datagram datagram) {
    inbox_[static_cast<std::size_t>(to)].push_back(std::move(datagram));
  }

  /// Every datagram handed to the medium, linked or not, in order.
  [[nodiscard]] const std::vector<Sent>& tap() const { return tap_; }

  Faults faults;

 private:
  class Endpoint : public Transport {
   public:
    Endpoint(Medium& medium, int id) : medium_(medium), id_(id) {}
    [[nodiscard]] RobotId self() const override { return robot(id_); }
    void send(std::optional<RobotId> to, MessageKind kind,
              std::span<const std::uint8_t> bytes) override {
      medium_.carry(id_, to, kind, bytes);
    }
    std::vector<Datagram> receive() override { return medium_.take(id_); }

   private:
    Medium& medium_;
    int id_;
  };

  void carry(int from, std::optional<RobotId> to, MessageKind kind,
             std::span<const std::uint8_t> bytes) {
    tap_.push_back({robot(from), to, kind, {bytes.begin(), bytes.end()}});
    for (int r = 0; r < static_cast<int>(inbox_.size()); ++r) {
      if (r == from || !linked_[static_cast<std::size_t>(from)][static_cast<std::size_t>(r)])
        continue;
      if (to && *to != robot(r) && !faults.shared) continue;
      deliver(r, Datagram{robot(from), kind, {bytes.begin(), bytes.end()}});
    }
  }

  void deliver(int to, Datagram datagram) {
    const std::size_t n = ++deliveries_;
    if (!faults.loss.empty() && faults.loss[n % faults.loss.size()]) return;
    const bool late =
        faults.delay_every > 0 && n % static_cast<std::size_t>(faults.delay_every) == 0;
    auto& box = (late ? held_ : inbox_)[static_cast<std::size_t>(to)];
    if (faults.duplicate_every > 0 && n % static_cast<std::size_t>(faults.duplicate_every) == 0)
      box.push_back(datagram);
    box.push_back(std::move(datagram));
  }

  std::vector<Datagram> take(int r) {
    const auto i = static_cast<std::size_t>(r);
    std::vector<Datagram> batch = std::exchange(inbox_[i], std::exchange(held_[i], {}));
    if (faults.shuffle) std::shuffle(batch.begin(), batch.end(), rng_);
    if (faults.reverse) std::reverse(batch.begin(), batch.end());
    return batch;
  }

  std::vector<std::vector<bool>> linked_;
  std::vector<std::vector<Datagram>> inbox_;
  std::vector<std::vector<Datagram>> held_;
  std::vector<std::unique_ptr<Endpoint>> endpoints_;
  std::vector<Sent> tap_;
  std::size_t deliveries_ = 0;
  std::mt19937 rng_{11};
};

// ---------------------------------------------------------------- robots on it

/// N messengers on one medium, polled in robot order every `kStep` seconds.
class Swarm {
 public:
  static constexpr double kStep = 0.1;

  explicit Swarm(int robots, const MessengerConfig& config = {})
      : medium(robots), config_(config), nodes_(static_cast<std::size_t>(robots)) {
    for (int r = 0; r < robots; ++r) restart(r, 1);
  }

  /// Replaces robot r's messenger by a new one in life `incarnation`, as a restarted process.
  void restart(int r, std::uint32_t incarnation) {
    Node& node = nodes_[static_cast<std::size_t>(r)];
    node = Node{};
    node.messenger = std::make_unique<Messenger>(medium.endpoint(r), incarnation, config_);
  }

  /// Polls every robot at each step up to `end` (s).
  void runTo(double end) {
    for (; static_cast<double>(tick_) * kStep <= end + 1e-9; ++tick_) {
      now_ = static_cast<double>(tick_) * kStep;
      for (Node& node : nodes_) {
        std::vector<Message> got = node.messenger->poll(now_);
        node.inbox.insert(node.inbox.end(), got.begin(), got.end());
        std::vector<NeighbourEvent> events = node.messenger->takeEvents();
        node.events.insert(node.events.end(), events.begin(), events.end());
      }
    }
  }

  void send(int from, std::optional<int> to, Body body) {
    messenger(from).send(to ? std::optional(robot(*to)) : std::nullopt, std::move(body), now_);
  }

  Messenger& messenger(int r) { return *nodes_[static_cast<std::size_t>(r)].messenger; }
  /// Everything robot r's current messenger delivered, in order.
  const std::vector<Message>& inbox(int r) { return nodes_[static_cast<std::size_t>(r)].inbox; }
  const std::vector<NeighbourEvent>& events(int r) {
    return nodes_[static_cast<std::size_t>(r)].events;
  }
  [[nodiscard]] double now() const { return now_; }

  Medium medium;

 private:
  struct Node {
    std::unique_ptr<Messenger> messenger;
    std::vector<Message> inbox;
    std::vector<NeighbourEvent> events;
  };

  MessengerConfig config_;
  std::vector<Node> nodes_;
  std::size_t tick_ = 0;
  double now_ = 0.0;
};

// ---------------------------------------------------------------- real message bodies

/// The compact LiDAR-Iris encoding of a synthetic occupancy image: near rows
/// full, far rows sparse, varying with the keyframe.
std::vector<std::uint8_t> encodedIris(int keyframe) {
  place::IrisImage image{80, 360, std::vector<std::uint8_t>(80 * 360, 0)};
  std::mt19937 rng(static_cast<unsigned>(keyframe) + 1U);
  for (int r = 0; r < 80; ++r) {
    for (int c = 0; c < 360; ++c) {
      if (static_cast<int>(rng() % 80U) < 80 - r)
        image.cells[static_cast<std::size_t>(r * 360 + c)] = static_cast<std::uint8_t>(rng());
    }
  }
  return place::encodeIrisImage(image);
}

/// Eight different descriptors, encoded once.
const std::vector<std::uint8_t>& irisBytes(int which) {
  static const std::vector<std::vector<std::uint8_t>> all = [] {
    std::vector<std::vector<std::uint8_t>> out;
    for (int i = 0; i < 8; ++i) out.push_back(encodedIris(i));
    return out;
  }();
  return all[static_cast<std::size_t>(which)];
}

DescriptorMessage descriptor(int keyframe) {
  return {core::KeyframeId(static_cast<std::uint64_t>(keyframe)),
          0.5 * keyframe,
          irisBytes(keyframe % 8),
          std::nullopt,
          std::nullopt,
          {}};
}

LoopMeasurement measurement(int query) {
  LoopMeasurement m;
  m.query = core::KeyframeId(static_cast<std::uint64_t>(query));
  m.match = core::KeyframeId(static_cast<std::uint64_t>(query + 100));
  m.T_match_query = core::makePose(Eigen::Vector3d(0.5 * query, 2.0, -0.3),
                                   core::expSO3(Eigen::Vector3d(0.01, -0.02, 0.05 * query)));
  core::Vector6d variances;
  variances << 0.04, 0.04, 0.09, 1e-4, 1e-4, 4e-4;
  m.covariance = variances.asDiagonal();
  m.covariance(0, 1) = m.covariance(1, 0) = 0.01;
  return m;
}

/// How often each (kind, keyframe) from `sender` was delivered.
std::map<std::pair<MessageKind, std::uint64_t>, int> deliveries(const std::vector<Message>& inbox,
                                                                int sender) {
  std::map<std::pair<MessageKind, std::uint64_t>, int> count;
  for (const Message& m : inbox) {
    if (m.header.sender != robot(sender)) continue;
    if (const auto* d = std::get_if<DescriptorMessage>(&m.body))
      ++count[{m.kind(), d->keyframe.value()}];
    if (const auto* l = std::get_if<LoopMeasurement>(&m.body))
      ++count[{m.kind(), l->query.value()}];
  }
  return count;
}

/// Each of `keyframes` delivered exactly once as `kind`, nothing else of that kind.
void expectEachOnce(const std::map<std::pair<MessageKind, std::uint64_t>, int>& count,
                    MessageKind kind, int first, int last) {
  int seen = 0;
  for (const auto& [key, n] : count) {
    if (key.first != kind) continue;
    ++seen;
    EXPECT_EQ(n, 1) << name(kind) << " " << key.second << " delivered " << n << " times";
    EXPECT_GE(key.second, static_cast<std::uint64_t>(first)) << name(kind);
    EXPECT_LE(key.second, static_cast<std::uint64_t>(last)) << name(kind);
  }
  EXPECT_EQ(seen, last - first + 1) << name(kind);
}

std::size_t delivered(const Messenger& m) {
  std::size_t n = 0;
  for (std::size_t k : m.stats().delivered) n += k;
  return n;
}

/// The acknowledgement of `peer` in the last heartbeat `from` sent.
std::optional<Ack> lastAck(const Medium& medium, int from, int peer) {
  for (auto it = medium.tap().rbegin(); it != medium.tap().rend(); ++it) {
    if (it->from != robot(from) || it->kind != MessageKind::heartbeat) continue;
    const Decoded d = decode(it->bytes);
    for (const Ack& ack : std::get<Heartbeat>(d.message->body).acks) {
      if (ack.peer == robot(peer)) return ack;
    }
    return std::nullopt;
  }
  return std::nullopt;
}

/// The reliable datagrams robot `from` handed to the medium, first transmissions and repeats.
std::vector<Medium::Sent> sentBy(const Medium& medium, int from, MessageKind kind) {
  std::vector<Medium::Sent> out;
  for (const Medium::Sent& s : medium.tap()) {
    if (s.from == robot(from) && s.kind == kind) out.push_back(s);
  }
  return out;
}

Datagram datagram(int from, const std::vector<std::uint8_t>& bytes,
                  MessageKind kind = MessageKind::descriptor) {
  return {robot(from), kind, bytes};
}

// ---------------------------------------------------------------- reliability

TEST(Messenger, DeliversEveryReliableMessageExactlyOnceOverALossyDuplicatingReorderingMedium) {
  Swarm swarm(3);
  swarm.medium.faults = {{false, false, true}, 4, 5, true, false, true};  // a third lost
  for (int i = 0; i < 30; ++i) {
    swarm.runTo(0.2 * i);
    swarm.send(0, std::nullopt, descriptor(i));
    if (i < 20) swarm.send(0, 1, measurement(i));
    if (i < 10) swarm.send(1, 0, measurement(i));
  }
  swarm.runTo(30.0);

  for (int r : {1, 2})
    expectEachOnce(deliveries(swarm.inbox(r), 0), MessageKind::descriptor, 0, 29);
  expectEachOnce(deliveries(swarm.inbox(1), 0), MessageKind::loop_measurement, 0, 19);
  expectEachOnce(deliveries(swarm.inbox(0), 1), MessageKind::loop_measurement, 0, 9);
  EXPECT_EQ(deliveries(swarm.inbox(2), 0).count({MessageKind::loop_measurement, 0}), 0U);
  for (const Message& m : swarm.inbox(1)) {  // the bodies arrive as sent
    if (const auto* d = std::get_if<DescriptorMessage>(&m.body)) {
      EXPECT_EQ(d->descriptor, irisBytes(static_cast<int>(d->keyframe.value()) % 8));
    }
    if (const auto* l = std::get_if<LoopMeasurement>(&m.body)) {
      const LoopMeasurement sent = measurement(static_cast<int>(l->query.value()));
      EXPECT_EQ(l->match, sent.match);
      EXPECT_LT((l->T_match_query.matrix() - sent.T_match_query.matrix()).norm(), 1e-3);
    }
  }
  // The faults happened, and the messengers absorbed them.
  const MessengerStats& a = swarm.messenger(0).stats();
  const auto k = [](MessageKind kind) { return static_cast<std::size_t>(kind); };
  std::printf("lossy medium: a sent %zu descriptors and %zu measurements, re-sent %zu and %zu\n",
              a.sent[k(MessageKind::descriptor)], a.sent[k(MessageKind::loop_measurement)],
              a.resent[k(MessageKind::descriptor)], a.resent[k(MessageKind::loop_measurement)]);
  EXPECT_GT(swarm.messenger(0).stats().resent[static_cast<std::size_t>(MessageKind::descriptor)],
            0U);
  EXPECT_GT(swarm.messenger(1).stats().dropped[static_cast<std::size_t>(DropReason::duplicate)],
            0U);
  EXPECT_GT(swarm.messenger(2).stats().dropped[static_cast<std::size_t>(DropReason::not_for_me)],
            0U);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 0U);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(2)), 0U);
  EXPECT_EQ(swarm.messenger(1).unacknowledged(robot(0)), 0U);
}

TEST(Messenger, NeighbourOutOfRangeGetsWhatItMissedOnReturnAndNothingTwice) {
  MessengerConfig config;
  config.retransmit_after = 1000.0;  // only the return can trigger the catch-up
  Swarm swarm(2, config);
  swarm.runTo(1.0);
  for (int i = 0; i < 5; ++i) swarm.send(0, std::nullopt, descriptor(i));
  for (int i = 0; i < 3; ++i) swarm.send(0, 1, measurement(i));
  swarm.runTo(3.0);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 0U);

  swarm.medium.link(0, 1, false);
  swarm.runTo(5.0);  // b is still a neighbour of a, though out of range
  for (int i = 5; i < 8; ++i) swarm.send(0, std::nullopt, descriptor(i));
  swarm.send(0, 1, measurement(3));
  swarm.runTo(8.0);  // b is gone
  EXPECT_FALSE(swarm.messenger(0).neighbours().contains(robot(1)));
  for (int i = 8; i < 10; ++i) swarm.send(0, std::nullopt, descriptor(i));
  for (int i = 4; i < 6; ++i) swarm.send(0, 1, measurement(i));
  swarm.runTo(11.9);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 5U + 3U);
  expectEachOnce(deliveries(swarm.inbox(1), 0), MessageKind::descriptor, 0, 4);

  swarm.medium.link(0, 1, true);
  swarm.runTo(13.5);
  expectEachOnce(deliveries(swarm.inbox(1), 0), MessageKind::descriptor, 0, 9);
  expectEachOnce(deliveries(swarm.inbox(1), 0), MessageKind::loop_measurement, 0, 5);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 0U);
}

TEST(Messenger, ARobotMetLateReceivesEveryEarlierBroadcast) {
  MessengerConfig config;
  config.retransmit_after = 1000.0;
  Swarm swarm(3, config);
  swarm.medium.link(0, 2, false);
  swarm.medium.link(1, 2, false);
  for (int i = 0; i < 12; ++i) {
    swarm.runTo(0.4 * i);
    swarm.send(0, std::nullopt, descriptor(i));
    if (i % 4 == 0) swarm.send(1, std::nullopt, descriptor(100 + i / 4));
  }
  swarm.runTo(10.0);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(2)), 12U);  // never heard: all of it
  EXPECT_TRUE(swarm.inbox(2).empty());

  swarm.medium.link(0, 2, true);
  swarm.medium.link(1, 2, true);
  swarm.runTo(11.5);
  expectEachOnce(deliveries(swarm.inbox(2), 0), MessageKind::descriptor, 0, 11);
  expectEachOnce(deliveries(swarm.inbox(2), 1), MessageKind::descriptor, 100, 102);
  swarm.runTo(12.5);  // c's next heartbeat acknowledges them
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(2)), 0U);
  EXPECT_EQ(swarm.messenger(1).unacknowledged(robot(2)), 0U);
}

TEST(Messenger, AcknowledgesTheContiguousPrefixOfOutOfOrderArrivalsWithinTheWindow) {
  MessengerConfig config;
  config.window = 4;
  Swarm swarm(2, config);
  swarm.medium.link(0, 1, false);
  swarm.runTo(0.0);
  for (int i = 0; i < 7; ++i) swarm.send(0, std::nullopt, descriptor(i));
  const std::vector<Medium::Sent> sent = sentBy(swarm.medium, 0, MessageKind::descriptor);
  ASSERT_EQ(sent.size(), 7U);
  Messenger& b = swarm.messenger(1);
  const auto inject = [&](std::initializer_list<int> sequences) {
    for (int s : sequences)
      swarm.medium.inject(1, datagram(0, sent[static_cast<std::size_t>(s - 1)].bytes));
  };
  const auto ackOfA = [&] { return lastAck(swarm.medium, 1, 0).value_or(Ack{}).broadcast; };
  const auto dropped = [&](DropReason r) { return b.stats().dropped[static_cast<std::size_t>(r)]; };

  inject({3, 1});
  swarm.runTo(0.1);
  EXPECT_EQ(delivered(b), 2U);
  inject({6, 5});  // 6 is 5 beyond the contiguous 1: out of the window of 4
  swarm.runTo(1.0);
  EXPECT_EQ(ackOfA(), 1U);
  EXPECT_EQ(dropped(DropReason::out_of_window), 1U);
  EXPECT_EQ(delivered(b), 3U);  // no heartbeat of a: a and b are not linked
  inject({2, 2});
  swarm.runTo(2.0);
  EXPECT_EQ(ackOfA(), 3U);
  EXPECT_EQ(dropped(DropReason::duplicate), 1U);
  inject({4, 6, 7});
  swarm.runTo(3.0);
  EXPECT_EQ(ackOfA(), 7U);
  std::vector<std::uint64_t> order;
  for (const Message& m : swarm.inbox(1)) order.push_back(m.header.sequence);
  EXPECT_EQ(order, (std::vector<std::uint64_t>{3, 1, 5, 2, 4, 6, 7}));  // arrival order, once each

  swarm.medium.link(0, 1, true);  // b's acks reach a: nothing left to send
  swarm.runTo(5.0);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 0U);
  EXPECT_EQ(deliveries(swarm.inbox(1), 0).size(), 7U);
}

TEST(Messenger, SelectiveAcknowledgementsSpareWhatArrivedBeyondAGap) {
  Swarm swarm(2);
  swarm.medium.link(0, 1, false);
  swarm.runTo(0.0);
  swarm.messenger(1).setKeyframes(42);
  for (int i = 0; i < 6; ++i) swarm.send(0, std::nullopt, descriptor(i));
  const std::vector<Medium::Sent> sent = sentBy(swarm.medium, 0, MessageKind::descriptor);
  ASSERT_EQ(sent.size(), 6U);
  for (int s : {1, 3, 4, 6})
    swarm.medium.inject(1, datagram(0, sent[static_cast<std::size_t>(s - 1)].bytes));
  swarm.runTo(1.5);
  const Ack ack = lastAck(swarm.medium, 1, 0).value_or(Ack{});
  EXPECT_EQ(ack.broadcast, 1U);
  EXPECT_EQ(ack.broadcast_above, 0b1011U);  // 3, 4 and 6 arrived too: bits 0, 1 and 3
  const Decoded beat = decode(sentBy(swarm.medium, 1, MessageKind::heartbeat).back().bytes);
  ASSERT_TRUE(beat.message);
  EXPECT_EQ(std::get<Heartbeat>(beat.message->body).keyframes, 42U);

  swarm.medium.link(0, 1, true);
  swarm.runTo(5.0);
  // Only 2 and 5 went again; b holds all six, once each.
  EXPECT_EQ(sentBy(swarm.medium, 0, MessageKind::descriptor).size(), sent.size() + 2);
  EXPECT_EQ(deliveries(swarm.inbox(1), 0).size(), 6U);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 0U);
}

// ---------------------------------------------------------------- restarts

TEST(Messenger, RestartedPeerGetsEverythingAgainAndItsNewMessagesAreNotReplays) {
  Swarm swarm(2);
  swarm.runTo(0.5);
  for (int i = 0; i < 4; ++i) swarm.send(0, std::nullopt, descriptor(i));
  for (int i = 0; i < 3; ++i) swarm.send(0, 1, measurement(i));
  for (int i = 0; i < 2; ++i) swarm.send(1, 0, measurement(10 + i));
  swarm.runTo(4.0);
  ASSERT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 0U);
  const std::vector<Medium::Sent> old_life = sentBy(swarm.medium, 1, MessageKind::loop_measurement);
  ASSERT_FALSE(old_life.empty());

  swarm.restart(1, 2);  // b's process restarts: it remembers nothing
  swarm.medium.link(0, 1, false);
  for (int i = 0; i < 2; ++i) swarm.send(1, 0, measurement(20 + i));  // sequences 1, 2 again
  swarm.runTo(4.5);  // lost; a's heartbeats still acknowledge b's sequences 1, 2 of its last life
  swarm.medium.link(0, 1, true);
  swarm.runTo(7.0);

  expectEachOnce(deliveries(swarm.inbox(1), 0), MessageKind::descriptor, 0, 3);
  expectEachOnce(deliveries(swarm.inbox(1), 0), MessageKind::loop_measurement, 0, 2);
  const auto from_b = deliveries(swarm.inbox(0), 1);
  EXPECT_EQ(from_b.size(), 4U);
  EXPECT_EQ(from_b.count({MessageKind::loop_measurement, 20}), 1U);
  EXPECT_EQ(from_b.count({MessageKind::loop_measurement, 21}), 1U);
  const std::vector<NeighbourEvent>& events = swarm.events(0);
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().type, NeighbourEvent::Type::restarted);
  EXPECT_EQ(events.back().robot, robot(1));
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 0U);

  // A message of b's earlier life, arriving late or replayed, is stale.
  const std::size_t before = swarm.inbox(0).size();
  swarm.medium.inject(0, datagram(1, old_life.back().bytes, MessageKind::loop_measurement));
  swarm.runTo(7.1);
  EXPECT_EQ(swarm.inbox(0).size(), before);
  const auto& dropped = swarm.messenger(0).stats().dropped_from.at(robot(1));
  EXPECT_EQ(dropped[static_cast<std::size_t>(DropReason::stale_incarnation)], 1U);
}

// ---------------------------------------------------------------- neighbours

TEST(Messenger, ReportsNeighboursAppearingAndLostAtTheRightTimes) {
  Swarm swarm(2);  // heartbeat 1 s, timeout 3.5 s
  swarm.runTo(5.0);
  using Type = NeighbourEvent::Type;
  ASSERT_EQ(swarm.events(1).size(), 1U);
  EXPECT_EQ(swarm.events(1)[0].type, Type::appeared);
  EXPECT_NEAR(swarm.events(1)[0].time, 0.0, 1e-9);  // a's first heartbeat, polled just before
  ASSERT_EQ(swarm.events(0).size(), 1U);
  EXPECT_NEAR(swarm.events(0)[0].time, 0.1, 1e-9);  // b's, heard at a's next poll
  EXPECT_EQ(swarm.messenger(0).neighbours(), std::set<RobotId>{robot(1)});

  swarm.medium.link(0, 1, false);  // last heard: a by b at 5.0, b by a at 5.1
  swarm.runTo(8.45);
  EXPECT_EQ(swarm.events(1).size(), 1U);
  swarm.runTo(12.0);
  ASSERT_EQ(swarm.events(1).size(), 2U);
  EXPECT_EQ(swarm.events(1)[1].type, Type::lost);
  EXPECT_NEAR(swarm.events(1)[1].time, 8.5, 1e-6);
  ASSERT_EQ(swarm.events(0).size(), 2U);
  EXPECT_EQ(swarm.events(0)[1].type, Type::lost);
  EXPECT_NEAR(swarm.events(0)[1].time, 8.6, 0.1 + 1e-6);
  EXPECT_TRUE(swarm.messenger(0).neighbours().empty());
  EXPECT_TRUE(swarm.messenger(1).neighbours().empty());

  swarm.medium.link(0, 1, true);  // heartbeats go at whole seconds: heard again at 13.0
  swarm.runTo(14.0);
  ASSERT_EQ(swarm.events(1).size(), 3U);
  EXPECT_EQ(swarm.events(1)[2].type, Type::appeared);
  EXPECT_NEAR(swarm.events(1)[2].time, 13.0, 0.1 + 1e-6);
  ASSERT_EQ(swarm.events(0).size(), 3U);
  EXPECT_EQ(swarm.events(0)[2].type, Type::appeared);
  EXPECT_EQ(swarm.messenger(1).neighbours(), std::set<RobotId>{robot(0)});
}

// ---------------------------------------------------------------- hostile input

/// Captures what is logged while it lives.
class LogCapture {
 public:
  LogCapture() : previous_(spdlog::default_logger()) {
    sink_ = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(1000);
    spdlog::set_default_logger(std::make_shared<spdlog::logger>("capture", sink_));
    spdlog::default_logger()->set_level(spdlog::level::debug);  // routine drops log at debug
  }
  ~LogCapture() { spdlog::set_default_logger(previous_); }
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;

  [[nodiscard]] std::vector<std::string> lines() const { return sink_->last_formatted(); }

 private:
  std::shared_ptr<spdlog::logger> previous_;
  std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> sink_;
};

TEST(Messenger, DropsHostileInputWithTheRightReasonAndKeepsItsState) {
  Swarm swarm(3);
  swarm.medium.link(1, 2, false);
  swarm.medium.link(0, 2, false);
  swarm.runTo(0.5);
  for (int i = 0; i < 3; ++i) swarm.send(0, std::nullopt, descriptor(i));
  swarm.runTo(3.0);
  Messenger& b = swarm.messenger(1);
  const std::size_t delivered_before = delivered(b);
  ASSERT_EQ(lastAck(swarm.medium, 1, 0).value().broadcast, 3U);

  // a's next broadcast, which it has not sent yet.
  const Message fresh{Header{kSchemaVersion, robot(0), std::nullopt, 1, 4}, descriptor(3)};
  const std::vector<std::uint8_t> good = encode(fresh);
  const auto& before = b.stats().dropped_from;
  std::array<std::size_t, kDropReasons> expected =
      before.contains(robot(0)) ? before.at(robot(0)) : std::array<std::size_t, kDropReasons>{};
  const auto hostile = [&](int from, const std::vector<std::uint8_t>& bytes) {
    const Decoded d = decode(bytes);
    ASSERT_FALSE(d.message.has_value());  // the decoder itself refuses these
    ++expected[static_cast<std::size_t>(d.reason)];
    swarm.medium.inject(1, datagram(from, bytes));
  };
  std::mt19937 rng(3);
  for (int i = 0; i < 50; ++i) {  // random bytes
    std::vector<std::uint8_t> noise(rng() % 300U);
    for (std::uint8_t& byte : noise) byte = static_cast<std::uint8_t>(rng());
    hostile(0, noise);
  }
  for (std::size_t n = 0; n < good.size(); n += 7) hostile(0, {good.begin(), good.begin() + n});
  std::vector<std::uint8_t> version = good;  // field 1 (varint) is the version: 1 -> 2
  ASSERT_EQ(version[0], 0x08);
  ASSERT_EQ(version[1], kSchemaVersion);
  version[1] = 2;
  hostile(0, version);
  hostile(0, std::vector<std::uint8_t>(kMaxMessageBytes + 1, 0));
  ASSERT_EQ(decode(version).reason, DropReason::wrong_version);
  ASSERT_GT(expected[static_cast<std::size_t>(DropReason::malformed)], 0U);

  swarm.medium.inject(1, datagram(2, good));  // a's message, forged by c
  const std::vector<Medium::Sent> old = sentBy(swarm.medium, 0, MessageKind::descriptor);
  swarm.medium.inject(1, datagram(0, old.front().bytes));  // replayed
  const Message to_c{Header{kSchemaVersion, robot(0), robot(2), 1, 1}, measurement(1)};
  swarm.medium.inject(1, datagram(0, encode(to_c), MessageKind::loop_measurement));
  expected[static_cast<std::size_t>(DropReason::duplicate)] += 1;
  expected[static_cast<std::size_t>(DropReason::not_for_me)] += 1;

  const LogCapture log;
  swarm.runTo(3.1);
  EXPECT_EQ(delivered(b), delivered_before);
  EXPECT_EQ(b.stats().dropped_from.at(robot(0)), expected);
  EXPECT_EQ(
      b.stats().dropped_from.at(robot(2))[static_cast<std::size_t>(DropReason::sender_mismatch)],
      1U);
  EXPECT_EQ(b.neighbours(), std::set<RobotId>{robot(0)});  // c heard of, never a neighbour
  EXPECT_EQ(swarm.events(1).size(), 1U);                   // a's appearance, nothing since
  // Logged once per peer and reason; not_for_me is normal on a shared medium.
  std::size_t reasons = 0;
  for (std::size_t r = 0; r < kDropReasons; ++r) {
    if (expected[r] > 0 && r != static_cast<std::size_t>(DropReason::not_for_me)) ++reasons;
  }
  EXPECT_EQ(log.lines().size(), reasons + 1U);

  swarm.runTo(4.0);  // b's acks are those of before
  EXPECT_EQ(lastAck(swarm.medium, 1, 0).value().broadcast, 3U);
  EXPECT_FALSE(lastAck(swarm.medium, 1, 2).has_value());
  swarm.send(0, std::nullopt, descriptor(3));  // the real sequence 4 is still welcome
  swarm.runTo(5.0);
  expectEachOnce(deliveries(swarm.inbox(1), 0), MessageKind::descriptor, 0, 3);
  EXPECT_EQ(lastAck(swarm.medium, 1, 0).value().broadcast, 4U);
}

TEST(Messenger, DeliversOnlyTheNewestBestEffortMessage) {
  Swarm swarm(2);
  swarm.runTo(0.0);  // heartbeats exchanged
  for (std::uint32_t round = 1; round <= 3; ++round) {
    DgsState state;
    state.round = round;
    state.stage = OptimisationStage::rotation;
    state.change = 0.5F / static_cast<float>(round);
    swarm.send(0, 1, state);
  }
  swarm.medium.faults.reverse = true;  // the newest arrives first
  swarm.runTo(0.1);
  std::vector<std::uint32_t> rounds;
  for (const Message& m : swarm.inbox(1)) {
    if (const auto* s = std::get_if<DgsState>(&m.body)) rounds.push_back(s->round);
  }
  EXPECT_EQ(rounds, std::vector<std::uint32_t>{3});
  EXPECT_EQ(swarm.messenger(1).stats().dropped[static_cast<std::size_t>(DropReason::duplicate)],
            2U);
  EXPECT_EQ(swarm.messenger(0).unacknowledged(robot(1)), 0U);  // best effort: never logged
}

// ---------------------------------------------------------------- misuse

TEST(Messenger, RefusesMisuseWithoutChangingItsState) {
  Medium medium(2);
  Messenger a(medium.endpoint(0), 1);
  EXPECT_THROW(a.send(std::nullopt, Heartbeat{}, 0.0), core::Error);
  EXPECT_THROW(a.send(robot(0), descriptor(0), 0.0), core::Error);            // to itself
  EXPECT_THROW(a.send(std::nullopt, DescriptorMessage{}, 0.0), core::Error);  // empty payload
  a.send(std::nullopt, descriptor(0), 0.0);
  ASSERT_EQ(medium.tap().size(), 1U);
  EXPECT_EQ(decode(medium.tap()[0].bytes).message->header.sequence, 1U);  // none was used up
  (void)a.poll(1.0);
  EXPECT_THROW((void)a.poll(0.5), core::Error);

  EXPECT_THROW({ const Messenger unborn(medium.endpoint(1), 0); }, core::Error);
  const auto invalid = [](auto change) {
    MessengerConfig config;
    change(config);
    EXPECT_THROW(validate(config), core::Error);
  };
  invalid([](MessengerConfig& c) { c.heartbeat_period = 0.0; });
  invalid([](MessengerConfig& c) { c.neighbour_timeout = 0.5; });
  invalid([](MessengerConfig& c) { c.retransmit_after = std::nan(""); });
  invalid([](MessengerConfig& c) { c.window = 0; });
  EXPECT_NO_THROW(validate(MessengerConfig{}));
}

}  // namespace
}  // namespace dcl::comm
