// The simulated radio: links from positions (robots driving KITTI 00's real
// roads) or a rendezvous schedule, bandwidth queues, latency, seeded losses,
// link breaks before arrival, broadcasts, the traffic meters against the log,
// and the determinism of a whole scripted swarm run.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/comm/sim_radio.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/io/pose_file.hpp>

namespace dcl::comm {
namespace {

using core::RobotId;

const RobotId kA(0);
const RobotId kB(1);
const RobotId kC(2);
const RobotId kD(3);

/// KITTI 00 ground truth with its real stamps (read once). Distances do not
/// depend on the camera frame the poses are given in.
const core::Trajectory& kitti00() {
  static const core::Trajectory route =
      io::readKittiPoses(std::string(DCL_DATA_DIR) + "/trajectories/evo/KITTI_00_gt.txt",
                         std::string(DCL_DATA_DIR) + "/trajectories/evo/KITTI_00_gt_times.txt");
  return route;
}

Eigen::Vector3d kittiPosition(int frame) {
  return kitti00().pose(static_cast<std::size_t>(frame)).translation();
}

/// `n` bytes whose first four say `tag`, so a test can tell messages apart.
std::vector<std::uint8_t> payload(std::size_t n, std::uint32_t tag = 0) {
  std::vector<std::uint8_t> bytes(n, 0xA5);
  for (std::size_t i = 0; i < std::min<std::size_t>(n, 4); ++i)
    bytes[i] = static_cast<std::uint8_t>(tag >> (8 * i));
  return bytes;
}

std::uint32_t tagOf(const Datagram& d) {
  std::uint32_t tag = 0;
  for (std::size_t i = 0; i < std::min<std::size_t>(d.bytes.size(), 4); ++i)
    tag |= static_cast<std::uint32_t>(d.bytes[i]) << (8 * i);
  return tag;
}

std::size_t countFate(const std::vector<TrafficEvent>& log, Fate fate) {
  return static_cast<std::size_t>(
      std::count_if(log.begin(), log.end(), [&](const TrafficEvent& e) { return e.fate == fate; }));
}

void expectThrowsNaming(const SimRadioConfig& config, const std::string& field) {
  try {
    validate(config);
    ADD_FAILURE() << "no error for a bad '" << field << "'";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("'" + field + "'"), std::string::npos) << e.what();
  }
}

TEST(SimRadio, ValidateNamesTheBadField) {
  EXPECT_NO_THROW(validate(SimRadioConfig{}));
  SimRadioConfig c;
  c.range = -1.0;
  expectThrowsNaming(c, "range");
  c = {};
  c.bandwidth = std::numeric_limits<double>::infinity();
  expectThrowsNaming(c, "bandwidth");
  c = {};
  c.latency = -0.1;
  expectThrowsNaming(c, "latency");
  c = {};
  c.drop_rate = 1.0;
  expectThrowsNaming(c, "drop_rate");
  c = {};
  c.meter_interval = 0.0;
  expectThrowsNaming(c, "meter_interval");
  EXPECT_THROW(SimRadio{c}, core::Error);
}

TEST(SimRadio, TimeOnlyMovesForward) {
  SimRadio radio;
  radio.advanceTo(5.0);
  EXPECT_EQ(radio.now(), 5.0);
  EXPECT_THROW(radio.advanceTo(4.0), core::Error);
  EXPECT_THROW(radio.advanceTo(std::numeric_limits<double>::quiet_NaN()), core::Error);
  EXPECT_EQ(radio.now(), 5.0);
  EXPECT_NO_THROW(radio.advanceTo(5.0));
  EXPECT_EQ(&radio.endpoint(kA), &radio.endpoint(kA));
  EXPECT_EQ(radio.endpoint(kB).self(), kB);
}

// Robot a drives KITTI 00 from frame 0, robot b the same road backwards from
// frame 400: they approach, pass each other near frame 200 and part. Each
// frame a broadcasts and b unicasts to a a small tagged message.
TEST(SimRadio, RangeLinksFollowRobotsDrivingTowardsEachOther) {
  SimRadio radio;  // 50 m range, no latency, unlimited bandwidth, no loss
  constexpr int kFrames = 400;
  std::vector<bool> in_range;
  std::set<std::uint32_t> b_heard, a_heard;
  for (int k = 0; k <= kFrames; ++k) {
    const Eigen::Vector3d pa = kittiPosition(k);
    const Eigen::Vector3d pb = kittiPosition(kFrames - k);
    radio.setPosition(kA, pa);
    radio.setPosition(kB, pb);
    radio.advanceTo(kitti00().stamp(static_cast<std::size_t>(k)));
    in_range.push_back((pa - pb).norm() < 50.0);
    ASSERT_EQ(radio.linked(kA, kB), in_range.back()) << "frame " << k;
    ASSERT_EQ(radio.linked(kB, kA), in_range.back()) << "frame " << k;
    for (const Datagram& d : radio.endpoint(kB).receive()) {
      EXPECT_EQ(d.from, kA);
      b_heard.insert(tagOf(d));
    }
    for (const Datagram& d : radio.endpoint(kA).receive()) {
      EXPECT_EQ(d.from, kB);
      a_heard.insert(tagOf(d));
    }
    const auto tag = static_cast<std::uint32_t>(k);
    radio.endpoint(kA).send(std::nullopt, MessageKind::heartbeat, payload(24, tag));
    radio.endpoint(kB).send(kA, MessageKind::descriptor, payload(1200, tag));
  }
  radio.advanceTo(radio.now() + 1.0);

  // Out of range at both ends, in range once in the middle.
  const auto first = std::find(in_range.begin(), in_range.end(), true);
  const auto last = std::find(in_range.rbegin(), in_range.rend(), true).base();
  ASSERT_FALSE(in_range.front());
  ASSERT_FALSE(in_range.back());
  ASSERT_NE(first, in_range.end());
  EXPECT_TRUE(std::all_of(first, last, [](bool b) { return b; }));
  const auto first_frame = static_cast<std::uint32_t>(first - in_range.begin());
  const auto last_frame = static_cast<std::uint32_t>(last - in_range.begin()) - 1;

  // A message sent at frame k arrives at once and is handed over at frame
  // k + 1, if they are still in range then: the one sent at the last frame in
  // range finds them parted.
  std::set<std::uint32_t> expected;
  for (std::uint32_t k = first_frame; k < last_frame; ++k) expected.insert(k);
  EXPECT_EQ(b_heard, expected);
  EXPECT_EQ(a_heard, expected);

  const auto& log = radio.log();
  EXPECT_EQ(log.size(), 2U * (kFrames + 1));
  EXPECT_EQ(countFate(log, Fate::link_down), 2U);
  EXPECT_EQ(countFate(log, Fate::delivered), 2 * expected.size());
  EXPECT_EQ(countFate(log, Fate::unreachable), 2U * (kFrames + 1) - 2 * (expected.size() + 1));
  for (const TrafficEvent& e : log) {
    if (e.fate != Fate::unreachable) continue;
    EXPECT_EQ(e.to.has_value(), !e.broadcast);  // a broadcast nobody heard has no receiver
    EXPECT_EQ(e.arrival, e.sent);
  }

  // Only what went on the air is counted as sent.
  const std::size_t transmitted = expected.size() + 1;
  EXPECT_EQ(radio.traffic(kB).sent, transmitted * 1200);
  EXPECT_EQ(radio.traffic(kB).messages_sent, transmitted);
  EXPECT_EQ(radio.traffic(kA).sent, transmitted * 24);
  EXPECT_EQ(radio.traffic(kA).received, expected.size() * 1200);
  EXPECT_EQ(radio.traffic(kA).received_from.at(kB), expected.size() * 1200);
}

// The same drive with a 1 kB/s link: when they come in range, b sends a
// trajectory summary that fits in the rendezvous and a map summary that
// cannot be carried before they part.
TEST(SimRadio, MessageIsDroppedWhenTheRobotsPartBeforeItArrives) {
  SimRadioConfig config;
  config.bandwidth = 1000.0;
  SimRadio radio(config);
  constexpr int kFrames = 400;
  std::optional<double> met, parted;
  std::vector<Datagram> heard;
  for (int k = 0; k <= kFrames; ++k) {
    radio.setPosition(kA, kittiPosition(k));
    radio.setPosition(kB, kittiPosition(kFrames - k));
    radio.advanceTo(kitti00().stamp(static_cast<std::size_t>(k)));
    for (Datagram& d : radio.endpoint(kA).receive()) heard.push_back(std::move(d));
    if (!met && radio.linked(kA, kB)) {
      met = radio.now();
      radio.endpoint(kB).send(kA, MessageKind::trajectory_summary, payload(3000, 1));
      radio.endpoint(kB).send(kA, MessageKind::map_summary, payload(20000, 2));
    }
    if (met && !parted && !radio.linked(kA, kB)) parted = radio.now();
  }
  radio.advanceTo(radio.now() + 30.0);
  for (Datagram& d : radio.endpoint(kA).receive()) heard.push_back(std::move(d));
  ASSERT_TRUE(met && parted);
  ASSERT_GT(*parted - *met, 3.0);   // the small one fits
  ASSERT_LT(*parted - *met, 23.0);  // the large one, queued behind it, does not

  const auto& log = radio.log();
  ASSERT_EQ(log.size(), 2U);
  EXPECT_DOUBLE_EQ(log[0].arrival, *met + 3.0);
  EXPECT_DOUBLE_EQ(log[1].arrival, *met + 23.0);
  EXPECT_EQ(log[0].fate, Fate::delivered);
  EXPECT_EQ(log[1].fate, Fate::link_down);
  ASSERT_EQ(heard.size(), 1U);
  EXPECT_EQ(heard[0].kind, MessageKind::trajectory_summary);
  EXPECT_EQ(heard[0].bytes, payload(3000, 1));
  // Both went on the air; only one was delivered.
  EXPECT_EQ(radio.traffic(kB).sent, 23000U);
  EXPECT_EQ(radio.traffic(kA).received, 3000U);
  EXPECT_EQ(radio.traffic(kB).delivered_to.at(kA), 3000U);
}

TEST(SimRadio, ScheduleOverridesPositions) {
  SimRadioConfig config;
  config.latency = 0.5;
  SimRadio radio(config);
  // All three parked side by side: linked by range.
  radio.setPosition(kA, {0.0, 0.0, 0.0});
  radio.setPosition(kB, {2.0, 0.0, 0.0});
  radio.setPosition(kC, {4.0, 0.0, 0.0});
  EXPECT_TRUE(radio.linked(kA, kB));
  EXPECT_TRUE(radio.linked(kA, kC));

  EXPECT_THROW(radio.setSchedule({{kA, kA, 0.0, 1.0}}), core::Error);
  EXPECT_THROW(radio.setSchedule({{kA, kB, 0.0, 1.0}, {kA, kC, 5.0, 4.0}}), core::Error);
  EXPECT_TRUE(radio.linked(kA, kC));  // a rejected schedule changes nothing

  radio.setSchedule({{kA, kB, 10.0, 20.0}, {kB, kC, 30.0, 31.0}});
  EXPECT_FALSE(radio.linked(kA, kB));
  EXPECT_FALSE(radio.linked(kA, kC));
  radio.endpoint(kA).send(kB, MessageKind::descriptor, payload(100, 1));  // unreachable

  radio.advanceTo(10.0);
  EXPECT_TRUE(radio.linked(kA, kB));
  EXPECT_TRUE(radio.linked(kB, kA));
  EXPECT_FALSE(radio.linked(kA, kC));
  EXPECT_FALSE(radio.linked(kB, kC));
  radio.endpoint(kA).send(std::nullopt, MessageKind::heartbeat, payload(30, 2));  // b only

  // The schedule is asked at each arrival, not when the radio next looks
  // (25 s): arriving at 19.75 is within the rendezvous, at 20.0 after it.
  radio.advanceTo(19.25);
  radio.endpoint(kA).send(kB, MessageKind::descriptor, payload(100, 3));
  radio.advanceTo(19.5);
  radio.endpoint(kA).send(kB, MessageKind::descriptor, payload(100, 4));
  radio.advanceTo(25.0);
  EXPECT_FALSE(radio.linked(kA, kB));
  radio.advanceTo(30.5);
  EXPECT_TRUE(radio.linked(kC, kB));

  const auto& log = radio.log();
  ASSERT_EQ(log.size(), 4U);
  EXPECT_EQ(log[0].fate, Fate::unreachable);
  EXPECT_EQ(log[1].to, kB);
  EXPECT_TRUE(log[1].broadcast);
  EXPECT_EQ(log[1].fate, Fate::delivered);
  EXPECT_EQ(log[2].fate, Fate::delivered);
  EXPECT_EQ(log[3].fate, Fate::link_down);
  std::vector<std::uint32_t> tags;
  for (const Datagram& d : radio.endpoint(kB).receive()) tags.push_back(tagOf(d));
  EXPECT_EQ(tags, (std::vector<std::uint32_t>{2, 3}));
  EXPECT_TRUE(radio.endpoint(kC).receive().empty());
}

TEST(SimRadio, BandwidthQueuesMessagesPerDirectedLink) {
  SimRadioConfig config;
  config.range = 0.0;  // always linked
  config.bandwidth = 1000.0;
  SimRadio radio(config);
  Transport& a = radio.endpoint(kA);
  Transport& b = radio.endpoint(kB);
  radio.endpoint(kC);
  a.send(kB, MessageKind::map_summary, payload(10000, 1));
  a.send(kB, MessageKind::map_summary, payload(10000, 2));  // behind the first
  a.send(kC, MessageKind::descriptor, payload(2000, 3));    // another link: not behind
  b.send(kA, MessageKind::descriptor, payload(1000, 4));    // the other direction

  const auto tagsAt = [&](double t, Transport& endpoint) {
    radio.advanceTo(t);
    std::vector<std::uint32_t> tags;
    for (const Datagram& d : endpoint.receive()) tags.push_back(tagOf(d));
    return tags;
  };
  EXPECT_TRUE(tagsAt(0.999, a).empty());
  EXPECT_EQ(tagsAt(1.0, a), std::vector<std::uint32_t>{4});
  EXPECT_EQ(tagsAt(2.0, radio.endpoint(kC)), std::vector<std::uint32_t>{3});
  EXPECT_TRUE(tagsAt(9.999, b).empty());
  EXPECT_EQ(tagsAt(10.0, b), std::vector<std::uint32_t>{1});
  EXPECT_TRUE(tagsAt(19.999, b).empty());
  EXPECT_EQ(tagsAt(20.0, b), std::vector<std::uint32_t>{2});

  // An idle link does not bank its idle time: sent at 25, arrives at 35.
  radio.advanceTo(25.0);
  a.send(kB, MessageKind::map_summary, payload(10000, 5));
  EXPECT_TRUE(tagsAt(34.999, b).empty());
  EXPECT_EQ(tagsAt(35.0, b), std::vector<std::uint32_t>{5});
  EXPECT_DOUBLE_EQ(radio.log().back().arrival, 35.0);
}

TEST(SimRadio, LatencyDelaysEveryDeliveryAndTiesKeepTheSendOrder) {
  SimRadioConfig config;
  config.range = 0.0;
  config.bandwidth = 1024.0;
  config.latency = 0.25;
  SimRadio radio(config);
  Transport& a = radio.endpoint(kA);
  Transport& b = radio.endpoint(kB);
  Transport& c = radio.endpoint(kC);
  radio.advanceTo(1.0);
  a.send(kC, MessageKind::loop_candidate, payload(512, 1));  // 0.5 s on the air, arrives 1.75
  radio.advanceTo(1.25);
  b.send(kC, MessageKind::loop_measurement, payload(256, 2));  // 0.25 s, arrives 1.75 too
  radio.advanceTo(1.7499);
  EXPECT_TRUE(c.receive().empty());
  radio.advanceTo(1.75);
  const auto got = c.receive();
  ASSERT_EQ(got.size(), 2U);
  EXPECT_EQ(tagOf(got[0]), 1U);  // a tie: the one sent first comes first
  EXPECT_EQ(tagOf(got[1]), 2U);
  EXPECT_EQ(got[0].from, kA);
  EXPECT_EQ(got[1].kind, MessageKind::loop_measurement);
  EXPECT_EQ(radio.log()[0].arrival, 1.75);
  EXPECT_EQ(radio.log()[1].arrival, 1.75);
}

// One robot sends to three others many times; returns the fates, per receiver.
std::map<RobotId, std::vector<Fate>> lossRun(std::uint64_t seed, int receivers, int messages) {
  SimRadioConfig config;
  config.range = 0.0;
  config.drop_rate = 0.2;
  config.seed = seed;
  SimRadio radio(config);
  for (int r = 0; r <= receivers; ++r) radio.endpoint(RobotId(static_cast<std::uint8_t>(r)));
  for (int i = 0; i < messages; ++i) {
    radio.endpoint(kA).send(std::nullopt, MessageKind::descriptor, payload(64));
    radio.advanceTo(0.1 * (i + 1));
  }
  std::map<RobotId, std::vector<Fate>> fates;
  for (const TrafficEvent& e : radio.log()) fates[*e.to].push_back(e.fate);
  std::size_t received = 0;
  for (int r = 1; r <= receivers; ++r)
    received += radio.endpoint(RobotId(static_cast<std::uint8_t>(r))).receive().size();
  EXPECT_EQ(received, countFate(radio.log(), Fate::delivered));
  EXPECT_EQ(radio.traffic(kA).sent, 64U * messages);  // lost messages went on the air
  return fates;
}

TEST(SimRadio, LossesFollowTheRateAndTheSeed) {
  constexpr int kMessages = 4000;
  const auto run = lossRun(1, 3, kMessages);
  ASSERT_EQ(run.size(), 3U);
  for (const auto& [robot, fates] : run) {
    ASSERT_EQ(fates.size(), static_cast<std::size_t>(kMessages));
    const double lost = static_cast<double>(std::count(fates.begin(), fates.end(), Fate::lost));
    // 4000 draws at 0.2: the standard deviation of the share is 0.0063.
    EXPECT_NEAR(lost / kMessages, 0.2, 0.025) << "robot " << int(robot.value());
  }
  // Receivers lose different messages.
  EXPECT_NE(run.at(kB), run.at(kC));

  EXPECT_EQ(lossRun(1, 3, kMessages), run);  // the same seed, the same losses
  EXPECT_NE(lossRun(2, 3, kMessages), run);  // another seed, others
  // Each receiver has its own stream: b loses the same messages whether or
  // not c and d listen too.
  EXPECT_EQ(lossRun(1, 1, kMessages).at(kB), run.at(kB));
}

TEST(SimRadio, BroadcastReachesOnlyRobotsInRangeAndIsCountedOnce) {
  SimRadio radio;  // 50 m
  radio.setPosition(kA, {0.0, 0.0, 0.0});
  radio.setPosition(kB, {30.0, 0.0, 0.0});
  radio.setPosition(kC, {0.0, -49.0, 1.0});
  radio.setPosition(kD, {120.0, 0.0, 0.0});
  radio.endpoint(kA).send(std::nullopt, MessageKind::descriptor, payload(700, 1));
  radio.endpoint(kD).send(std::nullopt, MessageKind::heartbeat, payload(30, 2));  // nobody near
  radio.advanceTo(0.1);

  const auto& log = radio.log();
  ASSERT_EQ(log.size(), 3U);
  EXPECT_EQ(log[0].to, kB);
  EXPECT_EQ(log[1].to, kC);
  EXPECT_TRUE(log[0].broadcast && log[1].broadcast && log[2].broadcast);
  EXPECT_EQ(log[2].from, kD);
  EXPECT_FALSE(log[2].to.has_value());
  EXPECT_EQ(log[2].fate, Fate::unreachable);

  EXPECT_EQ(radio.endpoint(kB).receive().size(), 1U);
  EXPECT_EQ(radio.endpoint(kC).receive().size(), 1U);
  EXPECT_TRUE(radio.endpoint(kD).receive().empty());
  EXPECT_TRUE(radio.endpoint(kA).receive().empty());  // not to itself
  const RobotTraffic a = radio.traffic(kA);
  EXPECT_EQ(a.sent, 700U);
  EXPECT_EQ(a.messages_sent, 1U);
  EXPECT_EQ(a.sent_by_kind[static_cast<std::size_t>(MessageKind::descriptor)], 700U);
  EXPECT_EQ(a.delivered_to, (std::map<RobotId, std::size_t>{{kB, 700}, {kC, 700}}));
  EXPECT_EQ(radio.traffic(kD).sent, 0U);
  EXPECT_EQ(radio.traffic(kC).received_by_kind[static_cast<std::size_t>(MessageKind::descriptor)],
            700U);
}

/// Everything a scripted swarm run leaves behind.
struct SwarmRun {
  /// One send and the log entries it made, [first, last).
  struct Send {
    RobotId from;
    MessageKind kind = MessageKind::heartbeat;
    std::size_t bytes = 0;
    double time = 0.0;
    std::size_t first = 0;
    std::size_t last = 0;
  };
  std::vector<TrafficEvent> log;
  std::vector<RobotTraffic> traffic;
  std::vector<std::vector<Datagram>> received;
  std::vector<Send> sends;
};

constexpr int kSwarm = 4;

// Four robots on KITTI 00 for 40 s at 10 Hz: a drives from frame 0, b towards
// it from frame 400, c ahead of a from frame 100, d backwards from frame 700;
// every pair but b-d meets. Each robot broadcasts a heartbeat a second and
// sends now and then a descriptor, candidate or summary of random size to a
// random teammate.
SwarmRun swarmRun(const SimRadioConfig& config, std::uint64_t script_seed = 7) {
  const int start[kSwarm] = {0, 400, 100, 700};
  const int step[kSwarm] = {1, -1, 1, -1};
  constexpr MessageKind kinds[] = {MessageKind::descriptor, MessageKind::loop_candidate,
                                   MessageKind::loop_measurement, MessageKind::map_summary};
  SimRadio radio(config);
  std::mt19937_64 script(script_seed);
  SwarmRun run;
  run.received.resize(kSwarm);
  const auto robot = [](int r) { return RobotId(static_cast<std::uint8_t>(r)); };
  const auto send = [&](int r, std::optional<RobotId> to, MessageKind kind, std::size_t n) {
    const std::size_t first = radio.log().size();
    radio.endpoint(robot(r)).send(to, kind, payload(n, static_cast<std::uint32_t>(first)));
    run.sends.push_back({robot(r), kind, n, radio.now(), first, radio.log().size()});
  };
  const auto collect = [&] {
    for (int r = 0; r < kSwarm; ++r) {
      for (Datagram& d : radio.endpoint(robot(r)).receive()) run.received[r].push_back(d);
    }
  };
  for (int k = 0; k < 400; ++k) {
    for (int r = 0; r < kSwarm; ++r)
      radio.setPosition(robot(r), kittiPosition(start[r] + step[r] * k));
    radio.advanceTo(0.1 * k);
    collect();
    for (int r = 0; r < kSwarm; ++r) {
      if (k % 10 == r) send(r, std::nullopt, MessageKind::heartbeat, 20 + script() % 20);
      if (script() % 5 != 0) continue;
      const int to = (r + 1 + static_cast<int>(script() % (kSwarm - 1))) % kSwarm;
      send(r, robot(to), kinds[script() % 4], 100 + script() % 8000);
    }
  }
  radio.advanceTo(radio.now() + 60.0);  // everything in flight lands or breaks
  collect();
  run.log = radio.log();
  for (int r = 0; r < kSwarm; ++r) run.traffic.push_back(radio.traffic(robot(r)));
  return run;
}

SimRadioConfig swarmConfig() {
  SimRadioConfig config;
  config.bandwidth = 20000.0;
  config.latency = 0.05;
  config.drop_rate = 0.1;
  config.seed = 42;
  config.meter_interval = 5.0;
  return config;
}

void expectSameTraffic(const RobotTraffic& x, const RobotTraffic& y) {
  EXPECT_EQ(x.sent, y.sent);
  EXPECT_EQ(x.received, y.received);
  EXPECT_EQ(x.messages_sent, y.messages_sent);
  EXPECT_EQ(x.messages_received, y.messages_received);
  EXPECT_EQ(x.received_from, y.received_from);
  EXPECT_EQ(x.delivered_to, y.delivered_to);
  EXPECT_EQ(x.sent_by_kind, y.sent_by_kind);
  EXPECT_EQ(x.received_by_kind, y.received_by_kind);
  EXPECT_EQ(x.sent_over_time, y.sent_over_time);
}

TEST(SimRadio, SameScriptedSwarmRunGivesIdenticalLogsAndTraffic) {
  const SwarmRun first = swarmRun(swarmConfig());
  // The run exercises every fate, so the comparison means something.
  for (Fate fate : {Fate::delivered, Fate::lost, Fate::link_down, Fate::unreachable})
    EXPECT_GT(countFate(first.log, fate), 0U) << static_cast<int>(fate);

  const SwarmRun second = swarmRun(swarmConfig());
  EXPECT_EQ(second.log, first.log);
  for (int r = 0; r < kSwarm; ++r) {
    expectSameTraffic(second.traffic[r], first.traffic[r]);
    ASSERT_EQ(second.received[r].size(), first.received[r].size());
    for (std::size_t i = 0; i < first.received[r].size(); ++i) {
      EXPECT_EQ(second.received[r][i].from, first.received[r][i].from);
      EXPECT_EQ(second.received[r][i].bytes, first.received[r][i].bytes);
    }
  }
  // Another loss seed, the same script: other losses.
  SimRadioConfig reseeded = swarmConfig();
  reseeded.seed = 43;
  EXPECT_NE(swarmRun(reseeded).log, first.log);
}

TEST(SimRadio, MetersAddUpToTheLog) {
  const SimRadioConfig config = swarmConfig();
  const SwarmRun run = swarmRun(config);
  std::vector<RobotTraffic> expected(kSwarm);
  for (RobotTraffic& t : expected) t.sent_over_time.assign(run.traffic[0].sent_over_time.size(), 0);
  for (const SwarmRun::Send& s : run.sends) {
    const bool on_air =
        std::any_of(run.log.begin() + static_cast<std::ptrdiff_t>(s.first),
                    run.log.begin() + static_cast<std::ptrdiff_t>(s.last),
                    [](const TrafficEvent& e) { return e.fate != Fate::unreachable; });
    if (!on_air) continue;
    RobotTraffic& t = expected[s.from.value()];
    t.sent += s.bytes;
    ++t.messages_sent;
    t.sent_by_kind[static_cast<std::size_t>(s.kind)] += s.bytes;
    t.sent_over_time[static_cast<std::size_t>(s.time / config.meter_interval)] += s.bytes;
  }
  for (const TrafficEvent& e : run.log) {
    if (e.fate != Fate::delivered) continue;
    RobotTraffic& receiver = expected[e.to->value()];
    receiver.received += e.bytes;
    ++receiver.messages_received;
    receiver.received_from[e.from] += e.bytes;
    receiver.received_by_kind[static_cast<std::size_t>(e.kind)] += e.bytes;
    expected[e.from.value()].delivered_to[*e.to] += e.bytes;
  }
  for (int r = 0; r < kSwarm; ++r) {
    SCOPED_TRACE("robot " + std::to_string(r));
    expectSameTraffic(run.traffic[r], expected[r]);
    EXPECT_EQ(run.traffic[r].received_by_kind.size(), kMessageKinds);
    // What the meters say was delivered is what the robots got.
    std::size_t got = 0;
    for (const Datagram& d : run.received[r]) got += d.bytes.size();
    EXPECT_EQ(got, run.traffic[r].received);
    const auto& series = run.traffic[r].sent_over_time;
    EXPECT_EQ(std::accumulate(series.begin(), series.end(), std::size_t{0}), run.traffic[r].sent);
  }
}

}  // namespace
}  // namespace dcl::comm
