#pragma once

/// The factors of a run's joint graph (run_graph.hpp) against the ground
/// truth (`dcl-slam bench noise`): odometry compounded over spans of
/// keyframes, own and inter-robot loops, each class's errors beside its
/// covariances. Whether the noise model weighs odometry and loops as their
/// errors do.

#include <cstddef>
#include <string>
#include <vector>

#include <dcl/core/se3.hpp>
#include <dcl/eval/run_graph.hpp>

namespace dcl::eval {

/// The errors of one class of factors (or of odometry compounded over a
/// span of keyframes) against the ground truth, beside their covariances.
struct FactorNoise {
  std::string factors;    ///< the class, as the tables name it
  std::size_t count = 0;  ///< factors added
  /// Per axis of the factor's frame (x y z, then rotations about them): sums
  /// of squared errors and of variances (m^2, rad^2).
  core::Vector6d error_axes = core::Vector6d::Zero();
  core::Vector6d sigma_axes = core::Vector6d::Zero();
  double nees = 0.0;  ///< sum of r^T Omega r

  /// Adds a factor whose residual at the ground truth is `r` ([rho; phi]).
  void add(const core::Vector6d& r, const core::Matrix6d& covariance);
  /// The root of a sum's mean over the factors (0 without factors).
  [[nodiscard]] double rms(double sum) const;
  [[nodiscard]] core::Vector6d rms(const core::Vector6d& sums) const;
  /// RMS of the translation (block 0) or rotation (block 1) error's norm.
  [[nodiscard]] double errorRms(int block) const;
  /// RMS of the root of the covariance block's trace.
  [[nodiscard]] double sigmaRms(int block) const;
  /// The normalised estimation error squared per degree of freedom: 1 when
  /// the covariances describe the errors, below when too loose, above when too tight.
  [[nodiscard]] double neesPerDof() const;
};

/// Every robot's odometry compounded over each span of `spans` keyframes
/// (windows half a span apart; covariances propagated as the keyframe
/// selector does), then the own and the inter-robot loops, once each: one
/// row per span, then "own loops" and "inter-robot loops".
std::vector<FactorNoise> factorNoise(const std::vector<RobotGraph>& robots,
                                     const std::vector<std::size_t>& spans);

}  // namespace dcl::eval
