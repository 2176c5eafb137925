#include <string>

#include <gtest/gtest.h>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>

#include "../common/keys.hpp"

namespace dcl::backend {
namespace {

using dcl::test::key;

Eigen::Isometry3d pose(double x, double y, double z, double yaw) {
  Eigen::Isometry3d T = core::makePose2d(x, y, yaw);
  T.translation().z() = z;
  return T;
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

TEST(PoseGraph, FactorKindsHaveNames) {
  EXPECT_EQ(toString(FactorKind::inter_loop), "inter_loop");
}

}  // namespace
}  // namespace dcl::backend
