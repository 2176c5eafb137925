#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/ate.hpp>

namespace dcl::eval {

namespace {

// evo's APE on one pair: the translation part is |p_est - p_gt|; the rotation part is the angle
// of est^-1 gt, whose rotation is the transpose of R_gt^T R_est (the same angle).
double translationError(const Eigen::Isometry3d& T_gt, const Eigen::Isometry3d& T_est) {
  return (T_est.translation() - T_gt.translation()).norm();
}

double rotationErrorDeg(const Eigen::Isometry3d& T_gt, const Eigen::Isometry3d& T_est) {
  return core::rad2deg(core::rotationAngle(T_gt.linear().transpose() * T_est.linear()));
}

void summarise(AteResult& result) {
  result.pairs = result.translation_errors.size();
  result.translation_m = computeStatistics(result.translation_errors);
  result.rotation_deg = computeStatistics(result.rotation_errors);
}

void appendErrors(AteResult& result, const Association& pairs, const Sim3& S_gt_est) {
  const core::Trajectory aligned = transformed(pairs.estimate, S_gt_est);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    result.translation_errors.push_back(
        translationError(pairs.ground_truth.pose(i), aligned.pose(i)));
    result.rotation_errors.push_back(rotationErrorDeg(pairs.ground_truth.pose(i), aligned.pose(i)));
  }
}

}  // namespace

AteResult computeAte(const Association& pairs, const Sim3& S_gt_est, Alignment alignment) {
  if (pairs.size() == 0) throw core::Error("ATE: no associated pose pairs");
  AteResult result;
  result.alignment = alignment;
  result.S_gt_est = S_gt_est;
  appendErrors(result, pairs, S_gt_est);
  summarise(result);
  return result;
}

AteResult computeAte(const Association& pairs, Alignment alignment) {
  return computeAte(pairs, computeAlignment(pairs, alignment), alignment);
}

AteResult computeAte(const core::Trajectory& estimate, const core::Trajectory& ground_truth,
                     const AteOptions& options) {
  return computeAte(associate(estimate, ground_truth, options.association), options.alignment);
}

MultiRobotAteResult computeMultiRobotAte(const std::vector<Association>& robots,
                                         const MultiRobotAteOptions& options) {
  if (robots.empty()) throw core::Error("multi-robot ATE: no robots");
  if (options.reference_robot >= robots.size()) {
    throw core::Error(fmt::format("multi-robot ATE: reference robot {} out of range ({} robots)",
                                  options.reference_robot, robots.size()));
  }
  MultiRobotAteResult result;
  result.reference_robot = options.reference_robot;
  result.S_gt_est = computeAlignment(robots[options.reference_robot], options.alignment);
  result.pooled.alignment = options.alignment;
  result.pooled.S_gt_est = result.S_gt_est;
  for (const Association& pairs : robots) {
    result.robots.push_back(computeAte(pairs, result.S_gt_est, options.alignment));
    appendErrors(result.pooled, pairs, result.S_gt_est);
  }
  summarise(result.pooled);
  return result;
}

}  // namespace dcl::eval
