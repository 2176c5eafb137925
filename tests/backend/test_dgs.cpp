#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/dgs.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/multi_robot_graph.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

#include "../common/keys.hpp"

namespace dcl::backend {
namespace {

using dcl::test::key;

core::RobotId robotId(int robot) {
  return core::RobotId(static_cast<std::uint8_t>(robot));
}

using dcl::test::poseGraphPath;

PoseGraph readGraph(const std::string& relative) {
  return io::readPoseGraph(poseGraphPath(relative));
}

PoseGraph distributedMapper(int robots) {
  return io::readMultiRobotGraph(
      poseGraphPath("multi_robot/distributed_mapper/example_" + std::to_string(robots) + "robots"));
}

/// Poses along a climbing spiral with roll and pitch wobble, two turns: every axis moves.
std::vector<Eigen::Isometry3d> spiral(int n) {
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < n; ++i) {
    const double a = 0.2 * i;
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(a + 1.57, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.2 * std::sin(a), Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(0.2 * std::cos(a), Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    poses.push_back(
        core::makePose(Eigen::Vector3d(10 * std::cos(a), 10 * std::sin(a), 0.3 * i), R));
  }
  return poses;
}

/// Exact odometry and loops (each pose to the one a turn earlier) on `truth`, one robot.
PoseGraph exactOneRobotGraph(const std::vector<Eigen::Isometry3d>& truth) {
  PoseGraph graph;
  const core::Matrix6d information = core::Vector6d(100, 100, 100, 400, 400, 400).asDiagonal();
  const auto relative = [&](int a, int b) { return truth[a].inverse() * truth[b]; };
  const int n = static_cast<int>(truth.size());
  for (int i = 0; i < n; ++i) graph.addNode(key(0, i), truth[i]);
  for (int i = 1; i < n; ++i) {
    graph.addFactor({key(0, i - 1), key(0, i), relative(i - 1, i), information});
  }
  for (int i = 31; i < n; i += 2) {
    graph.addFactor(
        {key(0, i - 31), key(0, i), relative(i - 31, i), information, FactorKind::intra_loop});
  }
  return graph;
}

/// Every estimate but the lowest node's moved by a random error (`metres`, `radians` per axis).
void perturb(PoseGraph& graph, unsigned seed, double metres, double radians) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  const core::PoseKey lowest = graph.nodes().begin()->first;
  for (const auto& [k, T] : graph.nodes()) {
    if (k == lowest) continue;
    core::Vector6d xi;
    for (int j = 0; j < 6; ++j) xi[j] = noise(rng) * (j < 3 ? metres : radians);
    graph.setEstimate(k, T * core::expSE3(xi));
  }
}

/// Largest |log(T_a^-1 T_b)| over the nodes of `a` (matched in node order with `b`).
double maxPoseError(const PoseGraph& a, const PoseGraph& b) {
  double worst = 0.0;
  auto it = b.nodes().begin();
  for (const auto& [k, T] : a.nodes()) {
    worst = std::max(worst, core::logSE3(T.inverse() * (it++)->second).norm());
  }
  return worst;
}

/// The optimum of `graph` from its chordal initialisation (the reference of every ratio).
double centralizedCost(PoseGraph graph) {
  chordalInitialise(graph);
  return solveCentralized(graph).final_cost;
}

/// `graph` without robot `gone`'s nodes and the factors touching them.
PoseGraph without(const PoseGraph& graph, core::RobotId gone) {
  PoseGraph out;
  for (const auto& [k, T] : graph.nodes()) {
    if (k.robot != gone) out.addNode(k, T);
  }
  for (const Factor& f : graph.factors()) {
    if (f.from.robot != gone && f.to.robot != gone) out.addFactor(f);
  }
  return out;
}

/// Runs one agent's round alone until it is done.
void runAlone(DgsAgent& agent) {
  agent.startRound({agent.robot()});
  for (int i = 0; i < 100 && agent.stage() != DgsStage::done; ++i) agent.iterate();
}

TEST(ChordalInitialise, RecoversExactPosesOfANoiseFreeGraph) {
  const PoseGraph truth = exactOneRobotGraph(spiral(90));
  PoseGraph graph = truth;
  perturb(graph, 11, 2.0, 0.8);  // far from the truth: the rotation stage needs no guess
  ASSERT_GT(maxPoseError(graph, truth), 1.0);
  chordalInitialise(graph);
  EXPECT_LT(maxPoseError(graph, truth), 1e-9);
  EXPECT_TRUE(graph.estimate(key(0, 0)).matrix() == truth.estimate(key(0, 0)).matrix());
}

TEST(ChordalInitialise, HoldsFixedNodesAndEveryComponent) {
  PoseGraph graph = exactOneRobotGraph(spiral(40));
  // A second piece, not linked to the first: its own lowest node holds it.
  const auto truth = spiral(40);
  for (int i = 0; i < 5; ++i) graph.addNode(key(1, i), truth[i]);
  for (int i = 1; i < 5; ++i) {
    graph.addFactor(
        {key(1, i - 1), key(1, i), truth[i - 1].inverse() * truth[i], core::Matrix6d::Identity()});
  }
  const PoseGraph exact = graph;
  graph.fix(key(0, 20));
  perturb(graph, 5, 0.5, 0.3);
  graph.setEstimate(key(0, 20), exact.estimate(key(0, 20)));
  const Eigen::Isometry3d first_of_piece = graph.estimate(key(1, 0));
  chordalInitialise(graph);
  EXPECT_LT(core::logSE3(exact.estimate(key(0, 0)).inverse() * graph.estimate(key(0, 0))).norm(),
            1e-9);
  EXPECT_TRUE(graph.estimate(key(1, 0)).matrix() == first_of_piece.matrix());
  const Eigen::Isometry3d T_piece = first_of_piece * exact.estimate(key(1, 0)).inverse();
  EXPECT_LT(
      core::logSE3((T_piece * exact.estimate(key(1, 4))).inverse() * graph.estimate(key(1, 4)))
          .norm(),
      1e-9);
}

TEST(SplitIntoRobots, KeepsEveryFactorAndMakesTheRightInterRobotOnes) {
  const PoseGraph graph = readGraph("3d/smallGrid3D.g2o");
  const PoseGraph split = splitIntoRobots(graph, 4);
  ASSERT_EQ(split.size(), graph.size());
  ASSERT_EQ(split.factors().size(), graph.factors().size());
  // 125 nodes: ranges [0, 31), [31, 62), [62, 93), [93, 125).
  const auto rangeOf = [](std::uint64_t i) { return i < 31 ? 0 : i < 62 ? 1 : i < 93 ? 2 : 3; };
  const std::vector<std::uint64_t> first{0, 31, 62, 93};
  std::size_t inter = 0;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    const Factor& f = graph.factors()[i];
    const Factor& g = split.factors()[i];
    const int a = rangeOf(f.from.keyframe.value());
    const int b = rangeOf(f.to.keyframe.value());
    EXPECT_EQ(g.from, key(a, static_cast<int>(f.from.keyframe.value() - first[a])));
    EXPECT_EQ(g.to, key(b, static_cast<int>(f.to.keyframe.value() - first[b])));
    EXPECT_EQ(g.kind == FactorKind::inter_loop, a != b);
    EXPECT_TRUE(g.T_from_to.matrix() == f.T_from_to.matrix());
    EXPECT_TRUE(g.information == f.information);
    inter += a != b ? 1 : 0;
  }
  EXPECT_GT(inter, 10u);
  EXPECT_TRUE(split.estimate(key(3, 31)).matrix() == graph.estimate(key(0, 124)).matrix());
  EXPECT_EQ(splitIntoRobots(graph, 1).factors().size(), graph.factors().size());
  EXPECT_THROW((void)splitIntoRobots(graph, 0), core::Error);
  EXPECT_THROW((void)splitIntoRobots(graph, 126), core::Error);
  EXPECT_THROW((void)splitIntoRobots(readGraph("3d/sphere2500.g2o"), 256), core::Error);
}

/// Three robots: a0-a1-a2, b0-b1-b2, c0-c1, inter-robot loops a1->b0, b2->a2, b1->c0, c1->a0.
PoseGraph threeRobots() {
  PoseGraph graph;
  const auto place = [](int robot, int i) { return core::makePose2d(i, 3.0 * robot, 0.1 * i); };
  const std::vector<int> sizes{3, 3, 2};
  for (int r = 0; r < 3; ++r) {
    for (int i = 0; i < sizes[r]; ++i) graph.addNode(key(r, i), place(r, i));
    for (int i = 1; i < sizes[r]; ++i) {
      graph.addFactor({key(r, i - 1), key(r, i), place(r, i - 1).inverse() * place(r, i)});
    }
  }
  const auto loop = [&](core::PoseKey a, core::PoseKey b) {
    graph.addFactor({a, b, graph.estimate(a).inverse() * graph.estimate(b),
                     core::Matrix6d::Identity(), FactorKind::inter_loop});
  };
  loop(key(0, 1), key(1, 0));
  loop(key(1, 2), key(0, 2));
  loop(key(1, 1), key(2, 0));
  loop(key(2, 1), key(0, 0));
  return graph;
}

TEST(DgsAgent, SeparatorsPerNeighbour) {
  const auto locals = partitionByRobot(threeRobots());
  ASSERT_EQ(locals.size(), 3u);
  EXPECT_EQ(locals.at(robotId(1)).size(), 3u);
  EXPECT_EQ(locals.at(robotId(1)).factors().size(), 2u + 3u);
  const DgsAgent a(robotId(0), locals.at(robotId(0)));
  const DgsAgent b(robotId(1), locals.at(robotId(1)));
  const DgsAgent c(robotId(2), locals.at(robotId(2)));
  using Keys = std::set<core::PoseKey>;
  EXPECT_EQ(b.neighbours(), (std::set<core::RobotId>{robotId(0), robotId(2)}));
  EXPECT_EQ(b.separators().at(robotId(0)), (Keys{key(1, 0), key(1, 2)}));
  EXPECT_EQ(b.separators().at(robotId(2)), (Keys{key(1, 1)}));
  EXPECT_EQ(a.separators().at(robotId(1)), (Keys{key(0, 1), key(0, 2)}));
  EXPECT_EQ(a.separators().at(robotId(2)), (Keys{key(0, 0)}));
  EXPECT_EQ(c.separators().at(robotId(0)), (Keys{key(2, 1)}));
  EXPECT_EQ(c.separators().at(robotId(1)), (Keys{key(2, 0)}));
  // The messages name exactly those separators once the sender has solved.
  DgsAgent anchor(robotId(0), locals.at(robotId(0)));
  anchor.startRound({robotId(0), robotId(1), robotId(2)});
  anchor.iterate();
  for (const DgsMessage& m : anchor.outgoing()) {
    Keys sent;
    for (const auto& [k, R] : m.rotations) sent.insert(k);
    EXPECT_EQ(sent, a.separators().at(m.to));
  }
  EXPECT_EQ(anchor.outgoing().size(), 2u);
}

TEST(DgsAgent, AloneEqualsTheCentralizedInitialisation) {
  PoseGraph graph = readGraph("3d/smallGrid3D.g2o");
  DgsAgent agent(robotId(0), graph);
  runAlone(agent);
  ASSERT_EQ(agent.stage(), DgsStage::done);
  chordalInitialise(graph);
  for (const auto& [k, T] : graph.nodes()) {
    EXPECT_TRUE(agent.estimates().at(k).matrix() == T.matrix()) << k.keyframe.value();
  }
  // One block, no neighbour: each stage's matrix is factored once.
  EXPECT_EQ(agent.factorizations(), 2u);
}

TEST(Dgs, SplitNoiseFreeGraphReachesTheTruePoses) {
  const PoseGraph truth = splitIntoRobots(exactOneRobotGraph(spiral(90)), 3);
  PoseGraph graph = truth;
  perturb(graph, 3, 1.0, 0.5);
  DgsConfig config;
  config.rotation_threshold = 1e-10;
  config.pose_threshold = 1e-10;
  const DgsSummary summary = runDgs(graph, config);
  EXPECT_LT(maxPoseError(graph, truth), 1e-7);
  EXPECT_GT(summary.iterations_rotation, 2);
  EXPECT_EQ(summary.groups, 1u);
  EXPECT_EQ(summary.aborted_rounds, 0u);
  EXPECT_EQ(summary.values_sent.size(), 3u);
}

/// DGS with the paper's defaults against the centralized optimum and the
/// centralized two-stage estimate (chordalInitialise). Bounds are the measured
/// ratios with a margin (measured: tinyGrid3D in 2 robots 1.77 and 1.13, which
/// the 0.1 threshold stops early; smallGrid3D in 4 1.445 and 1.007;
/// distributed-mapper's 4 robots 1.458 and 1.003): the two-stage estimate
/// itself lies 45 to 57 % above the optimum on these graphs.
struct RealCase {
  const char* name;
  PoseGraph (*load)();
  double optimum_ratio;    ///< DGS cost / centralized optimum at most
  double two_stage_ratio;  ///< DGS cost / centralized two-stage cost at most
};

class DgsReal : public testing::TestWithParam<RealCase> {};

TEST_P(DgsReal, CostWithinTheMeasuredBoundOfTheCentralizedOne) {
  const PoseGraph graph = GetParam().load();
  PoseGraph two_stage = graph;
  chordalInitialise(two_stage);
  const double optimum = centralizedCost(graph);
  PoseGraph dgs = graph;
  const DgsSummary summary = runDgs(dgs);
  const double cost = graphCost(dgs);
  EXPECT_LT(cost / optimum, GetParam().optimum_ratio);
  EXPECT_GE(cost, optimum * (1.0 - 1e-9));
  EXPECT_LT(cost / graphCost(two_stage), GetParam().two_stage_ratio);
  EXPECT_EQ(summary.groups, 1u);
  // Tighter thresholds close the gap to the centralized two-stage estimate.
  DgsConfig tight;
  tight.rotation_threshold = 1e-4;
  tight.pose_threshold = 1e-4;
  PoseGraph converged = graph;
  (void)runDgs(converged, tight);
  EXPECT_NEAR(graphCost(converged) / graphCost(two_stage), 1.0, 1e-4);
}

INSTANTIATE_TEST_SUITE_P(
    Graphs, DgsReal,
    testing::Values(
        RealCase{"tinyGrid3D_2", [] { return splitIntoRobots(readGraph("3d/tinyGrid3D.g2o"), 2); },
                 1.85, 1.2},
        RealCase{"smallGrid3D_4",
                 [] { return splitIntoRobots(readGraph("3d/smallGrid3D.g2o"), 4); }, 1.5, 1.02},
        RealCase{"distributed_mapper_4", [] { return distributedMapper(4); }, 1.5, 1.01}),
    [](const testing::TestParamInfo<RealCase>& info) { return std::string(info.param.name); });

TEST(Dgs, OrderIsGreedyByEdgesFromTheAnchor) {
  PoseGraph graph;
  for (int r = 0; r < 5; ++r) graph.addNode(key(r, 0), Eigen::Isometry3d::Identity());
  const auto loops = [&](int a, int b, int count) {
    for (int i = 0; i < count; ++i) {
      graph.addFactor({key(a, 0), key(b, 0), Eigen::Isometry3d::Identity(),
                       core::Matrix6d::Identity(), FactorKind::inter_loop});
    }
  };
  loops(0, 1, 1);
  loops(2, 0, 3);
  loops(2, 3, 5);
  loops(3, 1, 1);
  const std::set<core::RobotId> group{robotId(0), robotId(1), robotId(2), robotId(3)};
  EXPECT_EQ(optimisationOrder(graph, group),
            (std::vector<core::RobotId>{robotId(0), robotId(2), robotId(3), robotId(1)}));
  const auto groups = connectedGroups(graph);
  ASSERT_EQ(groups.size(), 2u);
  EXPECT_EQ(groups[0], group);
  EXPECT_EQ(groups[1], std::set<core::RobotId>{robotId(4)});
  EXPECT_EQ(connectedGroups(graph, {robotId(2)}).size(), 2u);  // 0-1-3 still linked
}

TEST(DgsAgent, DoesNotUseAnUninitialisedNeighbour) {
  const PoseGraph graph = splitIntoRobots(exactOneRobotGraph(spiral(60)), 2);
  const auto locals = partitionByRobot(graph);
  const std::set<core::RobotId> group{robotId(0), robotId(1)};
  const auto run = [&](bool garbage) -> std::map<core::PoseKey, Eigen::Matrix3d> {
    DgsAgent a(robotId(0), locals.at(robotId(0)));
    DgsAgent b(robotId(1), locals.at(robotId(1)));
    a.startRound(group, 7);
    b.startRound(group, 7);
    // b's turn first: no anchor, no initialised neighbour: it waits.
    b.iterate();
    EXPECT_FALSE(b.initialised());
    EXPECT_EQ(b.stage(), DgsStage::rotation);
    EXPECT_EQ(b.outgoing().size(), 1u);
    EXPECT_TRUE(b.outgoing().at(0).rotations.empty());
    if (garbage) {  // a neighbour that has not solved yet says so; its values are not used
      DgsMessage m;
      m.from = robotId(0);
      m.to = robotId(1);
      m.round = 7;
      m.iteration = 0;
      for (const core::PoseKey& k : a.separators().at(robotId(1))) {
        m.rotations.emplace(k, Eigen::Matrix3d::Constant(0.5));
      }
      b.receive(m);
      b.iterate();
      EXPECT_FALSE(b.initialised());
    }
    a.iterate();
    EXPECT_TRUE(a.initialised());
    for (const DgsMessage& m : a.outgoing()) b.receive(m);
    b.iterate();
    EXPECT_TRUE(b.initialised());
    return b.outgoing().at(0).rotations;
  };
  const auto clean = run(false);
  const auto after_garbage = run(true);
  ASSERT_EQ(clean.size(), after_garbage.size());
  for (const auto& [k, R] : clean) EXPECT_TRUE(after_garbage.at(k) == R);
}

/// The agents of a spiral split in two, in round 3 together.
std::pair<DgsAgent, DgsAgent> twoRobotRound() {
  const auto locals = partitionByRobot(splitIntoRobots(exactOneRobotGraph(spiral(60)), 2));
  const std::set<core::RobotId> group{robotId(0), robotId(1)};
  std::pair<DgsAgent, DgsAgent> agents{DgsAgent(robotId(0), locals.at(robotId(0))),
                                       DgsAgent(robotId(1), locals.at(robotId(1)))};
  agents.first.startRound(group, 3);
  agents.second.startRound(group, 3);
  return agents;
}

TEST(DgsAgent, AMemberInTheNextStageHasLeftThisOne) {
  // a and b step in turn; every message b sends while it leaves the rotation
  // stage is lost. b's first pose-stage message tells a that b has left: a
  // follows at its next step instead of stepping rotations alone to the cap.
  auto [a, b] = twoRobotRound();
  bool lost = false;
  for (int turn = 0; turn < 200 && b.stage() == DgsStage::rotation; ++turn) {
    a.iterate();
    for (const DgsMessage& m : a.outgoing()) b.receive(m);
    b.iterate();
    if (b.stage() == DgsStage::rotation) {
      for (const DgsMessage& m : b.outgoing()) a.receive(m);
    } else {
      lost = true;  // b's message saying it left is dropped
    }
  }
  ASSERT_TRUE(lost);
  ASSERT_EQ(b.stage(), DgsStage::pose);
  // b saw the group converged after a's step; a, stepping first, has not yet.
  ASSERT_EQ(a.stage(), DgsStage::rotation);
  const int before = a.stageIterations(DgsStage::rotation);
  b.iterate();
  for (const DgsMessage& m : b.outgoing()) a.receive(m);
  a.iterate();
  EXPECT_EQ(a.stage(), DgsStage::pose);
  EXPECT_EQ(a.stageIterations(DgsStage::rotation), before + 1);
  // Both then finish the round as usual.
  for (int turn = 0; turn < 400 && (a.stage() != DgsStage::done || b.stage() != DgsStage::done);
       ++turn) {
    a.iterate();
    for (const DgsMessage& m : a.outgoing()) b.receive(m);
    b.iterate();
    for (const DgsMessage& m : b.outgoing()) a.receive(m);
  }
  EXPECT_EQ(a.stage(), DgsStage::done);
  EXPECT_EQ(b.stage(), DgsStage::done);
  EXPECT_LT(a.stageIterations(DgsStage::rotation), 100);
}

TEST(DgsAgent, ADoneMemberAnswersOneStillInItsLastStage) {
  // b finishes the round and every message it sends as it does is lost: a,
  // still in the pose stage, would step alone to the cap. Its next message
  // makes b send its last pose-stage message again, which says b has left.
  auto [a, b] = twoRobotRound();
  std::vector<DgsMessage> lost;
  for (int turn = 0; turn < 400 && b.stage() != DgsStage::done; ++turn) {
    a.iterate();
    for (const DgsMessage& m : a.outgoing()) b.receive(m);
    EXPECT_TRUE(b.replies().empty());  // a is not behind b
    b.iterate();
    if (b.stage() != DgsStage::done) {
      for (const DgsMessage& m : b.outgoing()) a.receive(m);
    } else {
      lost = b.outgoing();
    }
  }
  ASSERT_EQ(b.stage(), DgsStage::done);
  ASSERT_EQ(lost.size(), 1U);
  ASSERT_EQ(a.stage(), DgsStage::pose);
  a.iterate();
  ASSERT_EQ(a.stage(), DgsStage::pose);  // it has not seen b leave
  for (const DgsMessage& m : a.outgoing()) b.receive(m);
  const std::vector<DgsMessage> replies = b.replies();
  ASSERT_EQ(replies.size(), 1U);
  EXPECT_EQ(replies[0].to, robotId(0));
  EXPECT_EQ(replies[0].iteration, lost[0].iteration);
  EXPECT_TRUE(replies[0].progress.at(robotId(1)).finished);
  EXPECT_TRUE(b.replies().empty());  // handed over once
  a.receive(replies[0]);
  a.iterate();
  EXPECT_EQ(a.stage(), DgsStage::done);
  EXPECT_LT(a.stageIterations(DgsStage::pose), 100);
}

TEST(DgsAgent, RejectsMalformedMessagesAndIgnoresOtherRounds) {
  const auto locals = partitionByRobot(splitIntoRobots(exactOneRobotGraph(spiral(60)), 2));
  DgsAgent b(robotId(1), locals.at(robotId(1)));
  b.startRound({robotId(0), robotId(1)}, 3);
  const core::PoseKey separator =
      *DgsAgent(robotId(0), locals.at(robotId(0))).separators().at(robotId(1)).begin();
  DgsMessage m;
  m.from = robotId(0);
  m.to = robotId(1);
  m.round = 3;
  m.iteration = 1;
  m.initialised = true;
  m.rotations.emplace(separator, Eigen::Matrix3d::Constant(std::nan("")));
  b.receive(m);
  EXPECT_EQ(b.rejectedMessages(), 1u);
  m.rotations.clear();
  m.stage = DgsStage::pose;
  Eigen::Isometry3d skewed = Eigen::Isometry3d::Identity();
  skewed.linear()(0, 1) = 0.3;
  m.poses.emplace(separator, skewed);
  b.receive(m);
  EXPECT_EQ(b.rejectedMessages(), 2u);
  m.poses.clear();
  m.progress[robotId(0)] = DgsProgress{2, 5, false};  // converged since after its last step
  b.receive(m);
  EXPECT_EQ(b.rejectedMessages(), 3u);
  m.progress.clear();
  m.stage = DgsStage::rotation;
  m.rotations.emplace(separator, Eigen::Matrix3d::Identity());
  m.round = 4;  // another round: ignored, not malformed
  b.receive(m);
  EXPECT_EQ(b.rejectedMessages(), 3u);
  b.iterate();  // still no initialised neighbour it may use
  EXPECT_FALSE(b.initialised());
}

TEST(DgsAgent, AbortKeepsTheLastFinishedRoundsEstimates) {
  const auto locals = partitionByRobot(splitIntoRobots(readGraph("3d/smallGrid3D.g2o"), 2));
  DgsAgent a(robotId(0), locals.at(robotId(0)));
  DgsAgent b(robotId(1), locals.at(robotId(1)));
  const auto before = a.estimates();
  const std::set<core::RobotId> group{robotId(0), robotId(1)};
  const auto sweep = [&] {
    a.iterate();
    for (const DgsMessage& m : a.outgoing()) b.receive(m);
    b.iterate();
    for (const DgsMessage& m : b.outgoing()) a.receive(m);
  };
  a.startRound(group);
  b.startRound(group);
  for (int i = 0; i < 3; ++i) sweep();
  a.abortRound();
  EXPECT_EQ(a.stage(), DgsStage::idle);
  for (const auto& [k, T] : before) EXPECT_TRUE(a.estimates().at(k).matrix() == T.matrix());
  a.iterate();  // idle: nothing to do
  EXPECT_TRUE(a.outgoing().empty());
  // The round is retried and finishes; b drops what is left of the old round.
  b.abortRound();
  const std::size_t factored_before = a.factorizations();
  a.startRound(group);
  b.startRound(group);
  for (int i = 0; i < 200 && (a.stage() != DgsStage::done || b.stage() != DgsStage::done); ++i) {
    sweep();
  }
  EXPECT_EQ(a.stage(), DgsStage::done);
  EXPECT_EQ(b.stage(), DgsStage::done);
  EXPECT_FALSE(a.estimates().at(key(0, 30)).matrix() == before.at(key(0, 30)).matrix());
  // Per stage the anchor's block matrix is factored when the stage starts and
  // once more when the neighbour first joins, not at every step.
  EXPECT_EQ(a.factorizations() - factored_before, 2u * 2u);
  EXPECT_GT(a.stageIterations(DgsStage::rotation) + a.stageIterations(DgsStage::pose), 8);
}

TEST(Dgs, ARobotVanishingMidRoundLeavesTheRestConsistent) {
  // smallGrid3D in 3 robots: without robot 1, robots 0 and 2 are not linked.
  const PoseGraph graph = splitIntoRobots(readGraph("3d/smallGrid3D.g2o"), 3);
  ASSERT_EQ(connectedGroups(graph, {robotId(1)}).size(), 2u);
  PoseGraph vanished = graph;
  const DgsSummary summary = runDgs(vanished, {}, {robotId(1)}, 3);
  EXPECT_EQ(summary.aborted_rounds, 1u);
  EXPECT_EQ(summary.groups, 2u);
  // The silent robot keeps its estimates; the rest end exactly where a round
  // among themselves ends: a consistent estimate, not a half-finished one.
  PoseGraph reference = without(graph, robotId(1));
  (void)runDgs(reference);
  for (const auto& [k, T] : vanished.nodes()) {
    const Eigen::Isometry3d& expected =
        k.robot == robotId(1) ? graph.estimate(k) : reference.estimate(k);
    EXPECT_TRUE(T.matrix() == expected.matrix())
        << int(k.robot.value()) << " " << k.keyframe.value();
  }
  // And that estimate is a good one for the graph left.
  EXPECT_LT(graphCost(reference) / centralizedCost(reference), 1.6);
}

TEST(Dgs, VanishingBeforeTheFirstStepAbortsAndRetries) {
  const PoseGraph graph = distributedMapper(4);
  PoseGraph vanished = graph;
  const DgsSummary summary = runDgs(vanished, {}, {robotId(0)}, 0);
  EXPECT_EQ(summary.aborted_rounds, 1u);
  PoseGraph reference = without(graph, robotId(0));
  (void)runDgs(reference);
  for (const auto& [k, T] : reference.nodes()) {
    EXPECT_TRUE(vanished.estimate(k).matrix() == T.matrix());
  }
  EXPECT_TRUE(vanished.estimate(key(0, 0)).matrix() == graph.estimate(key(0, 0)).matrix());
}

/// Every agent of `group` iterated in Algorithm 1's order over `graph`, its
/// messages delivered at once, until all are done (at most `sweeps`).
void sweepUntilDone(std::map<core::RobotId, DgsAgent>& agents, const PoseGraph& graph,
                    const std::set<core::RobotId>& group, int sweeps) {
  const std::vector<core::RobotId> order = optimisationOrder(graph, group);
  const auto done = [&] {
    return std::all_of(group.begin(), group.end(),
                       [&](core::RobotId r) { return agents.at(r).stage() == DgsStage::done; });
  };
  for (int sweep = 0; sweep < sweeps && !done(); ++sweep) {
    for (const core::RobotId r : order) {
      agents.at(r).iterate();
      for (const DgsMessage& m : agents.at(r).outgoing()) agents.at(m.to).receive(m);
    }
  }
}

TEST(DgsAgent, HeldSeparatorsOfAnAbsentRobotAnchorTheRound) {
  // distributed-mapper's 4 robots; robot 0 is gone, its poses held where the
  // whole graph's optimum puts them. Robots 1-3 start 3 m and 0.3 rad away
  // from there (their frame drifted since). They hold their loops to robot 0:
  // DGS among them reaches the centralized two-stage estimate of the graph
  // with robot 0 fixed there, the lowest of them pinning nothing (a pin would
  // pull against the held loops).
  const core::RobotId gone = robotId(0);
  PoseGraph optimum = distributedMapper(4);
  chordalInitialise(optimum);
  (void)solveCentralized(optimum);
  PoseGraph graph = optimum;
  const Eigen::Isometry3d drift =
      core::makePose(Eigen::Vector3d(3.0, -1.5, 0.5),
                     Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  for (const auto& [k, T] : optimum.nodes())
    if (k.robot != gone) graph.setEstimate(k, drift * T);
  PoseGraph reference = graph;  // robot 0 fixed at the optimum, the rest as given
  for (const auto& [k, T] : optimum.nodes()) {
    if (k.robot != gone) continue;
    reference.setEstimate(k, T);
    reference.fix(k);
  }
  chordalInitialise(reference);

  const std::set<core::RobotId> group{robotId(1), robotId(2), robotId(3)};
  std::map<core::RobotId, DgsAgent> agents;
  std::size_t held = 0;
  DgsConfig tight;
  tight.rotation_threshold = 1e-8;
  tight.pose_threshold = 1e-8;
  for (auto [robot, local] : partitionByRobot(graph)) {
    if (robot == gone) continue;
    for (const Factor& f : graph.factors()) {
      const bool touches = f.from.robot == robot || f.to.robot == robot;
      const core::PoseKey& other = f.from.robot == robot ? f.to : f.from;
      if (!touches || other.robot != gone) continue;
      local.addNode(other, optimum.estimate(other));
      local.fix(other);
      ++held;
    }
    agents.emplace(robot, DgsAgent(robot, std::move(local), tight));
    agents.at(robot).startRound(group, 7);
  }
  ASSERT_GT(held, 0u);
  sweepUntilDone(agents, graph, group, 2000);
  double worst = 0.0;
  for (const core::RobotId r : group) {
    ASSERT_EQ(agents.at(r).stage(), DgsStage::done) << core::robotName(r);
    for (const auto& [k, T] : agents.at(r).estimates())
      worst = std::max(worst, core::logSE3(reference.estimate(k).inverse() * T).norm());
  }
  EXPECT_LT(worst, 1e-4);
  // Without robot 0 the same group solves its own loops only, pinned at
  // robot 1's first pose: its map stays drifted from robot 0's.
  PoseGraph alone = without(graph, gone);
  (void)runDgs(alone, tight);
  PoseGraph with_held = optimum;
  PoseGraph with_alone = optimum;
  for (const core::RobotId r : group) {
    for (const auto& [k, T] : agents.at(r).estimates()) {
      with_held.setEstimate(k, T);
      with_alone.setEstimate(k, alone.estimate(k));
    }
  }
  std::printf("held: cost %.6g, alone: %.6g, optimum %.6g\n", graphCost(with_held),
              graphCost(with_alone), graphCost(optimum));
  EXPECT_LT(graphCost(with_held), 0.2 * graphCost(with_alone));
}

TEST(Dgs, RobotsWithoutAcceptedLoopsOptimiseAlone) {
  PoseGraph graph;
  const PoseGraph split = splitIntoRobots(readGraph("3d/smallGrid3D.g2o"), 2);
  for (const auto& [k, T] : split.nodes()) graph.addNode(k, T);
  for (const Factor& f : split.factors()) {
    if (f.kind != FactorKind::inter_loop) graph.addFactor(f);
  }
  PoseGraph dgs = graph;
  const DgsSummary summary = runDgs(dgs);
  EXPECT_EQ(summary.groups, 2u);
  EXPECT_EQ(summary.messages, 0u);
  // Each robot holds its own gauge: the same as the centralized initialisation,
  // which holds each piece by its lowest node.
  chordalInitialise(graph);
  EXPECT_LT(maxPoseError(dgs, graph), 1e-9);
  EXPECT_TRUE(dgs.estimate(key(1, 0)).matrix() == split.estimate(key(1, 0)).matrix());
}

TEST(Dgs, IsDeterministic) {
  const PoseGraph graph = distributedMapper(9);
  PoseGraph first = graph;
  PoseGraph second = graph;
  const DgsSummary a = runDgs(first);
  const DgsSummary b = runDgs(second);
  EXPECT_EQ(a.iterations_rotation, b.iterations_rotation);
  EXPECT_EQ(a.iterations_pose, b.iterations_pose);
  EXPECT_EQ(a.messages, b.messages);
  EXPECT_EQ(a.values_sent, b.values_sent);
  for (const auto& [k, T] : first.nodes()) EXPECT_TRUE(second.estimate(k).matrix() == T.matrix());
}

TEST(Dgs, OverRelaxationReachesTheSameEstimate) {
  const PoseGraph graph = splitIntoRobots(readGraph("3d/smallGrid3D.g2o"), 3);
  DgsConfig plain;
  plain.rotation_threshold = plain.pose_threshold = 1e-6;
  DgsConfig relaxed = plain;
  relaxed.gamma = 1.3;
  PoseGraph a = graph;
  PoseGraph b = graph;
  (void)runDgs(a, plain);
  (void)runDgs(b, relaxed);
  EXPECT_LT(maxPoseError(a, b), 1e-4);
  EXPECT_NEAR(graphCost(a), graphCost(b), 1e-6 * graphCost(a));
}

TEST(Dgs, RejectsABadConfiguration) {
  PoseGraph graph = distributedMapper(2);
  DgsConfig config;
  config.gamma = 2.5;
  try {
    (void)runDgs(graph, config);
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("gamma"), std::string::npos);
  }
  config = {};
  config.max_pose_iterations = 0;
  EXPECT_THROW((void)runDgs(graph, config), core::Error);
  PoseGraph bad = graph;
  Factor f = bad.factors().front();
  f.information(0, 0) = std::numeric_limits<double>::infinity();
  bad.addFactor(f);
  EXPECT_THROW((void)runDgs(bad), core::Error);
}

}  // namespace
}  // namespace dcl::backend
