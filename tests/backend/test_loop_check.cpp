// The second line of defence after PCM: loops the joint solution cannot explain.

#include <cmath>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/loop_check.hpp>
#include <dcl/backend/pcm.hpp>
#include <dcl/backend/pcm_evaluation.hpp>
#include <dcl/io/multi_robot_graph.hpp>

#include "../common/keys.hpp"
#include "loop_ids.hpp"

namespace dcl::backend {
namespace {

using dcl::test::key;

core::Matrix6d information(double sigma_translation, double sigma_rotation) {
  const double t = 1.0 / (sigma_translation * sigma_translation);
  const double r = 1.0 / (sigma_rotation * sigma_rotation);
  return core::Vector6d(t, t, t, r, r, r).asDiagonal();
}

/// Three robots driving one 60 m loop of road, each its own stretch of it,
/// each stretch overlapping the next by a few keyframes: loops a-c and b-c
/// are true. Robots a and b never meet, but the road repeats a block 48 m
/// on, and a few of a's keyframes match b's there: the a-b loops are wrong
/// by 48 m, and agree with each other.
struct ThreeRobots {
  static constexpr double kOdomT = 0.05, kOdomR = 0.005, kLoopT = 0.05, kLoopR = 0.005;
  static constexpr int kKeyframes = 40;
  std::vector<std::vector<Eigen::Isometry3d>> truth{3};
  PoseGraph graph;
  std::vector<Factor> true_loops;
  std::vector<Factor> wrong_loops;
  std::mt19937 rng;

  /// The pose `s` m along the road, a circle of 60 m circumference.
  static Eigen::Isometry3d onRoad(double s) {
    constexpr double kRadius = 60.0 / (2.0 * M_PI);
    const double angle = s / kRadius;
    return core::makePose(Eigen::Vector3d(kRadius * std::cos(angle), kRadius * std::sin(angle), 0),
                          Eigen::AngleAxisd(angle + M_PI / 2, Eigen::Vector3d::UnitZ()).matrix());
  }

  core::Vector6d noise(double t, double r) {
    std::normal_distribution<double> n(0.0, 1.0);
    core::Vector6d xi;
    for (int k = 0; k < 6; ++k) xi[k] = n(rng) * (k < 3 ? t : r);
    return xi;
  }

  Factor loop(int r1, int i, int r2, int j, const Eigen::Isometry3d& shift) {
    const Eigen::Isometry3d T =
        truth[r1][i].inverse() * shift * truth[r2][j] * core::expSE3(noise(kLoopT / 3, kLoopR / 3));
    return {key(r1, i), key(r2, j), T, information(kLoopT, kLoopR), FactorKind::inter_loop};
  }

  ThreeRobots(bool with_wrong_loops, unsigned seed) : rng(seed) {
    const double starts[3] = {0.0, 25.0, 12.5};  // c's stretch overlaps a's and b's
    for (int r = 0; r < 3; ++r) {
      for (int i = 0; i < kKeyframes; ++i) truth[r].push_back(onRoad(starts[r] + 0.5 * i));
      Eigen::Isometry3d odometry = truth[r][0];
      graph.addNode(key(r, 0), odometry);
      for (int i = 1; i < kKeyframes; ++i) {
        const Eigen::Isometry3d step =
            truth[r][i - 1].inverse() * truth[r][i] * core::expSE3(noise(kOdomT / 3, kOdomR / 3));
        odometry = odometry * step;
        graph.addNode(key(r, i), odometry);
        graph.addFactor(
            {key(r, i - 1), key(r, i), step, information(kOdomT, kOdomR), FactorKind::odometry});
      }
    }
    // a-c: a's keyframes 25-39 (12.5-19.5 m) are c's 0-14; b-c: c's 25-39 (25-32 m) are b's 0-14.
    for (int i = 25; i < 40; i += 3)
      true_loops.push_back(loop(0, i, 2, i - 25, Eigen::Isometry3d::Identity()));
    for (int j = 25; j < 40; j += 3)
      true_loops.push_back(loop(1, j - 25, 2, j, Eigen::Isometry3d::Identity()));
    if (with_wrong_loops) {
      const Eigen::Isometry3d shift = onRoad(0.0).inverse() * onRoad(48.0);
      for (int i = 4; i < 7; ++i) wrong_loops.push_back(loop(0, i, 1, i + 10, shift));
    }
    for (const Factor& f : true_loops) graph.addFactor(f);
    for (const Factor& f : wrong_loops) graph.addFactor(f);
  }
};

using dcl::test::loopIdsOf;

std::vector<Factor> interRobot(const PoseGraph& graph) {
  std::vector<Factor> loops;
  for (const Factor& f : graph.factors())
    if (f.from.robot != f.to.robot) loops.push_back(f);
  return loops;
}

SolverConfig chordal() {
  SolverConfig solver;
  solver.initialisation = "chordal";
  return solver;
}

// Every variant of the measurements' noise (five seeds) must give the same decision.
class LoopCheckSeeds : public ::testing::TestWithParam<unsigned> {};

TEST_P(LoopCheckSeeds, AConsistentWrongClusterIsWithdrawnThroughAThirdRobot) {
  ThreeRobots s(true, GetParam());
  // PCM between a and b alone keeps the wrong cluster: nothing of the pair refutes it.
  PcmConfig published;
  published.min_loops = 1;
  PcmResult pcm = runPcm(s.graph, published);
  for (const PcmPairResult& pair : pcm.pairs) {
    if (pair.robot_a == core::RobotId(0) && pair.robot_b == core::RobotId(1)) {
      EXPECT_EQ(loopIdsOf(pair.decision.accepted), loopIdsOf(s.wrong_loops));
    }
  }
  PoseGraph graph = s.graph;
  const std::vector<LoopId> withdrawn = withdrawUnexplained(graph, {}, chordal());
  EXPECT_EQ(std::set<LoopId>(withdrawn.begin(), withdrawn.end()), loopIdsOf(s.wrong_loops));
  EXPECT_EQ(loopIdsOf(interRobot(graph)), loopIdsOf(s.true_loops));
  // And the graph left is solved: every robot where the truth has it.
  for (int r = 0; r < 3; ++r) {
    const Eigen::Isometry3d T0 = graph.estimate(key(0, 0)).inverse() * graph.estimate(key(r, 20));
    const Eigen::Isometry3d truth = s.truth[0][0].inverse() * s.truth[r][20];
    EXPECT_LT((T0.translation() - truth.translation()).norm(), 0.5) << "robot " << r;
  }
}

TEST_P(LoopCheckSeeds, TrueLoopsAreAllExplained) {
  ThreeRobots s(false, GetParam());
  PoseGraph graph = s.graph;
  EXPECT_TRUE(withdrawUnexplained(graph, {}, chordal()).empty());
  EXPECT_EQ(loopIdsOf(interRobot(graph)), loopIdsOf(s.true_loops));
}

INSTANTIATE_TEST_SUITE_P(Noise, LoopCheckSeeds, ::testing::Values(1u, 2u, 3u, 4u, 5u));

TEST(LoopCheck, TheWorstPairIsJudgedAloneAndOnlyBeyondTheThreshold) {
  const auto id = [](int r1, int i, int r2, int j) { return LoopId{key(r1, i), key(r2, j)}; };
  const std::vector<LoopResidual> residuals{{id(0, 1, 1, 1), 5e4},
                                            {id(0, 2, 1, 2), 3e4},
                                            {id(0, 3, 1, 3), 20.0},
                                            {id(0, 5, 2, 1), 9e3},
                                            {id(1, 4, 2, 2), 40.0}};
  const std::optional<Unexplained> worst = worstUnexplained(residuals);
  ASSERT_TRUE(worst.has_value());
  EXPECT_EQ(worst->robots, std::make_pair(core::RobotId(0), core::RobotId(1)));
  EXPECT_EQ(worst->loops, (std::vector<LoopId>{id(0, 1, 1, 1), id(0, 2, 1, 2)}));
  EXPECT_DOUBLE_EQ(worst->worst_chi2, 5e4);
  EXPECT_FALSE(worstUnexplained({{id(0, 1, 1, 1), 99.0}}).has_value());
  LoopCheckConfig off;
  off.enabled = false;
  EXPECT_FALSE(worstUnexplained(residuals, off).has_value());
}

// On the real graphs with outlier loops, after PCM: the check must not take
// a true loop (precision stays 1, recall PCM's).
struct RealGraph {
  std::string graph;
  std::string reference;
};

class LoopCheckOnRealGraphs : public ::testing::TestWithParam<RealGraph> {};

TEST_P(LoopCheckOnRealGraphs, KeepsEveryTrueLoopPcmKept) {
  const std::string root = std::string(DCL_DATA_DIR) + "/pose_graphs/multi_robot_outliers/";
  const PoseGraph graph = io::readMultiRobotGraph(root + GetParam().graph);
  const std::set<LoopId> reference = io::readReferenceLoops(root + GetParam().reference, graph);
  PcmConfig published;
  published.min_loops = 1;
  PcmResult result = runPcm(graph, published);
  const LoopScore pcm = scoreLoops(result, reference);
  const std::size_t withdrawn = checkKeptLoops(graph, result);
  const LoopScore checked = scoreLoops(result, reference);
  std::printf("%s: PCM precision %.3f recall %.3f; after the check %.3f / %.3f (%zu withdrawn)\n",
              GetParam().graph.c_str(), pcm.precision, pcm.recall, checked.precision,
              checked.recall, withdrawn);
  EXPECT_GE(checked.precision, pcm.precision);
  EXPECT_GE(checked.recall, pcm.recall);
}

INSTANTIATE_TEST_SUITE_P(
    Outliers, LoopCheckOnRealGraphs,
    ::testing::Values(
        RealGraph{"mixrobust_real2d_split/CSAIL/spilt",
                  "mixrobust_real2d_split/CSAIL/spilt/fullgraph_without_outliers.g2o"},
        RealGraph{"mixrobust_real2d_split/INTEL/spilt",
                  "mixrobust_real2d_split/INTEL/spilt/fullgraph_without_outliers.g2o"},
        RealGraph{"mixrobust_real2d_split/city10000/spilt_part",
                  "mixrobust_real2d_split/city10000/spilt_part/fullgraph.g2o"},
        RealGraph{"mixrobust_real2d_split/city10000/spilt_part_spoiled",
                  "mixrobust_real2d_split/city10000/spilt_part/fullgraph.g2o"},
        RealGraph{"mixrobust_real2d_split/CSAIL/spilt_190random",
                  "mixrobust_real2d_split/CSAIL/spilt_190random/fullgraph_without_outliers.g2o"},
        RealGraph{"mixrobust_real2d_split/INTEL/spilt_5_6_random",
                  "mixrobust_real2d_split/INTEL/spilt_5_6_random/fullgraph_without_outliers.g2o"},
        RealGraph{
            "mixrobust_real2d_split/INTEL/spilt_5_6_spoiled",
            "mixrobust_real2d_split/INTEL/spilt_5_6_spoiled/fullgraph_without_outliers.g2o"}));

}  // namespace
}  // namespace dcl::backend
