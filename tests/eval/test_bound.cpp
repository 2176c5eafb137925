#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/eval/bound.hpp>
#include <dcl/eval/run_graph.hpp>

#include "kitti_run.hpp"

namespace dcl::eval {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The robots' graphs without the inter-robot loops that touch `robot`.
std::vector<RobotGraph> withoutLoopsOf(std::vector<RobotGraph> robots, core::RobotId robot) {
  for (RobotGraph& r : robots) {
    backend::PoseGraph kept;
    for (const auto& [key, T] : r.graph.nodes()) kept.addNode(key, T);
    for (const backend::Factor& f : r.graph.factors()) {
      const bool inter = f.from.robot != f.to.robot;
      if (!inter || (f.from.robot != robot && f.to.robot != robot)) kept.addFactor(f);
    }
    r.graph = kept;
  }
  return robots;
}

std::size_t countKind(const backend::PoseGraph& g, backend::FactorKind kind) {
  std::size_t n = 0;
  for (const backend::Factor& f : g.factors()) n += f.kind == kind ? 1 : 0;
  return n;
}

TEST(JointGraph, HoldsWhatEachLevelAsksAndEveryInterRobotLoopOnce) {
  const std::vector<RobotGraph> robots = test::kittiRun();
  const test::FactorCount n = test::countFactors(robots);
  // KITTI 00 split in three: robot c drives past its own start, robots a and
  // c share the sequence's start and end, and each robot starts where the last ended.
  EXPECT_EQ(n.odometry, 452u);
  EXPECT_EQ(n.own_loops, 7u);
  EXPECT_EQ(n.inter_loops, 67u);
  for (const JointFactors level : {JointFactors::odometry, JointFactors::own_loops,
                                   JointFactors::joint, JointFactors::exact}) {
    const backend::PoseGraph g = jointGraph(robots, level);
    EXPECT_EQ(g.size(), 455u);
    EXPECT_EQ(countKind(g, backend::FactorKind::odometry), n.odometry);
    EXPECT_EQ(countKind(g, backend::FactorKind::intra_loop),
              level == JointFactors::odometry ? 0u : n.own_loops);
    const bool inter = level == JointFactors::joint || level == JointFactors::exact;
    EXPECT_EQ(countKind(g, backend::FactorKind::inter_loop), inter ? n.inter_loops : 0u);
    // Robots no loop ties hold their own frames; tied, the first robot holds all.
    for (const RobotGraph& r : robots)
      EXPECT_EQ(g.isFixed({r.id, core::KeyframeId(0)}), !inter || r.id == robots[0].id) << r.name;
  }
}

TEST(JointGraph, ExactLoopsMeasureTheGroundTruth) {
  const std::vector<RobotGraph> robots = test::kittiRun();
  const backend::PoseGraph measured = jointGraph(robots, JointFactors::joint);
  const backend::PoseGraph exact = jointGraph(robots, JointFactors::exact);
  ASSERT_EQ(measured.factors().size(), exact.factors().size());
  std::size_t inter = 0;
  for (std::size_t k = 0; k < exact.factors().size(); ++k) {
    const backend::Factor& f = exact.factors()[k];
    const backend::Factor& m = measured.factors()[k];
    ASSERT_EQ(f.from, m.from);
    ASSERT_EQ(f.to, m.to);
    if (f.kind != backend::FactorKind::inter_loop) {
      EXPECT_TRUE(f.T_from_to.isApprox(m.T_from_to, 0.0));
      continue;
    }
    ++inter;
    const Eigen::Isometry3d truth =
        robots[f.from.robot.value()].T_world_gt[f.from.keyframe.value()].inverse() *
        robots[f.to.robot.value()].T_world_gt[f.to.keyframe.value()];
    EXPECT_TRUE(f.T_from_to.isApprox(truth, 1e-12));
    EXPECT_FALSE(m.T_from_to.isApprox(truth, 1e-6));  // measured with noise
    EXPECT_TRUE(f.information.isApprox(m.information));
  }
  EXPECT_EQ(inter, 67u);
}

TEST(JointGraph, LoopGroupsFollowTheLoopsThroughOtherRobots) {
  const std::vector<RobotGraph> robots = test::kittiRun();
  EXPECT_EQ(loopGroups(robots), (std::vector<std::size_t>{0, 0, 0}));
  // Without b's loops, a and c still meet at the sequence's start.
  EXPECT_EQ(loopGroups(withoutLoopsOf(robots, robots[1].id)), (std::vector<std::size_t>{0, 1, 0}));
  // Without a's, b and c meet where b ends and c starts.
  EXPECT_EQ(loopGroups(withoutLoopsOf(robots, robots[0].id)), (std::vector<std::size_t>{0, 1, 1}));
  EXPECT_EQ(loopGroups(withoutLoopsOf(withoutLoopsOf(robots, robots[0].id), robots[1].id)),
            (std::vector<std::size_t>{0, 1, 2}));
}

/// KITTI 00's run with every inter-robot loop measured 0.5 m off along x and
/// z of its first keyframe, far beyond its 5 cm standard deviation.
test::KittiRunOptions biasedLoops() {
  test::KittiRunOptions o;
  o.inter_loop_bias.translation() = Eigen::Vector3d(0.5, 0.0, 0.5);
  return o;
}

TEST(Bound, ExactLoopsBeatBiasedLoopsForEveryRobot) {
  const std::vector<RobotBound> biased = computeBound(test::kittiRun(biasedLoops()));
  const std::vector<RobotBound> unbiased = computeBound(test::kittiRun());
  ASSERT_EQ(biased.size(), 3u);
  for (std::size_t i = 0; i < biased.size(); ++i) {
    const RobotBound& r = biased[i];
    EXPECT_LT(r.exact, 0.95 * r.optimum) << r.name;
    EXPECT_LT(r.exact_joint, 0.95 * r.optimum_joint) << r.name;
    // Biased loops cost every robot against loops measured without bias.
    EXPECT_GT(r.optimum, unbiased[i].optimum) << r.name;
    // Exact loops do not depend on how the loops were measured.
    EXPECT_NEAR(r.exact, unbiased[i].exact, 1e-6 * r.exact) << r.name;
    EXPECT_NEAR(r.exact_joint, unbiased[i].exact_joint, 1e-6 * r.exact_joint) << r.name;
  }
}

TEST(Bound, LoopsThatAreExactAlreadyReachTheBound) {
  test::KittiRunOptions o;
  o.exact_loops = true;
  for (const RobotBound& r : computeBound(test::kittiRun(o))) {
    EXPECT_NEAR(r.optimum, r.exact, 1e-9) << r.name;
    EXPECT_NEAR(r.optimum_joint, r.exact_joint, 1e-9) << r.name;
  }
}

TEST(Bound, EachLevelAsTheRunsFiguresHaveIt) {
  const std::vector<RobotGraph> robots = test::kittiRun();
  JointCosts costs;
  const std::vector<RobotBound> bound = computeBound(robots, &costs);
  ASSERT_EQ(bound.size(), robots.size());
  for (std::size_t i = 0; i < robots.size(); ++i) {
    const RobotGraph& r = robots[i];
    const RobotBound& b = bound[i];
    EXPECT_EQ(b.name, r.name);
    EXPECT_FALSE(b.left);
    // The run's figure is the ATE of its estimates, as the run's metrics measure it.
    std::vector<Eigen::Isometry3d> poses;
    for (std::size_t k = 0; k < r.stamps.size(); ++k)
      poses.push_back(r.graph.estimate({r.id, core::KeyframeId(k)}));
    const AteResult ate = computeAte(core::Trajectory(r.stamps, poses), r.ground_truth);
    EXPECT_DOUBLE_EQ(b.run, ate.translation_m.rmse) << r.name;
    // Its estimates are its odometry: solving the odometry alone changes nothing.
    EXPECT_NEAR(b.odometry, b.run, 1e-3 * b.run) << r.name;
    // The loops of three robots that share much of the route lower every robot's ATE.
    EXPECT_LT(b.optimum, 0.8 * b.odometry) << r.name;
    // Aligned with the others a robot can only lose against its own alignment.
    EXPECT_GE(b.run_joint, b.run - 1e-9) << r.name;
    EXPECT_GE(b.optimum_joint, b.optimum - 1e-9) << r.name;
    EXPECT_GE(b.exact_joint, b.exact - 1e-9) << r.name;
    EXPECT_NEAR(robotAte(r, solveJointGraph(robots, JointFactors::joint)), b.optimum, 1e-12);
  }
  // Only c closes loops of its own; a's and b's own SLAM is their odometry.
  EXPECT_NEAR(bound[0].own_loops, bound[0].odometry, 1e-5 * bound[0].odometry);
  EXPECT_NEAR(bound[1].own_loops, bound[1].odometry, 1e-5 * bound[1].odometry);
  EXPECT_LT(bound[2].own_loops, 0.95 * bound[2].odometry);
  // The run's estimates (odometry, robots in frames of their own) are far from the optimum.
  EXPECT_GT(costs.optimum, 0.0);
  EXPECT_LT(1e3 * costs.optimum, costs.run);
  EXPECT_TRUE(costs.left.empty());
  EXPECT_EQ(costs.stayed_run, 0.0);
  EXPECT_EQ(costs.stayed_optimum, 0.0);
}

TEST(Bound, TheRobotsThatLeftAreCostedApart) {
  std::vector<RobotGraph> robots = test::kittiRun();
  robots[1].left = true;
  JointCosts all;
  (void)computeBound(test::kittiRun(), &all);
  JointCosts costs;
  const std::vector<RobotBound> bound = computeBound(robots, &costs);
  EXPECT_EQ(costs.left, (std::vector<std::string>{"b"}));
  EXPECT_FALSE(bound[0].left);
  EXPECT_TRUE(bound[1].left);
  EXPECT_FALSE(bound[2].left);
  // The whole graph's costs do not change; a and c alone hold fewer factors.
  EXPECT_DOUBLE_EQ(costs.run, all.run);
  EXPECT_NEAR(costs.optimum, all.optimum, 1e-9 * all.optimum);
  EXPECT_GT(costs.stayed_optimum, 0.0);
  EXPECT_LE(costs.stayed_optimum, costs.stayed_run);
  EXPECT_LT(costs.stayed_optimum, costs.optimum);
  EXPECT_LT(costs.stayed_run, costs.run);
}

TEST(Bound, MeanLoweredAndNotBelowLeaveOutMissingFigures) {
  const auto robot = [](double odometry, double run) {
    RobotBound r;
    r.odometry = odometry;
    r.run = run;
    return r;
  };
  const std::vector<RobotBound> robots{robot(2.0, 1.0), robot(4.0, 1.0),  robot(1.0, 1.5),
                                       robot(0.0, 1.0), robot(1.0, kNaN), robot(kNaN, 1.0)};
  // (0.5 + 0.75 - 0.5) / 3: no base, or no figure, is no robot.
  EXPECT_DOUBLE_EQ(meanLowered(robots, &RobotBound::run, &RobotBound::odometry), 0.25);
  // 1.5 >= 1 and 1 >= 0; a robot with a NaN figure is not counted.
  EXPECT_EQ(notBelow(robots, &RobotBound::run, &RobotBound::odometry), 2u);
  EXPECT_EQ(notBelow(robots, &RobotBound::odometry, &RobotBound::run), 2u);
  EXPECT_EQ(notBelow(robots, &RobotBound::run, &RobotBound::run), 5u);
  EXPECT_DOUBLE_EQ(meanLowered(robots, &RobotBound::odometry, &RobotBound::odometry), 0.0);
  EXPECT_EQ(meanLowered({}, &RobotBound::run, &RobotBound::odometry), 0.0);
  EXPECT_EQ(notBelow({}, &RobotBound::run, &RobotBound::odometry), 0u);
}

TEST(Bound, ARobotThatHasNotMovedHasNoAte) {
  std::vector<RobotGraph> robots = test::kittiRun();
  RobotGraph still;
  still.name = "d";
  still.id = core::RobotId(3);
  for (std::size_t k = 0; k < 2; ++k) {
    still.stamps.push_back(static_cast<double>(k));
    still.T_world_gt.push_back(Eigen::Isometry3d::Identity());
    still.ground_truth.push_back(static_cast<double>(k), Eigen::Isometry3d::Identity());
    still.graph.addNode({still.id, core::KeyframeId(k)}, Eigen::Isometry3d::Identity());
  }
  EXPECT_TRUE(std::isnan(robotAte(still, still.graph)));
  robots.push_back(still);
  const std::vector<double> joint = jointAtes(robots, jointGraph(robots, JointFactors::joint));
  ASSERT_EQ(joint.size(), 4u);
  EXPECT_TRUE(std::isnan(joint[3]));  // alone in its group
  for (std::size_t i = 0; i < 3; ++i) EXPECT_FALSE(std::isnan(joint[i])) << i;
}

}  // namespace
}  // namespace dcl::eval
