// The swarm runner: robots over the simulated radio in lock-step, in
// parallel, deterministic.
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/swarm/swarm_run.hpp>

#include "../common/sim_convoy.hpp"

namespace dcl::swarm {
namespace {

const test::Convoy& convoy() {
  static const test::Convoy c("swarm");
  return c;
}

std::vector<SwarmMember> members(const test::Convoy& data) {
  std::vector<SwarmMember> out;
  std::vector<std::unique_ptr<io::ScanSource>> scans = sim::openDatasetScans(data.spec);
  for (std::size_t r = 0; r < scans.size(); ++r) {
    out.push_back({data.spec.robots[r].name, std::move(scans[r]), data.spec.robots[r].start_time,
                   io::readGroundTruth(data.spec, r), std::nullopt});
  }
  return out;
}

SwarmResult run(int threads, const SwarmConfig& base = {}) {
  SwarmConfig config = base;
  config.threads = threads;
  config.max_frames = 120;
  return runSwarm(members(convoy()), config);
}

TEST(SwarmRun, TheSameRunOnOneOrTwoThreadsGivesTheSameResult) {
  const SwarmResult one = run(1);
  const SwarmResult two = run(2);
  ASSERT_EQ(one.robots.size(), 2u);
  EXPECT_EQ(one.radio_events, two.radio_events);
  for (std::size_t r = 0; r < one.robots.size(); ++r) {
    const MemberResult& a = one.robots[r];
    const MemberResult& b = two.robots[r];
    EXPECT_EQ(a.frames, 120u);
    EXPECT_EQ(a.counters, b.counters) << a.name;
    EXPECT_EQ(a.traffic.sent, b.traffic.sent);
    EXPECT_EQ(a.traffic.received, b.traffic.received);
    ASSERT_EQ(a.inter_loops.size(), b.inter_loops.size());
    for (std::size_t i = 0; i < a.inter_loops.size(); ++i) {
      EXPECT_EQ(a.inter_loops[i].accepted, b.inter_loops[i].accepted);
      EXPECT_TRUE(
          a.inter_loops[i].factor.T_from_to.isApprox(b.inter_loops[i].factor.T_from_to, 0.0));
    }
  }
  // The robots met: descriptors crossed and loops were found.
  EXPECT_GT(one.robots[0].counters.at("descriptors_received"), 0.0);
  EXPECT_GT(one.robots[0].counters.at("inter_loops_accepted"), 0.0);
  EXPECT_GT(
      one.robots[0].traffic.sent_by_kind[static_cast<std::size_t>(comm::MessageKind::descriptor)],
      0u);
}

TEST(SwarmRun, KeepsGoingWhenTheRadioLosesMessages) {
  SwarmConfig lossy;
  lossy.radio.drop_rate = 0.3;
  lossy.drain = 15.0;  // time for the re-sends of the last descriptors
  const SwarmResult result = run(2, lossy);
  for (const MemberResult& m : result.robots) {
    EXPECT_EQ(m.frames, 120u);
    EXPECT_GT(m.keyframes.size(), 5u);
  }
  // Reliable messages are re-sent: every descriptor still arrives, once.
  EXPECT_EQ(result.robots[0].counters.at("descriptors_received"),
            static_cast<double>(result.robots[1].keyframes.size()));
  EXPECT_EQ(result.robots[1].counters.at("descriptors_received"),
            static_cast<double>(result.robots[0].keyframes.size()));
}

TEST(SwarmRun, TheOthersFinishWhenARobotLeavesMidRun) {
  std::vector<SwarmMember> m = members(convoy());
  m[1].leave_time = 6.0;  // robot b stops 6 s in, without a word
  SwarmConfig config;
  config.max_frames = 150;
  config.drain = 10.0;
  const SwarmResult result = runSwarm(std::move(m), config);
  const MemberResult& a = result.robots[0];
  const MemberResult& b = result.robots[1];
  EXPECT_EQ(a.frames, 150u);
  EXPECT_LT(b.frames, 70u);
  EXPECT_GT(a.keyframes.size(), b.keyframes.size());
  // Robot a's map stays consistent: none of its keyframes lost, each where
  // its odometry, loops and finished rounds put it, within 0.3 m of the truth.
  ASSERT_EQ(a.keyframes.size(), static_cast<std::size_t>(a.counters.at("keyframes")));
  core::Trajectory estimate;
  for (const core::Keyframe& k : a.keyframes)
    estimate.push_back(k.stamp, a.graph.estimate({core::RobotId(0), k.id}));
  const eval::AteResult ate =
      eval::computeAte(estimate, members(convoy())[0].ground_truth);  // SE(3)-aligned
  EXPECT_LT(ate.translation_m.rmse, 0.3);
  EXPECT_FALSE(a.counters.contains("dgs_ignored"));
}

TEST(SwarmRun, RefusesWhatItCannotRun) {
  EXPECT_THROW((void)runSwarm({}, {}), core::Error);
  SwarmConfig bad;
  bad.step = 0.0;
  EXPECT_THROW((void)runSwarm(members(convoy()), bad), core::Error);
}

}  // namespace
}  // namespace dcl::swarm
