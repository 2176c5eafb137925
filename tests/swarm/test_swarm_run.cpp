// The swarm runner: robots over the simulated radio in lock-step, in
// parallel, deterministic; its progress and the map it keeps.
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/eval/alignment.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/swarm/merged_map.hpp>
#include <dcl/swarm/swarm_run.hpp>

#include "../common/sim_convoy.hpp"
#include "map_distance.hpp"

namespace dcl::swarm {
namespace {

constexpr std::size_t kFrames = 160;  ///< frames each robot plays

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
  // The whole convoy: PCM keeps loops once they span 10 m of both robots, a
  // few frames more than the first 12 s give with every odometry setting.
  config.max_frames = kFrames;
  return runSwarm(members(convoy()), config);
}

/// The convoy on two threads, shared by the tests that only read it.
const SwarmResult& twoThreads() {
  static const SwarmResult result = run(2);
  return result;
}

TEST(SwarmRun, TheSameRunOnOneOrTwoThreadsGivesTheSameResult) {
  const SwarmResult one = run(1);
  const SwarmResult& two = twoThreads();
  ASSERT_EQ(one.robots.size(), 2u);
  EXPECT_EQ(one.radio_events, two.radio_events);
  for (std::size_t r = 0; r < one.robots.size(); ++r) {
    const MemberResult& a = one.robots[r];
    const MemberResult& b = two.robots[r];
    EXPECT_EQ(a.frames, kFrames);
    EXPECT_EQ(a.counters, b.counters) << a.name;
    EXPECT_EQ(a.traffic.sent, b.traffic.sent);
    EXPECT_EQ(a.traffic.received, b.traffic.received);
    // Every keyframe's cloud is kept for the map, the same way on any thread count.
    EXPECT_EQ(a.map_clouds.size(), a.keyframes.size());
    EXPECT_EQ(a.map_clouds.bytes(), b.map_clouds.bytes());
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
    EXPECT_EQ(m.frames, kFrames);
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
  SwarmStatus last;
  std::size_t calls = 0;
  const SwarmResult result = runSwarm(std::move(m), config, [&](const SwarmStatus& status) {
    for (std::size_t r = 0; r < status.robots.size() && calls > 0; ++r)
      EXPECT_GE(status.robots[r].frames, last.robots[r].frames);  // never backwards
    last = status;
    ++calls;
  });
  const MemberResult& a = result.robots[0];
  const MemberResult& b = result.robots[1];
  EXPECT_EQ(a.frames, 150u);
  EXPECT_LT(b.frames, 70u);
  EXPECT_GT(a.keyframes.size(), b.keyframes.size());
  // The progress after the last step tells what the results tell, and who left.
  EXPECT_GT(calls, 100u);
  EXPECT_LE(last.time, last.end);
  EXPECT_GT(last.time + config.step, last.end - 1e-9);
  ASSERT_EQ(last.robots.size(), 2u);
  for (std::size_t r = 0; r < 2; ++r) {
    const MemberResult& robot = result.robots[r];
    EXPECT_EQ(last.robots[r].name, robot.name);
    EXPECT_EQ(last.robots[r].frames, robot.frames);
    EXPECT_EQ(last.robots[r].total_frames, 150u);
    EXPECT_EQ(last.robots[r].keyframes, robot.keyframes.size());
    EXPECT_EQ(static_cast<double>(last.robots[r].inter_loops),
              robot.counters.at("inter_loops_accepted"));
    EXPECT_EQ(last.robots[r].bytes_sent, robot.traffic.sent);
  }
  EXPECT_FALSE(last.robots[0].left);
  EXPECT_TRUE(last.robots[1].left);
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

/// Every robot's keyframe poses in one frame: `estimate(r, k)` for robot r's keyframe k.
template <class Pose>
std::vector<std::vector<Eigen::Isometry3d>> posesOf(const SwarmResult& result, Pose estimate) {
  std::vector<std::vector<Eigen::Isometry3d>> poses(result.robots.size());
  for (std::size_t r = 0; r < result.robots.size(); ++r) {
    for (const core::Keyframe& k : result.robots[r].keyframes) poses[r].push_back(estimate(r, k));
  }
  return poses;
}

VoxelMap mapAt(const SwarmResult& result,
               const std::vector<std::vector<Eigen::Isometry3d>>& poses) {
  std::vector<VoxelMap> maps;
  for (std::size_t r = 0; r < result.robots.size(); ++r)
    maps.push_back(robotMap(result.robots[r].map_clouds, poses[r], static_cast<std::uint8_t>(r)));
  return mergeMaps(maps, MapConfig{}.voxel);
}

TEST(SwarmRun, TheMapLiesWhereTheGroundTruthPutsIt) {
  const SwarmResult& result = twoThreads();
  const std::vector<SwarmMember> truth = members(convoy());
  const auto true_poses = posesOf(result, [&](std::size_t r, const core::Keyframe& k) {
    return *truth[r].ground_truth.at(k.stamp);
  });
  // The robots' common frame onto the world: one rigid alignment of all keyframes.
  auto estimates = posesOf(result, [&](std::size_t r, const core::Keyframe& k) {
    return result.robots[r].graph.estimate({core::RobotId(static_cast<std::uint8_t>(r)), k.id});
  });
  Eigen::Matrix3Xd from(3, 0), to(3, 0);
  for (std::size_t r = 0; r < estimates.size(); ++r) {
    for (std::size_t k = 0; k < estimates[r].size(); ++k) {
      from.conservativeResize(3, from.cols() + 1);
      to.conservativeResize(3, to.cols() + 1);
      from.col(from.cols() - 1) = estimates[r][k].translation();
      to.col(to.cols() - 1) = true_poses[r][k].translation();
    }
  }
  const eval::Sim3 S = eval::umeyamaAlignment(from, to, false);
  Eigen::Isometry3d T_world_common = Eigen::Isometry3d::Identity();
  T_world_common.linear() = S.R;
  T_world_common.translation() = S.t;
  for (auto& robot : estimates) {
    for (Eigen::Isometry3d& T : robot) T = T_world_common * T;
  }

  const VoxelMap truth_map = mapAt(result, true_poses);
  const VoxelMap estimated_map = mapAt(result, estimates);
  ASSERT_GT(truth_map.size(), 10000u);
  // Within a few centimetres of the map the true poses make (the true map is
  // 1 cm from itself by this measure, one robot 10 cm off makes 6 cm:
  // MergedMap.TheRobotsMapsCoincideAtTheTruePoses).
  const test::MapDistance distance = test::mapDistance(estimated_map, truth_map);
  EXPECT_GT(distance.points, estimated_map.size() / 2);
  EXPECT_LT(distance.median, 0.08);
}

TEST(SwarmRun, RefusesWhatItCannotRun) {
  EXPECT_THROW((void)runSwarm({}, {}), core::Error);
  SwarmConfig bad;
  bad.step = 0.0;
  EXPECT_THROW((void)runSwarm(members(convoy()), bad), core::Error);
}

}  // namespace
}  // namespace dcl::swarm
