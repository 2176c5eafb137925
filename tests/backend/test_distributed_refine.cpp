#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/dgs.hpp>
#include <dcl/backend/distributed_refine.hpp>
#include <dcl/backend/refine_coarse.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/multi_robot_graph.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

#include "../common/keys.hpp"

namespace dcl::backend {
namespace {

using dcl::test::poseGraphPath;

/// A single-robot benchmark of pose_graphs/3d split into `robots` robots.
PoseGraph splitBenchmark(const std::string& file, int robots) {
  return splitIntoRobots(io::readPoseGraph(poseGraphPath("3d/" + file)), robots);
}

/// A distributed-mapper example (robot i's graph in i.g2o).
PoseGraph mapperExample(int robots) {
  return io::readMultiRobotGraph(
      poseGraphPath("multi_robot/distributed_mapper/example_" + std::to_string(robots) + "robots"));
}

using dcl::test::key;

/// The centralized optimum of `graph` (Levenberg-Marquardt from the chordal initialisation).
PoseGraph centralizedOptimum(PoseGraph graph) {
  SolverConfig config;
  config.initialisation = "chordal";
  const SolverSummary summary = solveCentralized(graph, config);
  EXPECT_TRUE(summary.converged) << summary.message;
  return graph;
}

/// The largest SE(3) distance between the estimates of the same node in `a` and `b`.
double maxPoseDifference(const PoseGraph& a, const PoseGraph& b) {
  double worst = 0.0;
  for (const auto& [k, T] : a.nodes()) {
    worst = std::max(worst, core::logSE3(T.inverse() * b.estimate(k)).norm());
  }
  return worst;
}

/// Own poses each robot's inter-robot factors touch, per robot and neighbour.
std::map<core::RobotId, std::map<core::RobotId, std::set<core::PoseKey>>> separatorsOf(
    const PoseGraph& graph) {
  std::map<core::RobotId, std::map<core::RobotId, std::set<core::PoseKey>>> separators;
  for (const Factor& f : graph.factors()) {
    if (f.from.robot == f.to.robot || !graph.connects(f)) continue;
    separators[f.from.robot][f.to.robot].insert(f.from);
    separators[f.to.robot][f.from.robot].insert(f.to);
  }
  return separators;
}

std::string errorOf(const RefineConfig& config) {
  try {
    validate(config);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

TEST(RefineConfig, RejectsOutOfRangeFieldsByName) {
  EXPECT_EQ(errorOf({}), "");
  RefineConfig c;
  c.max_rounds = -1;
  EXPECT_NE(errorOf(c).find("max_rounds"), std::string::npos) << errorOf(c);
  c = {};
  c.relative_tolerance = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(errorOf(c).find("relative_tolerance"), std::string::npos) << errorOf(c);
  c = {};
  c.window = 0;
  EXPECT_NE(errorOf(c).find("window"), std::string::npos) << errorOf(c);
  c = {};
  c.block_iterations = 0;
  EXPECT_NE(errorOf(c).find("block_iterations"), std::string::npos) << errorOf(c);
  c = {};
  c.block_tolerance = -1.0;
  EXPECT_NE(errorOf(c).find("block_tolerance"), std::string::npos) << errorOf(c);
  c = {};
  c.coarse_trust = 1.0;
  EXPECT_NE(errorOf(c).find("coarse_trust"), std::string::npos) << errorOf(c);
  c = {};
  c.factorisation_reuse = -1;
  EXPECT_NE(errorOf(c).find("factorisation_reuse"), std::string::npos) << errorOf(c);
  PoseGraph graph = mapperExample(2);
  EXPECT_THROW((void)refineDistributed(graph, c), core::Error);
}

TEST(DistributedRefine, PlainBlockDescentLowersTheCostEveryRound) {
  PoseGraph graph = splitBenchmark("smallGrid3D.g2o", 4);
  RefineConfig config;
  config.accelerate = false;
  config.coarse_cells = 0;
  config.max_rounds = 30;
  const RefineSummary s = refineDistributed(graph, config);
  ASSERT_EQ(s.rounds, 30);
  ASSERT_EQ(s.round_costs.size(), 30u);
  EXPECT_EQ(s.restarts, 0);
  EXPECT_LT(s.round_costs.front(), s.initial_cost);
  for (std::size_t i = 1; i < s.round_costs.size(); ++i) {
    EXPECT_LT(s.round_costs[i], s.round_costs[i - 1]) << "round " << i;
  }
  EXPECT_LT(s.final_cost, 0.02 * s.initial_cost);
  EXPECT_DOUBLE_EQ(graphCost(graph), s.final_cost);
}

TEST(DistributedRefine, AcceleratedCostNeverIncreasesAndBeatsPlainDescent) {
  // With the first node held, as a robot of a live group holds it: the robot
  // holding it bends its part around it, and plain block descent crawls.
  PoseGraph start = splitBenchmark("smallGrid3D.g2o", 4);
  start.fix(start.nodes().begin()->first);
  RefineConfig config;
  config.max_rounds = 30;
  config.relative_tolerance = 0.0;
  config.coarse_cells = 0;  // momentum alone (the coarse level: CoarseSteps*)
  PoseGraph accelerated = start;
  const RefineSummary s = refineDistributed(accelerated, config);
  ASSERT_EQ(s.round_costs.size(), static_cast<std::size_t>(s.rounds));
  EXPECT_LE(s.round_costs.front(), s.initial_cost);
  for (std::size_t i = 1; i < s.round_costs.size(); ++i) {
    EXPECT_LE(s.round_costs[i], s.round_costs[i - 1]) << "round " << i;
  }
  EXPECT_DOUBLE_EQ(graphCost(accelerated), s.final_cost);
  const double optimum = graphCost(centralizedOptimum(start));
  const auto gap = [&](bool accelerate, int reuse) {
    PoseGraph graph = start;
    RefineConfig c = config;
    c.accelerate = accelerate;
    c.factorisation_reuse = reuse;
    return refineDistributed(graph, c).final_cost - optimum;
  };
  // Nesterov momentum: with exact block steps, the gap to the optimum after
  // 30 rounds at least 10x smaller; with factorisations reused across rounds
  // (the default, whose steps are less exact) at least 4x.
  EXPECT_LT(gap(true, 0), 0.1 * gap(false, 0));
  EXPECT_LT(s.final_cost - optimum, 0.25 * gap(false, config.factorisation_reuse));
}

/// A benchmark split into robots, refined from the file's own (odometry-composed) estimates.
class RefineSmallGrid : public ::testing::TestWithParam<int> {};

TEST_P(RefineSmallGrid, ReachesTheCentralizedOptimumFromTheInitialEstimate) {
  PoseGraph graph = splitBenchmark("smallGrid3D.g2o", GetParam());
  const PoseGraph optimum = centralizedOptimum(graph);
  const RefineSummary s = refineDistributed(graph);
  EXPECT_TRUE(s.converged);
  EXPECT_GT(s.initial_cost, 100.0 * s.final_cost);
  EXPECT_LE(s.final_cost / graphCost(optimum), 1.001);
  // Below the optimum by no more than Ceres' own tolerance leaves above it.
  EXPECT_GE(s.final_cost / graphCost(optimum), 1.0 - 1e-6);
  EXPECT_LT(maxPoseDifference(graph, optimum), 0.05);
}

INSTANTIATE_TEST_SUITE_P(Robots, RefineSmallGrid, ::testing::Values(2, 4));

TEST(DistributedRefine, DgsThenRefineReachesTheCentralizedOptimum) {
  for (const int robots : {9}) {
    PoseGraph graph = splitBenchmark("smallGrid3D.g2o", robots);
    const double optimum = graphCost(centralizedOptimum(graph));
    (void)runDgs(graph);
    const double after_dgs = graphCost(graph);
    const RefineSummary s = refineDistributed(graph);
    EXPECT_TRUE(s.converged);
    EXPECT_DOUBLE_EQ(s.initial_cost, after_dgs);
    EXPECT_GT(after_dgs / optimum, 1.01);  // DGS alone stops near the optimum, not at it
    EXPECT_LE(s.final_cost / optimum, 1.001) << robots << " robots";
  }
}

TEST(DistributedRefine, CoarseStepsPricedBeforeTakenReachManhattansOptimum) {
  // manhattan in 9 robots: every robot's part criss-crosses the whole map, and
  // coarse blocks a round old make the coarse step rise at every length.
  PoseGraph start = splitIntoRobots(io::readPoseGraph(poseGraphPath("2d/manhattan.g2o")), 9);
  const double optimum = graphCost(centralizedOptimum(start));
  (void)runDgs(start);
  RefineConfig config;
  config.max_rounds = 100;
  PoseGraph priced = start;
  const RefineSummary s = refineDistributed(priced, config);
  EXPECT_GT(s.coarse_refreshes, 0u);
  EXPECT_LE(s.final_cost / optimum, 1.01);
  config.coarse_trust = 0.0;  // blocks refreshed only by their Frobenius change
  PoseGraph stale = start;
  const RefineSummary t = refineDistributed(stale, config);
  EXPECT_EQ(t.coarse_refreshes, 0u);
  EXPECT_GT(t.final_cost / optimum, 1.1);
}

TEST(CoarseScale, TakesTheCheapestLengthAndRefreshesAModelThatFellShort) {
  CoarseStep step;
  step.slope = -20.0;  // the model predicts a fall of 10
  // Falls of 2, 9, 6 and -1 at 0.5, 1, 1.5, 2 times the step.
  CoarseChoice c = coarseScale(step, 100.0, {98.0, 91.0, 94.0, 101.0}, 0.5);
  EXPECT_DOUBLE_EQ(c.scale, 1.0);
  EXPECT_FALSE(c.refresh);
  c = coarseScale(step, 100.0, {99.0, 97.0, 102.0, 110.0}, 0.5);  // a fall of 3: short
  EXPECT_DOUBLE_EQ(c.scale, 1.0);
  EXPECT_TRUE(c.refresh);
  c = coarseScale(step, 100.0, {101.0, 120.0, 150.0, 200.0}, 0.5);  // every length rises
  EXPECT_DOUBLE_EQ(c.scale, 0.0);
  EXPECT_TRUE(c.refresh);
  EXPECT_FALSE(coarseScale(step, 100.0, {101.0, 120.0, 150.0, 200.0}, 0.0).refresh);
}

TEST(DistributedRefine, DistributedMapperExamplesReachTheCentralizedOptimum) {
  for (const int robots : {2, 4, 9}) {
    PoseGraph graph = mapperExample(robots);
    const PoseGraph optimum = centralizedOptimum(graph);
    const RefineSummary s = refineDistributed(graph);
    EXPECT_TRUE(s.converged) << robots;
    EXPECT_LE(s.final_cost / graphCost(optimum), 1.001) << robots;
    // The same minimum, up to the slack of the flat directions the tolerance leaves
    // (8 cm at the far end of the 15 m 9-robot example).
    EXPECT_LT(maxPoseDifference(graph, optimum), 0.1) << robots;
  }
}

TEST(DistributedRefine, CountsEverySeparatorPoseSentEveryRound) {
  PoseGraph graph = mapperExample(4);
  const auto separators = separatorsOf(graph);
  RefineConfig config;
  config.max_rounds = 7;
  const RefineSummary s = refineDistributed(graph, config);
  ASSERT_EQ(s.rounds, 7);
  std::size_t total = 0;
  ASSERT_EQ(s.values_sent.size(), 4u);
  for (const auto& [robot, sent] : s.values_sent) {
    std::size_t per_round = 0;
    for (const auto& [neighbour, keys] : separators.at(robot)) per_round += keys.size();
    EXPECT_GT(per_round, 0u);
    EXPECT_EQ(sent, 7 * per_round) << core::robotName(robot);
    total += sent;
  }
  EXPECT_EQ(s.separator_values, total);
}

TEST(DistributedRefine, ASingleRobotEqualsTheCentralizedSolve) {
  PoseGraph graph = io::readPoseGraph(poseGraphPath("3d/smallGrid3D.g2o"));
  PoseGraph centralized = graph;
  (void)solveCentralized(centralized);
  const RefineSummary s = refineDistributed(graph);
  EXPECT_TRUE(s.converged);
  EXPECT_EQ(s.separator_values, 0u);
  EXPECT_NEAR(s.final_cost / graphCost(centralized), 1.0, 1e-7);
  EXPECT_LT(maxPoseDifference(graph, centralized), 1e-4);
}

/// Every node of `graph` re-keyed to robot `robot`.
PoseGraph asRobot(const PoseGraph& graph, int robot) {
  PoseGraph out;
  const auto rekey = [&](const core::PoseKey& k) { return key(robot, k.keyframe.value()); };
  for (const auto& [k, T] : graph.nodes()) out.addNode(rekey(k), T);
  for (Factor f : graph.factors()) {
    f.from = rekey(f.from);
    f.to = rekey(f.to);
    out.addFactor(f);
  }
  return out;
}

TEST(DistributedRefine, ARobotWithoutInterRobotFactorsIsSolvedAlone) {
  // Robots 0 and 1 of a distributed-mapper example, and robot 5: tinyGrid3D, met by no one.
  PoseGraph graph = mapperExample(2);
  const Eigen::Isometry3d T_first = graph.nodes().begin()->second;
  const PoseGraph alone = asRobot(io::readPoseGraph(poseGraphPath("3d/tinyGrid3D.g2o")), 5);
  for (const auto& [k, T] : alone.nodes()) graph.addNode(k, T);
  for (const Factor& f : alone.factors()) graph.addFactor(f);
  PoseGraph alone_solved = alone;
  SolverConfig tight;
  tight.function_tolerance = 1e-14;
  (void)solveCentralized(alone_solved, tight);

  const RefineSummary s = refineDistributed(graph);
  EXPECT_TRUE(s.converged);
  EXPECT_EQ(s.values_sent.at(core::RobotId(5)), 0u);
  EXPECT_GT(s.values_sent.at(core::RobotId(0)), 0u);
  // The lowest robot's first node is where it started (the gauge).
  EXPECT_TRUE(graph.nodes().begin()->second.isApprox(T_first, 1e-12));
  for (const auto& [k, T] : alone_solved.nodes()) {
    EXPECT_LT(core::logSE3(T.inverse() * graph.estimate(k)).norm(), 1e-5);
  }
}

TEST(DistributedRefine, AFixedNodeHoldsTheGauge) {
  PoseGraph graph = mapperExample(4);
  const core::PoseKey held = std::next(graph.nodes().begin(), 30)->first;
  const Eigen::Isometry3d T_held =
      graph.estimate(held) * core::expSE3((core::Vector6d() << 1, 2, 0, 0, 0, 0.3).finished());
  graph.setEstimate(held, T_held);
  graph.fix(held);
  const double optimum = graphCost(centralizedOptimum(graph));
  const RefineSummary s = refineDistributed(graph);
  EXPECT_TRUE(graph.estimate(held).matrix() == T_held.matrix());
  EXPECT_LE(s.final_cost / optimum, 1.001);
}

TEST(DistributedRefine, AFactorFromANodeToItselfIsLeftOutNotFatal) {
  // Ceres aborts on a residual naming one parameter block twice; such a factor
  // (a constant cost) may arrive from a peer.
  PoseGraph graph = mapperExample(2);
  const core::PoseKey k = std::next(graph.nodes().begin(), 5)->first;
  graph.addFactor(
      {k, k, core::makePose2d(0.5, 0.0, 0.1), core::Matrix6d::Identity(), FactorKind::intra_loop});
  PoseGraph centralized = graph;
  const SolverSummary c = solveCentralized(centralized);
  EXPECT_EQ(c.skipped_factors, 1u);
  const RefineSummary s = refineDistributed(graph);
  EXPECT_TRUE(s.converged);
  EXPECT_LE(s.final_cost / c.final_cost, 1.001);
}

/// Agents of `graph`, each given its local graph with the neighbours'
/// separators, and every neighbour's coarse grid.
std::map<core::RobotId, RefineAgent> makeAgents(const PoseGraph& graph,
                                                const RefineConfig& config) {
  std::map<core::RobotId, RefineAgent> agents;
  for (auto [robot, local] : partitionByRobot(graph)) {
    for (const Factor& f : local.factors()) {
      for (const core::PoseKey& k : {f.from, f.to}) {
        if (!local.hasNode(k) && graph.hasNode(k)) local.addNode(k, graph.estimate(k));
      }
    }
    agents.emplace(robot, RefineAgent(robot, local, config));
  }
  for (auto& [robot, agent] : agents) {
    for (const core::RobotId n : agent.neighbours()) {
      if (agents.at(n).coarseGrid()) agent.setCoarseGrid(n, *agents.at(n).coarseGrid());
    }
  }
  return agents;
}

/// Every pose of `graph` relative to its first node: what a gauge leaves alone.
std::map<core::PoseKey, Eigen::Isometry3d> relativeToFirst(const PoseGraph& graph) {
  std::map<core::PoseKey, Eigen::Isometry3d> relative;
  const Eigen::Isometry3d first_inverse = graph.nodes().begin()->second.inverse();
  for (const auto& [k, T] : graph.nodes()) relative.emplace(k, first_inverse * T);
  return relative;
}

TEST(RefineAgent, AgentsPassingValuesByHandRunTheSameRoundsAsTheDriver) {
  // What refineDistributed does, spelled out with the agents' plain values:
  // Gauss-Seidel steps, the group's schedule from the summed cost shares,
  // and the coarse step from every robot's share after each kept round.
  const PoseGraph start = mapperExample(4);
  RefineConfig config;
  config.relative_tolerance = 0.0;
  config.max_rounds = 8;
  auto agents = makeAgents(start, config);
  PoseGraph by_hand = start;
  RefineSchedule schedule(config, graphCost(start));
  CoarseSolver solver;
  std::optional<CoarseStep> coarse;
  while (!schedule.done()) {
    for (auto& [robot, agent] : agents)
      agent.beginRound(schedule.momentum(), coarse ? &*coarse : nullptr);
    double cost = 0.0;
    for (auto& [robot, agent] : agents) {
      const RefineStep step = agent.step();
      EXPECT_LE(step.cost_after, step.cost_before);
      EXPECT_EQ(step.outgoing.size(), agent.neighbours().size());
      for (const auto& [neighbour, poses] : step.outgoing) agents.at(neighbour).receive(poses);
    }
    for (auto& [robot, agent] : agents) {
      cost += agent.ownedCost();
      for (const auto& [k, T] : agent.estimates()) by_hand.setEstimate(k, T);
    }
    EXPECT_NEAR(cost, graphCost(by_hand), 1e-9 * cost);
    const bool keep = schedule.endRound(cost, coarse.has_value());
    coarse.reset();
    if (keep) {
      std::vector<CoarseShare> shares;
      for (auto& [robot, agent] : agents) shares.push_back(agent.shareCoarse());
      coarse = solver.solve(shares);
    }
    for (auto& [robot, agent] : agents) agent.endRound(keep);
  }
  for (const auto& [robot, agent] : agents) {
    for (const auto& [k, T] : agent.estimates()) by_hand.setEstimate(k, T);
  }
  PoseGraph driven = start;
  const RefineSummary s = refineDistributed(driven, config);
  EXPECT_EQ(s.rounds, schedule.rounds());
  EXPECT_NEAR(graphCost(driven), graphCost(by_hand), 1e-9 * graphCost(by_hand));
  const auto hand = relativeToFirst(by_hand);
  for (const auto& [k, T] : relativeToFirst(driven)) {
    EXPECT_TRUE(T.isApprox(hand.at(k), 1e-9)) << core::robotName(k.robot);
  }
}

TEST(RefineAgent, OwnedCostsSumToTheGraphCostAndFallRoundByRound) {
  // As robots over a network run it: each agent knows only its own poses at
  // first; a first exchange of separators, then rounds in id order, each
  // agent's share of the cost taken once every neighbour's values of the
  // round are in.
  const PoseGraph start = mapperExample(4);
  RefineConfig config;
  config.accelerate = false;
  std::map<core::RobotId, RefineAgent> agents;
  for (auto [robot, local] : partitionByRobot(start)) {
    if (robot == start.nodes().begin()->first.robot) local.fix(start.nodes().begin()->first);
    agents.emplace(robot, RefineAgent(robot, local, config));
  }
  const auto exchange = [&](const auto& outgoing) {
    for (const auto& [neighbour, poses] : outgoing) agents.at(neighbour).receive(poses);
  };
  const auto total = [&] {
    double shares = 0.0;
    PoseGraph g = start;
    for (const auto& [robot, agent] : agents) {
      shares += agent.ownedCost();
      for (const auto& [k, T] : agent.estimates()) g.setEstimate(k, T);
    }
    EXPECT_NEAR(shares, graphCost(g), 1e-9 * graphCost(g));
    return shares;
  };
  for (auto& [robot, agent] : agents) {
    std::map<core::RobotId, std::map<core::PoseKey, Eigen::Isometry3d>> first;
    for (const auto& [neighbour, keys] : agent.separators())
      for (const core::PoseKey& k : keys) first[neighbour][k] = agent.estimates().at(k);
    exchange(first);
  }
  double cost = total();
  EXPECT_NEAR(cost, graphCost(start), 1e-9 * cost);
  for (auto& [robot, agent] : agents) agent.endRound(true);
  for (int round = 0; round < 5; ++round) {
    for (auto& [robot, agent] : agents) agent.beginRound();
    for (auto& [robot, agent] : agents) exchange(agent.step().outgoing);
    const double next = total();
    EXPECT_LT(next, cost) << "round " << round;
    cost = next;
    for (auto& [robot, agent] : agents) agent.endRound(true);
  }
}

TEST(RefineAgent, AFactorToAnUnknownNeighbourPoseWaitsForItsValue) {
  const PoseGraph graph = mapperExample(2);
  const core::RobotId b(1);
  PoseGraph local = partitionByRobot(graph).at(b);
  for (const auto& [k, T] : local.nodes()) ASSERT_EQ(k.robot, b);
  RefineAgent agent(b, local, {});
  ASSERT_FALSE(agent.neighbourPoses().empty());
  EXPECT_EQ(agent.neighbours(), std::set<core::RobotId>{core::RobotId(0)});

  // Without a's values the block is b's own factors only.
  PoseGraph own_only;
  for (const auto& [k, T] : local.nodes()) own_only.addNode(k, T);
  for (const Factor& f : local.factors()) own_only.addFactor(f);  // inter factors: ends missing
  agent.beginRound();
  const RefineStep first = agent.step();
  EXPECT_NEAR(first.cost_before, graphCost(own_only), 1e-9 * graphCost(own_only));
  agent.endRound(true);

  // With them, the inter-robot factors count too.
  std::map<core::PoseKey, Eigen::Isometry3d> values;
  for (const core::PoseKey& k : agent.neighbourPoses()) values.emplace(k, graph.estimate(k));
  agent.beginRound();
  agent.receive(values);
  for (const auto& [k, T] : agent.estimates()) own_only.setEstimate(k, T);
  PoseGraph with_neighbours = own_only;
  for (const auto& [k, T] : values) with_neighbours.addNode(k, T);
  const RefineStep second = agent.step();
  EXPECT_GT(graphCost(with_neighbours), graphCost(own_only) + 1e-3);
  EXPECT_NEAR(second.cost_before, graphCost(with_neighbours), 1e-9 * graphCost(with_neighbours));
  EXPECT_LE(second.cost_after, second.cost_before);
}

TEST(RefineAgent, HeldNeighbourPosesStayPutAndTheirFactorsAreOwned) {
  // Robot b of the two-robot example, with a's separators held where the
  // joint optimum puts them (fixed in b's local graph): a robot whose
  // neighbour is out of the group. b's block is then the whole problem left,
  // and its solve is the joint optimum's b.
  const PoseGraph graph = mapperExample(2);
  const PoseGraph optimum = centralizedOptimum(graph);
  const core::RobotId b(1);
  PoseGraph local = partitionByRobot(graph).at(b);
  std::set<core::PoseKey> held;
  for (const Factor& f : local.factors()) {
    for (const core::PoseKey& end : {f.from, f.to}) {
      if (end.robot == b || !held.insert(end).second) continue;
      local.addNode(end, optimum.estimate(end));
      local.fix(end);
    }
  }
  ASSERT_FALSE(held.empty());
  RefineAgent agent(b, local, {});
  EXPECT_TRUE(agent.neighbours().empty());
  EXPECT_TRUE(agent.neighbourPoses().empty());
  agent.beginRound();
  const RefineStep step = agent.step();
  EXPECT_TRUE(step.outgoing.empty());
  EXPECT_LT(step.cost_after, step.cost_before);
  agent.endRound(true);
  double worst = 0.0;
  for (const auto& [k, T] : agent.estimates())
    worst = std::max(worst, core::logSE3(T.inverse() * optimum.estimate(k)).norm());
  EXPECT_LT(worst, 1e-4);

  // b owns every factor, a's id being lower: its share is its block's whole cost.
  PoseGraph solved = local;
  for (const auto& [k, T] : agent.estimates()) solved.setEstimate(k, T);
  EXPECT_NEAR(agent.ownedCost(), graphCost(solved), 1e-9 * graphCost(solved));

  // Values sent for a held pose are not taken in.
  std::map<core::PoseKey, Eigen::Isometry3d> moved;
  for (const core::PoseKey& k : held)
    moved.emplace(k, optimum.estimate(k) * core::expSE3(core::Vector6d::Constant(0.1)));
  agent.beginRound();
  agent.receive(moved);
  const RefineStep again = agent.step();
  EXPECT_NEAR(again.cost_before, graphCost(solved), 1e-9 * graphCost(solved) + 1e-12);
}

TEST(CentralizedInitialisation, ChordalStartReachesTheSameOptimumFromCloser) {
  const PoseGraph start = io::readPoseGraph(poseGraphPath("3d/smallGrid3D.g2o"));
  PoseGraph as_is = start;
  PoseGraph chordal = start;
  const SolverSummary a = solveCentralized(as_is);
  SolverConfig config;
  config.initialisation = "chordal";
  const SolverSummary c = solveCentralized(chordal, config);
  EXPECT_DOUBLE_EQ(a.initialised_cost, a.initial_cost);
  EXPECT_DOUBLE_EQ(c.initial_cost, a.initial_cost);
  EXPECT_LT(c.initialised_cost, 0.1 * c.initial_cost);
  EXPECT_LT(c.iterations, a.iterations);
  EXPECT_NEAR(c.final_cost / a.final_cost, 1.0, 1e-6);
  EXPECT_TRUE(chordal.nodes().begin()->second.matrix() == start.nodes().begin()->second.matrix());
}

TEST(CentralizedInitialisation, UnknownNameThrowsAndLeavesTheGraphAlone) {
  PoseGraph graph = mapperExample(2);
  const PoseGraph before = graph;
  SolverConfig config;
  config.initialisation = "spanning_tree";
  EXPECT_THROW((void)solveCentralized(graph, config), core::Error);
  for (const auto& [k, T] : before.nodes()) {
    EXPECT_TRUE(graph.estimate(k).matrix() == T.matrix());
  }
}

TEST(DistributedRefine, SeparatorsThatBarelyMovedAreNotSent) {
  PoseGraph every = splitBenchmark("smallGrid3D.g2o", 4);
  const double optimum = graphCost(centralizedOptimum(every));
  PoseGraph changed = every;
  RefineConfig config;
  const RefineSummary all = refineDistributed(every, config);
  config.separator_tolerance = 1e-3;
  const RefineSummary some = refineDistributed(changed, config);
  // Fewer values in all; the answer as close.
  EXPECT_LT(some.separator_values, all.separator_values) << some.rounds << " " << all.rounds;
  EXPECT_LE(graphCost(changed) / optimum, 1.001);
  // The robots' cost is that of their copies, within the tolerance of the graph's.
  EXPECT_NEAR(some.final_cost, graphCost(changed), 1e-3 * graphCost(changed));
}

// ---- the coarse level ------------------------------------------------------

/// `n` x `n` positions filling [0, x] x [0, y] at height z (every other one a millimetre up).
std::vector<Eigen::Vector3d> sheet(double x, double y, int n) {
  std::vector<Eigen::Vector3d> positions;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j)
      positions.emplace_back(x * i / (n - 1), y * j / (n - 1), 0.001 * (i % 2));
  }
  return positions;
}

TEST(CoarseGrid, CoversTheBoxAndFlattensAThinSide) {
  const CoarseGrid grid = makeCoarseGrid(sheet(8, 2, 20), 4);
  EXPECT_DOUBLE_EQ(grid.cell, 2.0);
  EXPECT_EQ(grid.origin, Eigen::Vector3d::Zero());
  EXPECT_EQ(grid.nodes, Eigen::Vector3i(5, 2, 1));
  EXPECT_EQ(grid.size(), 10);
}

TEST(CoarseGrid, HasFewerNodesThanAQuarterOfItsPositions) {
  // 25 positions: at most 6 nodes, so one cell (four nodes in the plane).
  const CoarseGrid grid = makeCoarseGrid(sheet(8, 8, 5), 8);
  EXPECT_EQ(grid.nodes, Eigen::Vector3i(2, 2, 1));
  EXPECT_DOUBLE_EQ(grid.cell, 8.0);
}

TEST(CoarseGrid, HatWeightsSumToOneAndReproducePositions) {
  // Enough positions in the box [-3, 5] x [1, 4] x [2, 7] for a full 4-cell grid.
  std::vector<Eigen::Vector3d> positions;
  for (int i = 0; i <= 1000; ++i) {
    positions.emplace_back(-3.0 + 8.0 * i / 1000, 1.0 + 3.0 * ((i * 7) % 1001) / 1000,
                           2.0 + 5.0 * ((i * 13) % 1001) / 1000);
  }
  const CoarseGrid grid = makeCoarseGrid(positions, 4);
  ASSERT_EQ(grid.nodes, Eigen::Vector3i(5, 3, 4));
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.3, 2.2, 4.9), Eigen::Vector3d(-3, 1, 2), Eigen::Vector3d(5, 4, 7)}) {
    double sum = 0.0;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const CoarseWeight& w : coarseWeights(grid, p)) {
      sum += w.weight;
      centre += w.weight * w.centre;
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    EXPECT_LT((centre - p).norm(), 1e-9);  // trilinear hats reproduce linear functions
  }
}

/// `graph` with every pose moved by `step` on its robot's grid.
PoseGraph moved(PoseGraph graph, const std::map<core::RobotId, RefineAgent>& agents,
                const CoarseStep& step) {
  for (const auto& [key, T] : graph.nodes()) {
    const auto& grid = agents.at(key.robot).coarseGrid();
    graph.setEstimate(key, applyCoarse(step, key.robot, *grid, T));
  }
  return graph;
}

TEST(CoarseShare, GradientIsTheGraphCostsDerivativeAlongACoarseMotion) {
  PoseGraph graph = splitIntoRobots(io::readPoseGraph(poseGraphPath("3d/smallGrid3D.g2o")), 3);
  const auto agents = makeAgents(graph, {});
  std::map<CoarseNode, core::Vector6d> gradient;
  for (const auto& [robot, agent] : agents) {
    for (const auto& [node, g] : agent.coarseShare(false).gradient) {
      auto [it, added] = gradient.try_emplace(node, core::Vector6d::Zero());
      it->second += g;
    }
  }
  ASSERT_FALSE(gradient.empty());
  CoarseStep direction;
  double predicted = 0.0;
  int i = 0;
  for (const auto& [node, g] : gradient) {
    core::Vector6d d;
    d << std::sin(i + 1.0), std::cos(2.0 * i), 0.3, 0.01 * std::sin(3.0 * i), 0.02, -0.01;
    direction.motion[node] = d;
    predicted += 2.0 * g.dot(d);  // cost = |r|^2
    ++i;
  }
  const double h = 1e-6;
  CoarseStep plus = direction;
  CoarseStep minus = direction;
  for (auto& [node, d] : plus.motion) d *= h;
  for (auto& [node, d] : minus.motion) d *= -h;
  const double numeric =
      (graphCost(moved(graph, agents, plus)) - graphCost(moved(graph, agents, minus))) / (2 * h);
  EXPECT_NEAR(numeric, predicted, 1e-4 * std::abs(predicted));
}

}  // namespace
}  // namespace dcl::backend
