#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/eval/factor_noise.hpp>

#include "kitti_run.hpp"

namespace dcl::eval {
namespace {

/// Windows of `span` keyframes, half a span apart, over one robot of `n` keyframes.
std::size_t windows(std::size_t n, std::size_t span) {
  const std::size_t step = std::max<std::size_t>(1, span / 2);
  return n > span ? (n - span - 1) / step + 1 : 0;
}

/// The same over every robot (KITTI 00's have 120, 120 and 215 keyframes).
std::size_t windows(const std::vector<RobotGraph>& robots, std::size_t span) {
  std::size_t n = 0;
  for (const RobotGraph& r : robots) n += windows(r.stamps.size(), span);
  return n;
}

TEST(FactorNoise, RowsCountEveryWindowAndEveryLoopOnce) {
  const std::vector<RobotGraph> robots = test::kittiRun();
  const std::vector<FactorNoise> rows = factorNoise(robots, {1, 10, 100});
  ASSERT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows[0].factors, "odometry, 1 keyframe");
  EXPECT_EQ(rows[1].factors, "odometry, 10 keyframes");
  EXPECT_EQ(rows[2].factors, "odometry, 100 keyframes");
  EXPECT_EQ(rows[3].factors, "own loops");
  EXPECT_EQ(rows[4].factors, "inter-robot loops");
  EXPECT_EQ(rows[0].count, 452u);
  EXPECT_EQ(rows[1].count, windows(robots, 10));
  EXPECT_EQ(rows[1].count, 85u);
  EXPECT_EQ(rows[2].count, windows(robots, 100));
  const test::FactorCount n = test::countFactors(robots);
  EXPECT_EQ(rows[3].count, n.own_loops);
  EXPECT_EQ(rows[4].count, n.inter_loops);  // both robots of a loop hold it
}

TEST(FactorNoise, NoiseDrawnFromTheCovariancesGivesNeesNearOne) {
  const test::KittiRunOptions o;
  const std::vector<FactorNoise> rows = factorNoise(test::kittiRun(o), {1, 10});
  ASSERT_EQ(rows.size(), 4u);
  const FactorNoise& step = rows[0];
  EXPECT_NEAR(step.sigmaRms(0), std::sqrt(3.0) * o.odometry_sigma_m, 1e-12);
  EXPECT_NEAR(step.sigmaRms(1), std::sqrt(3.0) * o.odometry_sigma_rad, 1e-12);
  EXPECT_NEAR(step.errorRms(0), step.sigmaRms(0), 0.05 * step.sigmaRms(0));
  EXPECT_NEAR(step.errorRms(1), step.sigmaRms(1), 0.05 * step.sigmaRms(1));
  EXPECT_NEAR(step.neesPerDof(), 1.0, 0.1);
  for (int axis = 0; axis < 6; ++axis) {
    const double sigma = axis < 3 ? o.odometry_sigma_m : o.odometry_sigma_rad;
    EXPECT_NEAR(step.rms(step.sigma_axes)(axis), sigma, 1e-12) << axis;
    EXPECT_NEAR(step.rms(step.error_axes)(axis), sigma, 0.15 * sigma) << axis;
  }
  // Compounded over 10 keyframes: the propagated covariance still describes
  // the error, and its translation grows at least as the sum of the steps'.
  const FactorNoise& ten = rows[1];
  EXPECT_NEAR(ten.neesPerDof(), 1.0, 0.2);
  EXPECT_GE(ten.sigmaRms(0), std::sqrt(10.0) * step.sigmaRms(0));
  EXPECT_GT(ten.errorRms(0), std::sqrt(10.0) * step.errorRms(0));
  EXPECT_NEAR(rows[3].neesPerDof(), 1.0, 0.25);  // 67 inter-robot loops
}

TEST(FactorNoise, CovariancesTooLooseShowAsNeesBelowOne) {
  test::KittiRunOptions loose;
  loose.covariance_scale = 4.0;
  const std::vector<FactorNoise> right = factorNoise(test::kittiRun(), {1, 10, 100});
  const std::vector<FactorNoise> rows = factorNoise(test::kittiRun(loose), {1, 10, 100});
  ASSERT_EQ(rows.size(), right.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    // The same errors, standard deviations twice as large: NEES a quarter.
    EXPECT_EQ(rows[i].count, right[i].count);
    EXPECT_DOUBLE_EQ(rows[i].errorRms(0), right[i].errorRms(0)) << rows[i].factors;
    EXPECT_NEAR(rows[i].sigmaRms(0), 2.0 * right[i].sigmaRms(0), 1e-9 * rows[i].sigmaRms(0));
    EXPECT_NEAR(rows[i].neesPerDof(), right[i].neesPerDof() / 4.0, 1e-9) << rows[i].factors;
  }
  EXPECT_LT(rows[0].neesPerDof(), 0.3);
}

TEST(FactorNoise, ABiasOfTheLoopsIsTheirError) {
  test::KittiRunOptions o;
  o.exact_loops = true;
  o.inter_loop_bias.translation() = Eigen::Vector3d(0.3, 0.0, 0.4);
  const std::vector<FactorNoise> rows = factorNoise(test::kittiRun(o), {1});
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1].count, 7u);
  EXPECT_NEAR(rows[1].errorRms(0), 0.0, 1e-9);
  EXPECT_NEAR(rows[1].errorRms(1), 0.0, 1e-9);
  EXPECT_EQ(rows[2].count, 67u);
  EXPECT_NEAR(rows[2].errorRms(0), 0.5, 1e-6);  // KITTI's rotations: 9 digits
  EXPECT_NEAR(rows[2].errorRms(1), 0.0, 1e-9);
  // 0.5 m against 5 cm per axis: (0.3^2 + 0.4^2) / 0.05^2 / 6 per factor.
  EXPECT_NEAR(rows[2].neesPerDof(), 100.0 / 6.0, 1e-4);
}

TEST(FactorNoise, OneFactorByHand) {
  FactorNoise row{"by hand"};
  EXPECT_EQ(row.rms(1.0), 0.0);
  EXPECT_EQ(row.neesPerDof(), 0.0);
  EXPECT_TRUE(row.rms(row.error_axes).isZero());
  core::Vector6d r;
  r << 0.1, 0.0, 0.0, 0.0, 0.0, 0.01;
  core::Vector6d variance;
  variance << 0.01, 0.01, 0.01, 1e-4, 1e-4, 1e-4;
  row.add(r, variance.asDiagonal().toDenseMatrix());
  EXPECT_EQ(row.count, 1u);
  EXPECT_DOUBLE_EQ(row.errorRms(0), 0.1);
  EXPECT_DOUBLE_EQ(row.errorRms(1), 0.01);
  EXPECT_DOUBLE_EQ(row.sigmaRms(0), std::sqrt(0.03));
  EXPECT_DOUBLE_EQ(row.sigmaRms(1), std::sqrt(3e-4));
  EXPECT_DOUBLE_EQ(row.neesPerDof(), 2.0 / 6.0);  // one sigma along two axes
  row.add(-r, variance.asDiagonal().toDenseMatrix());
  EXPECT_DOUBLE_EQ(row.errorRms(0), 0.1);
  EXPECT_DOUBLE_EQ(row.neesPerDof(), 2.0 / 6.0);
}

}  // namespace
}  // namespace dcl::eval
