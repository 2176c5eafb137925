#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <utility>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/registration/gicp.hpp>
#include <dcl/registration/verification.hpp>
#include <dcl/registration/voxel_filter.hpp>

namespace dcl::registration {
namespace {

/// GICP settings of a stage gated at `gate` metres (kernel at half the gate).
GicpConfig stage(const VerificationConfig& config, double gate) {
  GicpConfig gicp;
  gicp.max_iterations = config.max_iterations;
  gicp.max_correspondence_distance = gate;
  gicp.kernel_scale = 0.5 * gate;
  gicp.inlier_distance = config.inlier_distance;
  return gicp;
}

/// Coarse then fine GICP from `guess`; the result is the fine stage's, with
/// the iterations of both.
GicpResult refine(RegistrationCloud& target, RegistrationCloud& query,
                  const Eigen::Isometry3d& guess, const VerificationConfig& config) {
  const GicpResult coarse =
      alignGicp(target, query, guess, stage(config, config.coarse_correspondence_distance));
  GicpResult fine = alignGicp(target, query, coarse.T_target_source,
                              stage(config, config.max_correspondence_distance));
  fine.iterations += coarse.iterations;
  return fine;
}

/// The first acceptance test `result` fails, or none.
RejectReason judge(const GicpResult& result, const VerificationConfig& config) {
  if (!result.converged) return RejectReason::not_converged;
  if (result.inlier_share < config.min_inlier_share) return RejectReason::low_inlier_share;
  if (result.fitness > config.max_fitness) return RejectReason::high_fitness;
  if (result.degeneracy < config.min_degeneracy) return RejectReason::degenerate;
  return RejectReason::none;
}

/// True when `a` is a better alignment than `b`: accepted first, then the larger overlap.
bool better(const GicpResult& a, const GicpResult& b, const VerificationConfig& config) {
  const bool a_ok = judge(a, config) == RejectReason::none;
  const bool b_ok = judge(b, config) == RejectReason::none;
  if (a_ok != b_ok) return a_ok;
  if (a.converged != b.converged) return a.converged;
  return a.inlier_share > b.inlier_share;
}

/// The global alignment of the fallback: FPFH on clouds filtered at the
/// feature grid, mutual matches, RANSAC. None when RANSAC finds nothing.
std::optional<Eigen::Isometry3d> globalAlignment(const RegistrationCloud& query_cloud,
                                                 const RegistrationCloud& submap_cloud,
                                                 const VerificationConfig& config) {
  RegistrationCloud query(voxelDownsample(query_cloud.points(), config.feature_voxel_size),
                          config.shape_neighbors);
  RegistrationCloud submap(voxelDownsample(submap_cloud.points(), config.feature_voxel_size),
                           config.shape_neighbors);
  const std::vector<Correspondence> matches =
      matchFeatures(computeFpfh(query, config.fpfh), computeFpfh(submap, config.fpfh));
  const RansacResult ransac =
      ransacRegistration(query.points(), submap.points(), matches, config.ransac);
  if (!ransac.found) return std::nullopt;
  return ransac.T_target_source;
}

Eigen::Isometry3d yawPose(double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

}  // namespace

std::string_view toString(RejectReason reason) {
  switch (reason) {
    case RejectReason::none:
      return "none";
    case RejectReason::too_few_points:
      return "too_few_points";
    case RejectReason::not_converged:
      return "not_converged";
    case RejectReason::low_inlier_share:
      return "low_inlier_share";
    case RejectReason::high_fitness:
      return "high_fitness";
    case RejectReason::degenerate:
      return "degenerate";
    case RejectReason::symmetric:
      return "symmetric";
  }
  return "unknown";
}

void VerificationStats::add(const VerificationResult& result) {
  ++attempts;
  if (result.used_ransac) ++ransac;
  if (result.accepted) {
    ++accepted;
  } else {
    ++rejected[static_cast<std::size_t>(result.reason)];
  }
}

std::size_t VerificationStats::count(RejectReason reason) const {
  return reason == RejectReason::none ? accepted : rejected[static_cast<std::size_t>(reason)];
}

void validate(const VerificationConfig& config) {
  core::checkConfig(config, "verification config");
}

VerificationResult verifyLoop(const core::PointCloud& query_cloud, double yaw_guess,
                              const core::PointCloud& submap_cloud,
                              const VerificationConfig& config) {
  validate(config);
  VerificationResult result;
  RegistrationCloud query(voxelDownsample(query_cloud.points, config.voxel_size),
                          config.shape_neighbors);
  RegistrationCloud submap(voxelDownsample(submap_cloud.points, config.voxel_size),
                           config.shape_neighbors);
  result.query_points = query.size();
  result.submap_points = submap.size();
  if (query.size() < config.min_points || submap.size() < config.min_points) {
    result.reason = RejectReason::too_few_points;
    return result;
  }
  const Eigen::Isometry3d guess = yawPose(std::isfinite(yaw_guess) ? yaw_guess : 0.0);
  GicpResult best = refine(submap, query, guess, config);
  int iterations = best.iterations;
  const RejectReason first = judge(best, config);
  if (config.ransac_fallback && first != RejectReason::none && first != RejectReason::degenerate) {
    if (const auto global = globalAlignment(query, submap, config)) {
      GicpResult second = refine(submap, query, *global, config);
      iterations += second.iterations;
      result.used_ransac = better(second, best, config);
      if (result.used_ransac) best = std::move(second);
    }
  }
  result.reason = judge(best, config);
  if (result.reason == RejectReason::none && config.symmetric_share > 0.0) {
    // Half a turn about the query's own vertical axis, where it is in the submap.
    const GicpResult turned = refine(submap, query, best.T_target_source * yawPose(M_PI), config);
    iterations += turned.iterations;
    if (judge(turned, config) == RejectReason::none &&
        turned.inlier_share >= config.symmetric_share * best.inlier_share) {
      result.reason = RejectReason::symmetric;
    }
  }
  result.accepted = result.reason == RejectReason::none;
  result.T_candidate_query = best.T_target_source;
  result.covariance = best.covariance;
  result.inlier_share = best.inlier_share;
  result.fitness = best.fitness;
  result.degeneracy = best.degeneracy;
  result.iterations = iterations;
  return result;
}

core::PointCloud buildSubmap(std::span<const core::Keyframe> keyframes, std::size_t center,
                             int radius, double voxel_size) {
  if (center >= keyframes.size())
    throw core::Error("submap: keyframe index " + std::to_string(center) + " is outside the " +
                      std::to_string(keyframes.size()) + " keyframes given");
  if (radius < 0) throw core::Error("submap: negative radius " + std::to_string(radius));
  const core::Keyframe& middle = keyframes[center];
  const Eigen::Isometry3d T_center_odom = middle.T_odom_keyframe.inverse();
  const std::size_t first =
      center - std::min<std::size_t>(center, static_cast<std::size_t>(radius));
  const std::size_t last =
      std::min(keyframes.size() - 1, center + static_cast<std::size_t>(radius));
  std::vector<Eigen::Vector3d> points;
  for (std::size_t k = first; k <= last; ++k) {
    const core::Keyframe& keyframe = keyframes[k];
    if (keyframe.robot != middle.robot) continue;
    const Eigen::Isometry3d T = T_center_odom * keyframe.T_odom_keyframe;
    for (const Eigen::Vector3f& p : keyframe.cloud.points) points.push_back(T * p.cast<double>());
  }
  if (voxel_size > 0.0) points = voxelDownsample(points, voxel_size);
  core::PointCloud submap;
  submap.points.reserve(points.size());
  for (const Eigen::Vector3d& p : points) submap.points.push_back(p.cast<float>());
  return submap;
}

}  // namespace dcl::registration
