#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

#include "../../src/backend/pose_block_solver.hpp"

namespace dcl::backend {
namespace {

using detail::BlockSolveOptions;
using detail::BlockSolveSummary;
using detail::PoseBlockSolver;

PoseGraph benchmark(const std::string& file) {
  return io::readPoseGraph(std::string(DCL_DATA_DIR) + "/pose_graphs/3d/" + file);
}

/// A solver over the whole graph, its lowest node held (the centralized solver's gauge).
void load(PoseBlockSolver& solver, const PoseGraph& graph) {
  for (const auto& [key, pose] : graph.nodes()) solver.setPose(key, pose);
  for (const Factor& f : graph.factors()) ASSERT_TRUE(solver.addFactor(f));
  ASSERT_TRUE(solver.setConstant(graph.nodes().begin()->first));
}

/// The graph with the solver's poses as its estimates.
PoseGraph withEstimates(PoseGraph graph, const PoseBlockSolver& solver) {
  for (const auto& [key, pose] : graph.nodes()) graph.setEstimate(key, solver.pose(key));
  return graph;
}

double reference(const PoseGraph& graph) {
  PoseGraph solved = graph;
  SolverConfig config;
  config.function_tolerance = 1e-12;
  (void)solveCentralized(solved, config);
  return graphCost(solved);
}

TEST(PoseBlockSolver, ReachesCeresOptimumOnRealGraphs) {
  for (const std::string file : {"smallGrid3D.g2o", "sphere2500.g2o"}) {
    const PoseGraph graph = benchmark(file);
    PoseBlockSolver solver;
    load(solver, graph);
    BlockSolveOptions options;
    options.max_iterations = 100;
    options.function_tolerance = 1e-12;
    const BlockSolveSummary s = solver.solve(options);
    EXPECT_NEAR(s.initial_cost / graphCost(graph), 1.0, 1e-9) << file;
    // Its own cost figure is the graph's chi-square (no factor is between held poses).
    const PoseGraph solved = withEstimates(graph, solver);
    EXPECT_NEAR(s.final_cost / graphCost(solved), 1.0, 1e-9) << file;
    EXPECT_NEAR(graphCost(solved) / reference(graph), 1.0, 1e-6) << file;
    EXPECT_TRUE(
        solver.pose(graph.nodes().begin()->first).isApprox(graph.nodes().begin()->second, 1e-12))
        << file << ": the held pose moved";
  }
}

TEST(PoseBlockSolver, ReusedFactorisationsReachTheSameOptimumNeverRaisingTheCost) {
  const PoseGraph graph = benchmark("sphere2500.g2o");
  const double optimum = reference(graph);
  for (const int reuse : {0, 8}) {
    PoseBlockSolver solver;
    load(solver, graph);
    BlockSolveOptions options;
    options.max_iterations = 1;  // one step per call, as the refinement does
    options.factorisation_reuse = reuse;
    options.function_tolerance = 0.0;
    double last = graphCost(graph);
    int calls = 0;
    // A refused step only raises the damping; five in a row: converged.
    for (int idle = 0; calls < 300 && idle < 5; ++calls) {
      const BlockSolveSummary s = solver.solve(options);
      ASSERT_LE(s.final_cost, s.initial_cost) << "reuse " << reuse << ", call " << calls;
      ASSERT_NEAR(s.initial_cost, last, 1e-9 * last);
      idle = s.final_cost > (1.0 - 1e-12) * last ? idle + 1 : 0;
      last = s.final_cost;
    }
    EXPECT_NEAR(last / optimum, 1.0, 1e-6) << "reuse " << reuse << " after " << calls;
  }
}

/// Three poses in a line, one metre apart; the middle one alone is free.
struct Chain {
  PoseBlockSolver solver;
  core::PoseKey a{core::RobotId(0), core::KeyframeId(0)};
  core::PoseKey b{core::RobotId(0), core::KeyframeId(1)};
  core::PoseKey c{core::RobotId(1), core::KeyframeId(0)};

  Chain() {
    const Eigen::Isometry3d step =
        core::makePose(Eigen::Vector3d(1.0, 0.0, 0.0), Eigen::Quaterniond::Identity());
    solver.setPose(a, Eigen::Isometry3d::Identity());
    solver.setPose(b, core::makePose2d(0.3, 0.4, 0.2));  // off its optimum
    solver.setPose(c, step * step);
    Factor ab;
    ab.from = a;
    ab.to = b;
    ab.T_from_to = step;
    ab.information = core::Matrix6d::Identity();
    Factor bc = ab;
    bc.from = b;
    bc.to = c;
    EXPECT_TRUE(solver.addFactor(ab));
    EXPECT_TRUE(solver.addFactor(bc));
    EXPECT_TRUE(solver.setConstant(a));
    EXPECT_TRUE(solver.setConstant(c));
  }

  Eigen::Isometry3d solve() {
    BlockSolveOptions options;
    options.max_iterations = 50;
    options.function_tolerance = 1e-14;
    (void)solver.solve(options);
    return solver.pose(b);
  }
};

TEST(PoseBlockSolver, UsesTheLatestValuesOfHeldPoses) {
  Chain chain;
  EXPECT_TRUE(chain.solver.isVariable(chain.b));
  EXPECT_FALSE(chain.solver.isVariable(chain.c));
  EXPECT_LT((chain.solve().translation() - Eigen::Vector3d(1, 0, 0)).norm(), 1e-6);
  // A neighbour's separator moves: the same structure, new values.
  const Eigen::Isometry3d lifted =
      core::makePose(Eigen::Vector3d(0.0, 0.0, 2.0), Eigen::Quaterniond::Identity());
  chain.solver.setPose(chain.a, lifted);
  chain.solver.setPose(chain.c, lifted * chain.solver.pose(chain.c));
  const Eigen::Isometry3d b = chain.solve();
  EXPECT_LT((b.translation() - Eigen::Vector3d(1, 0, 2)).norm(), 1e-6);
  EXPECT_LT(core::rotationAngle(b.rotation()), 1e-6);
  EXPECT_TRUE(chain.solver.pose(chain.a).isApprox(lifted, 1e-12));
}

TEST(PoseBlockSolver, AFactorAddedBetweenSolvesCounts) {
  Chain chain;
  (void)chain.solve();
  // A second, stronger measurement pulls b half a metre up.
  Factor up;
  up.from = chain.a;
  up.to = chain.b;
  up.T_from_to = core::makePose(Eigen::Vector3d(1.0, 0.0, 0.5), Eigen::Quaterniond::Identity());
  up.information = 1e6 * core::Matrix6d::Identity();
  ASSERT_TRUE(chain.solver.addFactor(up));
  EXPECT_EQ(chain.solver.factors(), 3u);
  EXPECT_NEAR(chain.solve().translation().z(), 0.5, 1e-3);
}

TEST(PoseBlockSolver, RefusesFactorsItCannotHold) {
  Chain chain;
  Factor self;
  self.from = self.to = chain.b;
  self.information = core::Matrix6d::Identity();
  EXPECT_FALSE(chain.solver.addFactor(self));
  Factor unknown = self;
  unknown.to = {core::RobotId(7), core::KeyframeId(3)};
  EXPECT_FALSE(chain.solver.addFactor(unknown));
  EXPECT_FALSE(chain.solver.setConstant(unknown.to));
  EXPECT_EQ(chain.solver.factors(), 2u);
}

TEST(PoseBlockSolver, NothingFreeIsNotAnError) {
  Chain chain;
  ASSERT_TRUE(chain.solver.setConstant(chain.b));
  const Eigen::Isometry3d before = chain.solver.pose(chain.b);
  const BlockSolveSummary s = chain.solver.solve({});
  EXPECT_EQ(s.iterations, 0);
  EXPECT_EQ(s.final_cost, s.initial_cost);
  EXPECT_TRUE(chain.solver.pose(chain.b).isApprox(before, 0.0));
}

}  // namespace
}  // namespace dcl::backend
