// DdsTransport over Cyclone DDS on loopback: discovery, routing, payloads,
// QoS paths and separation of swarms and domains. Every test has its own DDS
// domain (ctest runs tests in parallel) and a swarm name unique to the
// process (so that two test runs on one machine do not hear each other).
// The test domains lie in 0..101: a domain's fixed ports (7400 + 250 x
// domain and up) stay below Linux's ephemeral ports (32768 and up), which
// any other socket on the machine may hold (domain 153's 45651 was seen taken).
//
// Transports of one process meet inside Cyclone without the network, so one
// test starts this executable again as an echo peer to go through the
// loopback interface, discovery included.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <dcl/comm/dds_transport.hpp>
#include <dcl/core/error.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/registration/cloud_codec.hpp>

#include "../common/keys.hpp"
#include "../common/kitti_test_data.hpp"

namespace dcl::comm {
namespace {

using Clock = std::chrono::steady_clock;
using Bytes = std::vector<std::uint8_t>;

/// How long discovery may take before a test gives up.
constexpr std::chrono::seconds kDiscoveryDeadline{5};
/// How often discovery probes go out.
constexpr std::chrono::milliseconds kProbePeriod{5};
/// How long a test waits for a message that must arrive.
constexpr std::chrono::seconds kDeliveryDeadline{5};

/// A probe's payload: discovery traffic, never a test's message.
const Bytes kProbe = {'p', 'r', 'o', 'b', 'e'};

using dcl::test::robot;

DdsConfig loopback(std::uint32_t domain) {
  DdsConfig config;
  config.domain = domain;
  config.swarm = "dcl-test-" + std::to_string(::getpid());
  config.interface = "lo";
  return config;
}

/// Deterministic incompressible bytes: a misplaced fragment changes them.
Bytes pattern(std::size_t size, unsigned seed) {
  std::mt19937 rng(seed);
  Bytes bytes(size);
  for (std::uint8_t& b : bytes) b = static_cast<std::uint8_t>(rng());
  return bytes;
}

/// What one transport has heard, probes set aside.
struct Inbox {
  std::vector<Datagram> messages;
  std::set<std::pair<int, Qos>> probed;  ///< (sender, QoS) of the probes heard

  void take(DdsTransport& t) {
    for (Datagram& d : t.receive()) {
      if (d.bytes == kProbe) {
        probed.insert({d.from.value(), qosOf(d.kind)});
      } else {
        messages.push_back(std::move(d));
      }
    }
  }
  [[nodiscard]] bool has(int from, const Bytes& bytes) const {
    return std::any_of(messages.begin(), messages.end(), [&](const Datagram& d) {
      return d.from == robot(from) && d.bytes == bytes;
    });
  }
};

/// The echo peer's robot id and its environment variable ("domain swarm").
constexpr int kEchoPeer = 9;
constexpr const char* kEchoPeerVariable = "DCL_DDS_ECHO_PEER";
/// A datagram that ends the echo peer.
const Bytes kBye = {'b', 'y', 'e'};

/// Sends `bytes` until DDS takes it: a reliable writer refuses new samples
/// while too many bytes are unacknowledged (Messenger sends again later).
void sendSurely(DdsTransport& t, std::optional<core::RobotId> to, MessageKind kind,
                const Bytes& bytes) {
  const auto start = Clock::now();
  for (;;) {
    const std::size_t failed = t.failedWrites();
    t.send(to, kind, bytes);
    if (t.failedWrites() == failed || Clock::now() - start > kDeliveryDeadline) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

/// Echoes every datagram back to its sender, unicast, same kind, for at most
/// 10 s or until "bye". Returns the exit status.
int runEchoPeer(const std::string& spec) {
  std::istringstream in(spec);
  DdsConfig config;
  in >> config.domain >> config.swarm;
  config.interface = "lo";
  DdsTransport t(robot(kEchoPeer), config);
  const auto start = Clock::now();
  while (Clock::now() - start < std::chrono::seconds(10)) {
    if (!t.wait(std::chrono::milliseconds(50))) continue;
    for (const Datagram& d : t.receive()) {
      if (d.bytes == kBye) return 0;
      sendSurely(t, d.from, d.kind, d.bytes);
    }
  }
  return 3;
}

/// Runs the echo peer instead of the tests when the environment asks for it.
const bool kIsEchoPeer = [] {
  const char* spec = std::getenv(kEchoPeerVariable);
  if (spec == nullptr) return false;
  int status = 2;
  try {
    status = runEchoPeer(spec);
  } catch (const core::Error& e) {
    std::fprintf(stderr, "echo peer: %s\n", e.what());
  }
  std::_Exit(status);
}();

/// This executable started again as the echo peer; killed if still running
/// when the test ends.
class EchoPeerProcess {
 public:
  explicit EchoPeerProcess(const DdsConfig& config) {
    const std::string variable =
        std::string(kEchoPeerVariable) + "=" + std::to_string(config.domain) + " " + config.swarm;
    std::vector<char*> env;
    for (char** e = environ; *e != nullptr; ++e) env.push_back(*e);
    env.push_back(const_cast<char*>(variable.c_str()));
    env.push_back(nullptr);
    char exe[] = "/proc/self/exe";
    char no_tests[] = "--gtest_filter=-*";
    char* argv[] = {exe, no_tests, nullptr};
    if (posix_spawn(&pid_, exe, nullptr, nullptr, argv, env.data()) != 0) pid_ = 0;
  }
  ~EchoPeerProcess() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
  EchoPeerProcess(const EchoPeerProcess&) = delete;
  EchoPeerProcess& operator=(const EchoPeerProcess&) = delete;

  [[nodiscard]] bool started() const { return pid_ > 0; }

  /// The exit status once it has exited by itself within the deadline.
  std::optional<int> exitStatus() {
    const auto start = Clock::now();
    while (Clock::now() - start < kDeliveryDeadline) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = 0;
        return WIFEXITED(status) ? std::optional<int>(WEXITSTATUS(status)) : std::nullopt;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return std::nullopt;
  }

 private:
  pid_t pid_ = 0;
};

/// Probes on both QoS paths until every transport has heard every other on
/// both, as robots find each other by their heartbeats. Returns the seconds
/// it took, or nothing by the deadline.
std::optional<double> discover(const std::vector<DdsTransport*>& transports,
                               std::vector<Inbox>& inboxes) {
  const auto start = Clock::now();
  const auto complete = [&] {
    for (std::size_t i = 0; i < transports.size(); ++i) {
      for (std::size_t j = 0; j < transports.size(); ++j) {
        if (i == j) continue;
        const int from = transports[j]->self().value();
        if (inboxes[i].probed.count({from, Qos::reliable}) == 0 ||
            inboxes[i].probed.count({from, Qos::best_effort}) == 0)
          return false;
      }
    }
    return true;
  };
  while (Clock::now() - start < kDiscoveryDeadline) {
    for (DdsTransport* t : transports) {
      t->send(std::nullopt, MessageKind::heartbeat, kProbe);
      t->send(std::nullopt, MessageKind::dgs_state, kProbe);
    }
    for (std::size_t i = 0; i < transports.size(); ++i) {
      transports[i]->wait(kProbePeriod);
      inboxes[i].take(*transports[i]);
    }
    if (complete()) return std::chrono::duration<double>(Clock::now() - start).count();
  }
  return std::nullopt;
}

/// Receives into `inbox` until `done` holds or the deadline passes.
bool receiveUntil(DdsTransport& t, Inbox& inbox, const std::function<bool()>& done) {
  const auto start = Clock::now();
  while (!done()) {
    if (Clock::now() - start > kDeliveryDeadline) return false;
    if (t.wait(std::chrono::milliseconds(50))) inbox.take(t);
  }
  return true;
}

TEST(DdsTransport, DiscoversPeersAndRoutesBroadcastsAndUnicasts) {
  const DdsConfig config = loopback(71);
  DdsTransport a(robot(0), config);
  DdsTransport b(robot(1), config);
  DdsTransport c(robot(2), config);
  std::vector<Inbox> inbox(3);
  const std::optional<double> seconds = discover({&a, &b, &c}, inbox);
  ASSERT_TRUE(seconds) << "three transports did not discover each other in 5 s";
  std::printf("discovery of 3 transports in one process (both QoS paths, both ways): %.3f s\n",
              *seconds);

  // A broadcast reaches both others, from a; nobody hears itself.
  const Bytes hello = pattern(300, 1);
  a.send(std::nullopt, MessageKind::loop_candidate, hello);
  ASSERT_TRUE(receiveUntil(b, inbox[1], [&] { return inbox[1].has(0, hello); }));
  ASSERT_TRUE(receiveUntil(c, inbox[2], [&] { return inbox[2].has(0, hello); }));
  inbox[0].take(a);
  EXPECT_TRUE(inbox[0].messages.empty());
  EXPECT_EQ(inbox[1].messages.front().kind, MessageKind::loop_candidate);

  // A unicast to b, then a broadcast on the same reliable path: once c has the
  // broadcast, the unicast (sent before it, in order) would have reached it too.
  const Bytes measurement = pattern(90, 2);
  const Bytes marker = pattern(40, 3);
  a.send(robot(1), MessageKind::loop_measurement, measurement);
  a.send(std::nullopt, MessageKind::loop_measurement, marker);
  ASSERT_TRUE(receiveUntil(b, inbox[1], [&] { return inbox[1].has(0, marker); }));
  ASSERT_TRUE(receiveUntil(c, inbox[2], [&] { return inbox[2].has(0, marker); }));
  EXPECT_TRUE(inbox[1].has(0, measurement));
  EXPECT_FALSE(inbox[2].has(0, measurement));
  EXPECT_EQ(inbox[2].messages.size(), 2U);  // hello and the marker

  // And back: b answers a alone.
  const Bytes answer = pattern(120, 4);
  b.send(robot(0), MessageKind::pose_estimates, answer);
  ASSERT_TRUE(receiveUntil(a, inbox[0], [&] { return inbox[0].has(1, answer); }));
  EXPECT_EQ(inbox[0].messages.back().kind, MessageKind::pose_estimates);
  EXPECT_EQ(a.failedWrites() + b.failedWrites() + c.failedWrites(), 0U);
}

TEST(DdsTransport, CarriesRealPayloadsIntactOnBothQosPaths) {
  const DdsConfig config = loopback(72);
  DdsTransport a(robot(3), config);
  DdsTransport b(robot(7), config);
  std::vector<Inbox> inbox(2);
  ASSERT_TRUE(discover({&a, &b}, inbox));

  // Best effort: a real LiDAR-Iris descriptor of a KITTI 00 scan. Sent again
  // until it arrives: best effort may lose it, but never corrupts it.
  const core::PointCloud scan = test::kittiScan(0);
  const Bytes descriptor = place::encodeIris(place::describeIris(scan));
  ASSERT_EQ(qosOf(MessageKind::descriptor), Qos::best_effort);
  ASSERT_TRUE(receiveUntil(b, inbox[1], [&] {
    if (!inbox[1].has(3, descriptor)) a.send(std::nullopt, MessageKind::descriptor, descriptor);
    return inbox[1].has(3, descriptor);
  }));
  EXPECT_EQ(inbox[1].messages.front().kind, MessageKind::descriptor);

  // Reliable: a map summary's cloud, KITTI 00 scans 0-5 merged in the world
  // frame and voxel-filtered (over 200 kB), sent once.
  core::PointCloud map;
  for (int frame = 0; frame <= 5; ++frame)
    map.append(core::transformed(test::kittiScan(frame),
                                 test::kittiLidarPoses()[static_cast<std::size_t>(frame)]));
  registration::CloudCodecConfig summary;
  summary.voxel_size = 0.1;
  summary.zstd_level = 3;
  const Bytes cloud = registration::encodeVerificationCloud(map, summary);
  ASSERT_GT(cloud.size(), 200'000U);
  ASSERT_EQ(qosOf(MessageKind::map_summary), Qos::reliable);
  a.send(robot(7), MessageKind::map_summary, cloud);
  ASSERT_TRUE(receiveUntil(b, inbox[1], [&] { return inbox[1].has(3, cloud); }));
  const Datagram& got = *std::find_if(inbox[1].messages.begin(), inbox[1].messages.end(),
                                      [&](const Datagram& d) { return d.bytes == cloud; });
  EXPECT_EQ(got.kind, MessageKind::map_summary);
  EXPECT_EQ(registration::decodeVerificationCloud(got.bytes).size(),
            registration::decodeVerificationCloud(cloud).size());
  std::printf("payloads on loopback: descriptor %zu B (best effort), cloud %zu B (reliable)\n",
              descriptor.size(), cloud.size());

  // The largest message goes through; one byte more is not written, counted.
  const Bytes oversized = pattern(kMaxMessageBytes + 1, 5);
  const Bytes largest = pattern(kMaxMessageBytes, 6);
  b.send(robot(3), MessageKind::map_summary, oversized);
  EXPECT_EQ(b.failedWrites(), 1U);
  b.send(robot(3), MessageKind::map_summary, largest);
  ASSERT_TRUE(receiveUntil(a, inbox[0], [&] { return inbox[0].has(7, largest); }));
  EXPECT_EQ(inbox[0].messages.size(), 1U);  // the oversized one never came
  EXPECT_EQ(b.failedWrites(), 1U);
  EXPECT_EQ(a.failedWrites(), 0U);
}

TEST(DdsTransport, TalksToAnotherProcessOverLoopback) {
  const DdsConfig config = loopback(77);
  DdsTransport a(robot(0), config);
  EchoPeerProcess peer(config);
  ASSERT_TRUE(peer.started());
  Inbox inbox;

  // Discovery: probes on both QoS paths until the peer's echoes come back.
  const auto start = Clock::now();
  const std::set<std::pair<int, Qos>> both = {{kEchoPeer, Qos::reliable},
                                              {kEchoPeer, Qos::best_effort}};
  while (inbox.probed != both && Clock::now() - start < kDiscoveryDeadline) {
    a.send(std::nullopt, MessageKind::heartbeat, kProbe);
    a.send(std::nullopt, MessageKind::dgs_state, kProbe);
    if (a.wait(kProbePeriod)) inbox.take(a);
  }
  ASSERT_EQ(inbox.probed, both) << "no echo from the peer process within 5 s";
  std::printf("discovery of a peer process on loopback (both QoS paths, round trip): %.3f s\n",
              std::chrono::duration<double>(Clock::now() - start).count());

  // Best effort and reliable payloads come back intact, the largest included.
  const Bytes descriptor = pattern(2800, 11);
  ASSERT_TRUE(receiveUntil(a, inbox, [&] {
    if (!inbox.has(kEchoPeer, descriptor))
      a.send(robot(kEchoPeer), MessageKind::descriptor, descriptor);
    return inbox.has(kEchoPeer, descriptor);
  }));
  for (const Bytes& payload : {pattern(450'000, 12), pattern(kMaxMessageBytes, 13)}) {
    sendSurely(a, robot(kEchoPeer), MessageKind::map_summary, payload);
    ASSERT_TRUE(receiveUntil(a, inbox, [&] { return inbox.has(kEchoPeer, payload); }))
        << payload.size() << " B did not come back";
  }

  // A unicast to another robot is not for the peer: it echoes only the marker after it.
  const Bytes elsewhere = pattern(90, 14);
  const Bytes marker = pattern(40, 15);
  sendSurely(a, robot(kEchoPeer - 1), MessageKind::loop_measurement, elsewhere);
  sendSurely(a, std::nullopt, MessageKind::loop_measurement, marker);
  ASSERT_TRUE(receiveUntil(a, inbox, [&] { return inbox.has(kEchoPeer, marker); }));
  EXPECT_FALSE(inbox.has(kEchoPeer, elsewhere));
  for (const Datagram& d : inbox.messages) EXPECT_EQ(d.from, robot(kEchoPeer));

  sendSurely(a, robot(kEchoPeer), MessageKind::summary_request, kBye);
  EXPECT_EQ(peer.exitStatus(), std::optional<int>(0));
}

TEST(DdsTransport, KeepsSwarmsAndDomainsApart) {
  DdsConfig alpha = loopback(73);
  DdsConfig beta = alpha;
  beta.swarm += "-beta";
  DdsConfig other_domain = alpha;
  other_domain.domain = 74;

  // Robot 0 talks in swarm alpha, domain 73. Each listener elsewhere has a
  // partner of its own that it demonstrably hears meanwhile.
  DdsTransport speaker(robot(0), alpha);
  DdsTransport peer(robot(1), alpha);
  DdsTransport beta_partner(robot(2), beta);
  DdsTransport beta_listener(robot(3), beta);
  DdsTransport domain_partner(robot(4), other_domain);
  DdsTransport domain_listener(robot(5), other_domain);
  std::vector<Inbox> inbox(2);
  ASSERT_TRUE(discover({&speaker, &peer}, inbox));
  std::vector<Inbox> beta_inbox(2);
  ASSERT_TRUE(discover({&beta_partner, &beta_listener}, beta_inbox));
  std::vector<Inbox> domain_inbox(2);
  ASSERT_TRUE(discover({&domain_partner, &domain_listener}, domain_inbox));

  const Bytes words = pattern(64, 7);
  const Bytes beta_words = pattern(64, 8);
  const Bytes domain_words = pattern(64, 9);
  for (int round = 0; round < 3; ++round) {
    speaker.send(std::nullopt, MessageKind::loop_candidate, words);
    speaker.send(std::nullopt, MessageKind::heartbeat, words);
    beta_partner.send(std::nullopt, MessageKind::loop_candidate, beta_words);
    domain_partner.send(std::nullopt, MessageKind::loop_candidate, domain_words);
    ASSERT_TRUE(receiveUntil(peer, inbox[1], [&] { return inbox[1].has(0, words); }));
    ASSERT_TRUE(receiveUntil(beta_listener, beta_inbox[1],
                             [&] { return beta_inbox[1].has(2, beta_words); }));
    ASSERT_TRUE(receiveUntil(domain_listener, domain_inbox[1],
                             [&] { return domain_inbox[1].has(4, domain_words); }));
  }
  // Probes of the other swarm or domain were never heard either.
  const std::set<std::pair<int, Qos>> beta_peers = {{2, Qos::reliable}, {2, Qos::best_effort}};
  const std::set<std::pair<int, Qos>> domain_peers = {{4, Qos::reliable}, {4, Qos::best_effort}};
  EXPECT_EQ(beta_inbox[1].probed, beta_peers);
  EXPECT_EQ(domain_inbox[1].probed, domain_peers);
  for (const Datagram& d : beta_inbox[1].messages) EXPECT_EQ(d.from, robot(2));
  for (const Datagram& d : domain_inbox[1].messages) EXPECT_EQ(d.from, robot(4));
  EXPECT_FALSE(beta_inbox[1].has(0, words));
  EXPECT_FALSE(domain_inbox[1].has(0, words));
}

TEST(DdsTransport, WaitReturnsWhenASampleArrivesAndTimesOutOtherwise) {
  const DdsConfig config = loopback(75);
  DdsTransport a(robot(0), config);
  DdsTransport b(robot(1), config);
  std::vector<Inbox> inbox(2);
  ASSERT_TRUE(discover({&a, &b}, inbox));
  // Let probes still in flight arrive, then nothing more is coming.
  while (b.wait(std::chrono::milliseconds(100))) inbox[1].take(b);
  EXPECT_FALSE(b.wait(std::chrono::milliseconds(10)));
  EXPECT_TRUE(b.receive().empty());

  const Bytes state = pattern(24, 10);
  a.send(robot(1), MessageKind::dgs_state, state);
  EXPECT_TRUE(b.wait(kDeliveryDeadline));
  ASSERT_TRUE(receiveUntil(b, inbox[1], [&] { return inbox[1].has(0, state); }));
}

/// The message of the core::Error that `make` throws, or "" when it throws none.
std::string errorOf(const std::function<void()>& make) {
  try {
    make();
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

TEST(DdsTransport, RejectsInvalidConfigurationsNamingTheField) {
  const auto invalid = [](const std::function<void(DdsConfig&)>& change) {
    DdsConfig config = loopback(76);
    change(config);
    return errorOf([&] { DdsTransport t(robot(0), config); });
  };
  EXPECT_NE(invalid([](DdsConfig& c) { c.domain = 233; }).find("'domain'"), std::string::npos);
  EXPECT_NE(invalid([](DdsConfig& c) { c.swarm = ""; }).find("'swarm'"), std::string::npos);
  // A wildcard would make the partition match other swarms.
  EXPECT_NE(invalid([](DdsConfig& c) { c.swarm = "dcl*"; }).find("'swarm'"), std::string::npos);
  EXPECT_NE(invalid([](DdsConfig& c) { c.interface = "lo\"/><x"; }).find("'interface'"),
            std::string::npos);
  EXPECT_NE(invalid([](DdsConfig& c) { c.history = 0; }).find("'history'"), std::string::npos);
  EXPECT_EQ(invalid([](DdsConfig&) {}), "");

  // An interface that does not exist: DDS refuses, and the error says which.
  const std::string missing = invalid([](DdsConfig& c) { c.interface = "nosuchif0"; });
  EXPECT_NE(missing.find("dds_create_domain"), std::string::npos) << missing;
  EXPECT_NE(missing.find("nosuchif0"), std::string::npos) << missing;

  // One domain, one configuration per process.
  DdsTransport first(robot(0), loopback(76));
  const std::string clash = invalid([](DdsConfig& c) { c.interface = "eth7"; });
  EXPECT_NE(clash.find("'interface'"), std::string::npos) << clash;
  EXPECT_NE(errorOf([] { DdsTransport t(core::RobotId(), loopback(76)); }).find("robot id"),
            std::string::npos);
  EXPECT_NE(errorOf([&] {
              first.send(core::RobotId(), MessageKind::heartbeat, kProbe);
            }).find("receiver"),
            std::string::npos);
}

}  // namespace
}  // namespace dcl::comm
