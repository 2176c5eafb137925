#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/se3.hpp>

#include "../../src/backend/se3_cost.hpp"

namespace dcl::backend::detail {
namespace {

using Jacobian3 = Eigen::Matrix<double, 6, 3, Eigen::RowMajor>;
using Jacobian4 = Eigen::Matrix<double, 6, 4, Eigen::RowMajor>;

/// A random rotation of exactly `angle` radians about a random axis.
Eigen::Quaterniond rotationOfAngle(std::mt19937& rng, double angle) {
  std::normal_distribution<double> normal;
  const Eigen::Vector3d axis = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis));
}

Eigen::Quaterniond randomRotation(std::mt19937& rng) {
  return rotationOfAngle(rng, std::uniform_real_distribution<double>(0.0, M_PI)(rng));
}

Eigen::Vector3d randomTranslation(std::mt19937& rng, double scale) {
  std::normal_distribution<double> normal(0.0, scale);
  return {normal(rng), normal(rng), normal(rng)};
}

/// An information matrix like a g2o edge's: positive definite, correlated.
core::Matrix6d randomInformation(std::mt19937& rng) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  core::Matrix6d A;
  for (int i = 0; i < 36; ++i) A(i / 6, i % 6) = uniform(rng);
  return A * A.transpose() + 10.0 * core::Matrix6d::Identity();
}

/// The residual and the Jacobians of `cost` in the tangent space of the
/// solver's parameterisation (quaternion blocks through EigenQuaternionManifold).
struct TangentEvaluation {
  core::Vector6d residual;
  std::array<Eigen::Matrix<double, 6, 3>, 4> jacobians;
};

TangentEvaluation evaluate(const ceres::CostFunction& cost, const PoseBlock& from,
                           const PoseBlock& to) {
  const std::array<const double*, 4> parameters = {from.q, from.t, to.q, to.t};
  Jacobian4 j_q_from;
  Jacobian3 j_t_from;
  Jacobian4 j_q_to;
  Jacobian3 j_t_to;
  std::array<double*, 4> jacobians = {j_q_from.data(), j_t_from.data(), j_q_to.data(),
                                      j_t_to.data()};
  TangentEvaluation out;
  EXPECT_TRUE(cost.Evaluate(parameters.data(), out.residual.data(), jacobians.data()));
  const ceres::EigenQuaternionManifold manifold;
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus_from;
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus_to;
  manifold.PlusJacobian(from.q, plus_from.data());
  manifold.PlusJacobian(to.q, plus_to.data());
  out.jacobians[0] = j_q_from * plus_from;
  out.jacobians[1] = j_t_from;
  out.jacobians[2] = j_q_to * plus_to;
  out.jacobians[3] = j_t_to;
  return out;
}

/// Compares analytic and autodiff costs of a factor whose error rotation is
/// `error_angle` radians (the measurement is T_from^-1 T_to perturbed by it).
void expectSameAsAutoDiff(std::mt19937& rng, double error_angle, double error_translation) {
  const Eigen::Isometry3d T_from =
      core::makePose(randomTranslation(rng, 20.0), randomRotation(rng));
  const Eigen::Isometry3d T_to = core::makePose(randomTranslation(rng, 20.0), randomRotation(rng));
  const Eigen::Isometry3d error =
      core::makePose(randomTranslation(rng, error_translation), rotationOfAngle(rng, error_angle));
  Factor factor;
  factor.T_from_to = T_from.inverse() * T_to * error.inverse();
  const core::Matrix6d sqrt_information = sqrtInformation(randomInformation(rng));
  const std::unique_ptr<ceres::CostFunction> analytic(
      RelativePoseCost::create(factor, sqrt_information));
  const std::unique_ptr<ceres::CostFunction> autodiff(
      RelativePoseError::createAutoDiff(factor, sqrt_information));
  const PoseBlock from = toBlock(T_from);
  const PoseBlock to = toBlock(T_to);
  const TangentEvaluation a = evaluate(*analytic, from, to);
  const TangentEvaluation b = evaluate(*autodiff, from, to);

  // The residual really is the SE(3) log of the error, whitened.
  const core::Vector6d expected = sqrt_information * core::logSE3(error);
  EXPECT_LE((a.residual - expected).norm(), 1e-9 * (1.0 + expected.norm()));
  EXPECT_LE((a.residual - b.residual).norm(), 1e-12 * (1.0 + b.residual.norm()));
  for (int k = 0; k < 4; ++k) {
    const double scale = b.jacobians[k].norm();
    ASSERT_GT(scale, 0.0);
    EXPECT_LE((a.jacobians[k] - b.jacobians[k]).norm(), 1e-6 * scale)
        << "block " << k << ", error angle " << error_angle << "\nanalytic\n"
        << a.jacobians[k] << "\nautodiff\n"
        << b.jacobians[k];
  }
}

TEST(Se3Cost, AnalyticJacobiansMatchAutoDiffOnRandomFactors) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(0.0, 3.0);
  for (int i = 0; i < 200; ++i) expectSameAsAutoDiff(rng, angle(rng), 2.0);
}

TEST(Se3Cost, AnalyticJacobiansMatchAutoDiffNearIdentity) {
  std::mt19937 rng(11);
  // Both sides of the series switch of J_r^-1 (theta^2 = 1e-2) and of the
  // quaternion log (|v|^2 = 1e-14), and an exact measurement.
  for (const double angle : {0.0, 1e-9, 1e-7, 1e-5, 1e-3, 0.0999, 0.1001, 0.3}) {
    for (int i = 0; i < 20; ++i) {
      expectSameAsAutoDiff(rng, angle, angle == 0.0 ? 0.0 : 0.5);
    }
  }
}

TEST(Se3Cost, AnalyticJacobiansMatchAutoDiffNearPi) {
  std::mt19937 rng(13);
  for (const double angle : {M_PI - 1e-2, M_PI - 1e-4, M_PI - 1e-6}) {
    for (int i = 0; i < 20; ++i) expectSameAsAutoDiff(rng, angle, 3.0);
  }
}

/// A step of the solver's own parameterisation moves the residual as the
/// analytic Jacobian predicts (a check independent of the autodiff reference).
TEST(Se3Cost, AnalyticJacobianPredictsManifoldSteps) {
  std::mt19937 rng(17);
  const ceres::EigenQuaternionManifold manifold;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Isometry3d T_from =
        core::makePose(randomTranslation(rng, 5.0), randomRotation(rng));
    const Eigen::Isometry3d T_to = core::makePose(randomTranslation(rng, 5.0), randomRotation(rng));
    Factor factor;
    factor.T_from_to = T_from.inverse() * T_to *
                       core::makePose(randomTranslation(rng, 1.0), rotationOfAngle(rng, 1.0));
    const core::Matrix6d sqrt_information = sqrtInformation(randomInformation(rng));
    const std::unique_ptr<ceres::CostFunction> cost(
        RelativePoseCost::create(factor, sqrt_information));
    const PoseBlock from = toBlock(T_from);
    const PoseBlock to = toBlock(T_to);
    const TangentEvaluation at = evaluate(*cost, from, to);
    for (int block = 0; block < 4; ++block) {
      for (int axis = 0; axis < 3; ++axis) {
        const double h = 1e-6;
        std::array<PoseBlock, 2> moved;
        for (int side = 0; side < 2; ++side) {
          moved[side] = block < 2 ? from : to;
          double* q = moved[side].q;
          double* t = moved[side].t;
          Eigen::Vector3d delta = Eigen::Vector3d::Zero();
          delta[axis] = side == 0 ? h : -h;
          if (block % 2 == 0) {
            const std::array<double, 4> q0 = {q[0], q[1], q[2], q[3]};
            ASSERT_TRUE(manifold.Plus(q0.data(), delta.data(), q));
          } else {
            for (int i = 0; i < 3; ++i) t[i] += delta[i];
          }
        }
        const auto residualAt = [&](const PoseBlock& m) {
          return evaluate(*cost, block < 2 ? m : from, block < 2 ? to : m).residual;
        };
        const core::Vector6d numeric = (residualAt(moved[0]) - residualAt(moved[1])) / (2.0 * h);
        const core::Vector6d analytic = at.jacobians[block].col(axis);
        EXPECT_LE((numeric - analytic).norm(), 1e-5 * (1.0 + analytic.norm()))
            << "block " << block << " axis " << axis;
      }
    }
  }
}

}  // namespace
}  // namespace dcl::backend::detail
