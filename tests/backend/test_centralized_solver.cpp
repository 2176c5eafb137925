#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

#include "../common/keys.hpp"

namespace dcl::backend {
namespace {

core::PoseKey key(int keyframe) {
  return {core::RobotId(0), core::KeyframeId(static_cast<std::uint64_t>(keyframe))};
}

using dcl::test::poseGraphPath;

/// Poses along a climbing helix with roll and pitch wobble: every axis moves.
std::vector<Eigen::Isometry3d> helix(int n) {
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < n; ++i) {
    const double a = 0.25 * i;
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(a + 1.57, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.1 * std::sin(a), Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(0.1 * std::cos(a), Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    poses.push_back(
        core::makePose(Eigen::Vector3d(10 * std::cos(a), 10 * std::sin(a), 0.2 * i), R));
  }
  return poses;
}

/// A graph of exact odometry and loops (each pose to the one a turn earlier) on `truth`.
PoseGraph exactGraph(const std::vector<Eigen::Isometry3d>& truth) {
  PoseGraph graph;
  const core::Matrix6d information = core::Vector6d(100, 100, 100, 1000, 1000, 1000).asDiagonal();
  const auto relative = [&](int a, int b) { return truth[a].inverse() * truth[b]; };
  const int n = static_cast<int>(truth.size());
  for (int i = 0; i < n; ++i) graph.addNode(key(i), truth[i]);
  for (int i = 1; i < n; ++i) {
    graph.addFactor({key(i - 1), key(i), relative(i - 1, i), information, FactorKind::odometry});
  }
  for (int i = 25; i < n; i += 3) {
    graph.addFactor(
        {key(i - 25), key(i), relative(i - 25, i), information, FactorKind::intra_loop});
  }
  return graph;
}

/// Every estimate but the lowest moved by a random error (about 0.3 m and 0.1 rad).
void perturb(PoseGraph& graph, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (const auto& [k, T] : graph.nodes()) {
    if (k == key(0)) continue;
    core::Vector6d xi;
    for (int j = 0; j < 6; ++j) xi[j] = noise(rng) * (j < 3 ? 0.3 : 0.1);
    graph.setEstimate(k, T * core::expSE3(xi));
  }
}

double maxPoseError(const PoseGraph& graph, const std::vector<Eigen::Isometry3d>& truth) {
  double worst = 0.0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const auto& T = graph.estimate(key(static_cast<int>(i)));
    worst = std::max(worst, core::logSE3(truth[i].inverse() * T).norm());
  }
  return worst;
}

TEST(CentralizedSolver, RecoversExactPosesOfAPerturbedConsistentGraph) {
  const auto truth = helix(80);
  PoseGraph graph = exactGraph(truth);
  perturb(graph, 7);
  const SolverSummary summary = solveCentralized(graph);
  EXPECT_GT(summary.initial_cost, 1e4);
  EXPECT_LT(summary.final_cost, 1e-12);
  EXPECT_TRUE(summary.converged) << summary.message;
  EXPECT_LT(maxPoseError(graph, truth), 1e-6);
  EXPECT_EQ(summary.factors, graph.factors().size());
}

TEST(CentralizedSolver, FixedNodeStaysFixedAndSetsTheGauge) {
  const auto truth = helix(40);
  PoseGraph graph = exactGraph(truth);
  // Shift the whole graph and hold node 10 at a shifted pose: the solution is the truth
  // moved rigidly so that node 10 lands there.
  const Eigen::Isometry3d T_shift =
      core::expSE3((core::Vector6d() << 1, -2, 3, 0.1, 0.2, -0.3).finished());
  const Eigen::Isometry3d T_fixed = T_shift * truth[10];
  perturb(graph, 3);
  graph.setEstimate(key(10), T_fixed);
  graph.fix(key(10));
  (void)solveCentralized(graph);
  EXPECT_TRUE(graph.estimate(key(10)).matrix() == T_fixed.matrix());  // bit for bit
  for (int i = 0; i < 40; ++i) {
    EXPECT_LT(core::logSE3((T_shift * truth[i]).inverse() * graph.estimate(key(i))).norm(), 1e-6);
  }
}

TEST(CentralizedSolver, LowestNodeIsFixedUnlessToldOtherwise) {
  PoseGraph graph = exactGraph(helix(30));
  perturb(graph, 5);
  const Eigen::Isometry3d T_first = core::makePose2d(5, 5, 1.0);
  graph.setEstimate(key(0), T_first);
  (void)solveCentralized(graph);
  EXPECT_TRUE(graph.estimate(key(0)).matrix() == T_first.matrix());
}

TEST(CentralizedSolver, SkipsFactorsToMissingNodesAndRejectsUnknownLoss) {
  PoseGraph graph = exactGraph(helix(10));
  graph.addFactor({key(3), key(99), Eigen::Isometry3d::Identity(), core::Matrix6d::Identity()});
  const SolverSummary summary = solveCentralized(graph);
  EXPECT_EQ(summary.skipped_factors, 1u);
  SolverConfig config;
  config.loop_loss = "tukey";
  EXPECT_THROW((void)solveCentralized(graph, config), core::Error);
}

TEST(CentralizedSolver, RobustLossLimitsAWrongLoop) {
  const auto truth = helix(80);
  PoseGraph plain = exactGraph(truth);
  // A wrong loop: node 70 claimed 5 m away from where node 5 sees it.
  const Eigen::Isometry3d wrong = truth[5].inverse() * truth[70] * core::makePose2d(5.0, 0.0, 0.5);
  plain.addFactor(
      {key(5), key(70), wrong, core::Matrix6d::Identity() * 100, FactorKind::intra_loop});
  PoseGraph robust = plain;
  (void)solveCentralized(plain);
  SolverConfig config;
  config.loop_loss = "cauchy";
  config.loss_scale = 1.0;
  (void)solveCentralized(robust, config);
  EXPECT_GT(maxPoseError(plain, truth), 0.1);
  EXPECT_LT(maxPoseError(robust, truth), 0.5 * maxPoseError(plain, truth));
}

/// Solves a benchmark from its file's initial estimate; returns the summary.
SolverSummary solveBenchmark(const std::string& file) {
  PoseGraph graph = io::readPoseGraph(poseGraphPath(file));
  SolverConfig config;
  config.threads = 2;
  return solveCentralized(graph, config);
}

TEST(CentralizedSolver, SmallGridBenchmarksConverge) {
  for (const std::string file : {"3d/tinyGrid3D.g2o", "3d/smallGrid3D.g2o"}) {
    const SolverSummary s = solveBenchmark(file);
    EXPECT_TRUE(s.converged) << file << ": " << s.message;
    EXPECT_LT(s.final_cost, 0.5 * s.initial_cost) << file;
  }
}

TEST(CentralizedSolver, Sphere2500ConvergesFromOdometry) {
  const SolverSummary s = solveBenchmark("3d/sphere2500.g2o");
  EXPECT_TRUE(s.converged) << s.message;
  // From the odometry initialisation (chi2 2.6e6) to chi2 1351.4, the value g2o's own
  // error function also gives at this solution (1351.2). The often quoted 1687 is
  // SE-Sync's objective (isotropic kappa, tau weights), not a chi-square.
  EXPECT_GT(s.initial_cost, 1e6);
  EXPECT_LT(s.final_cost, 1360.0);
}

TEST(CentralizedSolver, NoiseFreeSphereSolvesToZeroCost) {
  // TORO EDGE3 lines of noise-free measurements, no vertices: chained by the reader,
  // then perturbed. The optimum is consistent up to the file's 6 printed digits.
  PoseGraph graph = io::readPoseGraph(poseGraphPath("3d/sphere2500_groundtruth.graph"));
  perturb(graph, 11);
  const SolverSummary s = solveCentralized(graph);
  EXPECT_GT(s.initial_cost, 1e4);
  EXPECT_LT(s.final_cost, 1.0);
}

TEST(CentralizedSolver, PlanarGraphLiftedTo3dSolvesAndStaysPlanar) {
  PoseGraph graph = io::readPoseGraph(poseGraphPath("2d/intel.g2o"));
  const SolverSummary s = solveCentralized(graph);
  EXPECT_TRUE(s.converged) << s.message;
  EXPECT_LT(s.final_cost, 0.1 * s.initial_cost);
  for (const auto& [k, T] : graph.nodes()) {
    EXPECT_NEAR(T.translation().z(), 0.0, 1e-6);
    EXPECT_NEAR(T.rotation()(2, 2), 1.0, 1e-9);
  }
}

}  // namespace
}  // namespace dcl::backend
