#include <string>

#include <gtest/gtest.h>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/g2o.hpp>

namespace dcl::backend {
namespace {

core::PoseKey key(int robot, int keyframe) {
  return {core::RobotId(static_cast<std::uint8_t>(robot)),
          core::KeyframeId(static_cast<std::uint64_t>(keyframe))};
}

Eigen::Isometry3d pose(double x, double y, double z, double yaw) {
  Eigen::Isometry3d T = core::makePose2d(x, y, yaw);
  T.translation().z() = z;
  return T;
}

std::string dataPath(const std::string& relative) {
  return std::string(DCL_DATA_DIR) + "/pose_graphs/" + relative;
}

TEST(PoseGraph, NodesAndEstimates) {
  PoseGraph graph;
  graph.addNode(key(0, 0), pose(1, 2, 3, 0.1));
  EXPECT_TRUE(graph.hasNode(key(0, 0)));
  EXPECT_FALSE(graph.hasNode(key(1, 0)));
  EXPECT_TRUE(graph.estimate(key(0, 0)).isApprox(pose(1, 2, 3, 0.1)));
  graph.setEstimate(key(0, 0), pose(0, 0, 0, 0));
  EXPECT_TRUE(graph.estimate(key(0, 0)).isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_THROW((void)graph.estimate(key(0, 1)), core::Error);
  EXPECT_THROW(graph.setEstimate(key(0, 1), pose(0, 0, 0, 0)), core::Error);
  graph.fix(key(0, 0));
  EXPECT_TRUE(graph.isFixed(key(0, 0)));
  graph.unfix(key(0, 0));
  EXPECT_FALSE(graph.isFixed(key(0, 0)));
}

TEST(PoseGraph, ResidualIsZeroForAnExactMeasurementAndCostIsChiSquare) {
  PoseGraph graph;
  const Eigen::Isometry3d T_a = pose(1, 0, 0, 0.3);
  const Eigen::Isometry3d T_b = pose(2, 1, 0.5, -0.2);
  graph.addNode(key(0, 0), T_a);
  graph.addNode(key(0, 1), T_b);
  Factor factor{key(0, 0), key(0, 1), T_a.inverse() * T_b, core::Matrix6d::Identity() * 4.0};
  EXPECT_LT(factorResidual(factor, T_a, T_b).norm(), 1e-12);
  // Off by 0.1 m along the measured node's x: residual rho = (0.1, 0, 0), cost 4 * 0.01.
  factor.T_from_to = factor.T_from_to * pose(-0.1, 0, 0, 0);
  graph.addFactor(factor);
  EXPECT_NEAR(graphCost(graph), 0.04, 1e-12);
  // A factor to a node the graph does not hold is left out of the cost.
  graph.addFactor({key(0, 1), key(1, 0), pose(1, 0, 0, 0), core::Matrix6d::Identity()});
  EXPECT_FALSE(graph.connects(graph.factors().back()));
  EXPECT_NEAR(graphCost(graph), 0.04, 1e-12);
}

TEST(PoseGraph, InformationFromCovarianceInvertsAndRegularises) {
  core::Matrix6d covariance = core::Vector6d(0.01, 0.02, 0.03, 1e-4, 2e-4, 3e-4).asDiagonal();
  covariance(0, 1) = covariance(1, 0) = 0.005;
  EXPECT_TRUE((informationFromCovariance(covariance) * covariance)
                  .isApprox(core::Matrix6d::Identity(), 1e-9));
  const core::Matrix6d singular = core::Matrix6d::Zero();
  const core::Matrix6d information = informationFromCovariance(singular, 1e-6);
  EXPECT_TRUE(information.allFinite());
  EXPECT_NEAR(information(3, 3), 1e6, 1e-3);
}

TEST(PoseGraph, FromG2oKeepsVerticesEdgesAndKinds) {
  const io::G2oGraph g2o = io::readG2o(dataPath("3d/tinyGrid3D.g2o"));
  const PoseGraph graph = fromG2o(g2o);
  EXPECT_EQ(graph.size(), g2o.vertices.size());
  ASSERT_EQ(graph.factors().size(), g2o.edges.size());
  std::size_t odometry = 0;
  for (std::size_t i = 0; i < g2o.edges.size(); ++i) {
    const Factor& f = graph.factors()[i];
    EXPECT_EQ(f.from, key(0, static_cast<int>(g2o.edges[i].from)));
    EXPECT_TRUE(f.T_from_to.isApprox(g2o.edges[i].T_from_to));
    EXPECT_EQ(f.information, g2o.edges[i].information);
    const bool consecutive = g2o.edges[i].to == g2o.edges[i].from + 1;
    EXPECT_EQ(f.kind, consecutive ? FactorKind::odometry : FactorKind::intra_loop);
    odometry += f.kind == FactorKind::odometry ? 1 : 0;
  }
  EXPECT_EQ(odometry, g2o.vertices.size() - 1);  // tinyGrid3D is one odometry chain plus loops
  EXPECT_GT(graph.factors().size(), odometry);
}

TEST(PoseGraph, SymbolIdsGiveRobotsAndInterRobotLoops) {
  io::G2oGraph g2o;
  const core::PoseKey a0 = key(0, 0), a1 = key(0, 1), b0 = key(1, 0);
  g2o.vertices = {
      {a0.pack(), pose(0, 0, 0, 0)}, {a1.pack(), pose(1, 0, 0, 0)}, {b0.pack(), pose(1, 1, 0, 0)}};
  g2o.edges = {{a0.pack(), a1.pack(), pose(1, 0, 0, 0), core::Matrix6d::Identity()},
               {a1.pack(), b0.pack(), pose(0, 1, 0, 0), core::Matrix6d::Identity()}};
  g2o.fixed = {a0.pack()};
  const PoseGraph graph = fromG2o(g2o);
  EXPECT_TRUE(graph.hasNode(b0));
  EXPECT_TRUE(graph.isFixed(a0));
  EXPECT_EQ(graph.factors()[0].kind, FactorKind::odometry);
  EXPECT_EQ(graph.factors()[1].kind, FactorKind::inter_loop);
  // Several robots: symbols by default; plain ids cannot name them.
  const io::G2oGraph back = toG2o(graph);
  EXPECT_EQ(back.vertices.size(), 3u);
  EXPECT_TRUE(back.hasVertex(b0.pack()));
  EXPECT_TRUE(back.fixed.contains(a0.pack()));
  EXPECT_EQ(back.edges[1].to, b0.pack());
  EXPECT_THROW((void)toG2o(graph, VertexIds::plain), core::Error);
}

TEST(PoseGraph, RoundTripsThroughG2oWithPlainIds) {
  const io::G2oGraph g2o = io::readG2o(dataPath("3d/smallGrid3D.g2o"));
  const io::G2oGraph back = toG2o(fromG2o(g2o));
  ASSERT_EQ(back.vertices.size(), g2o.vertices.size());
  ASSERT_EQ(back.edges.size(), g2o.edges.size());
  for (const auto& [id, T] : g2o.vertices) EXPECT_TRUE(back.vertices.at(id).isApprox(T));
  for (std::size_t i = 0; i < g2o.edges.size(); ++i) {
    EXPECT_EQ(back.edges[i].from, g2o.edges[i].from);
    EXPECT_EQ(back.edges[i].to, g2o.edges[i].to);
    EXPECT_EQ(back.edges[i].information, g2o.edges[i].information);
  }
  EXPECT_EQ(toString(FactorKind::inter_loop), "inter_loop");
}

}  // namespace
}  // namespace dcl::backend
