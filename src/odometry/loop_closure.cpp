#include <algorithm>
#include <utility>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/odometry/loop_closure.hpp>
#include <dcl/odometry/preprocessing.hpp>

namespace dcl::odometry {
namespace {

std::size_t indexOf(core::KeyframeId id) {
  return static_cast<std::size_t>(id.value());
}

/// The query's cloud, thinned for ICP, as double points.
std::vector<Eigen::Vector3d> sourcePoints(const core::Keyframe& query, double voxel_size) {
  return voxelDownsample(toPoints(query.cloud), voxel_size);
}

}  // namespace

std::vector<LoopCandidate> RadiusCandidateSearch::search(
    const core::Keyframe& query, std::span<const Eigen::Isometry3d> T_world_keyframes,
    std::size_t searchable) const {
  const Eigen::Vector3d position = T_world_keyframes[indexOf(query.id)].translation();
  std::vector<LoopCandidate> candidates;
  for (std::size_t i = 0; i < std::min(searchable, T_world_keyframes.size()); ++i) {
    const double distance = (T_world_keyframes[i].translation() - position).norm();
    if (distance <= config_.radius) candidates.push_back({core::KeyframeId(i), distance});
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const LoopCandidate& a, const LoopCandidate& b) { return a.score < b.score; });
  if (candidates.size() > config_.max_candidates) candidates.resize(config_.max_candidates);
  return candidates;
}

LoopClosure::LoopClosure(const LoopClosureConfig& config,
                         std::unique_ptr<LoopCandidateSearch> search)
    : config_(config), search_(std::move(search)) {
  if (!search_) search_ = std::make_unique<RadiusCandidateSearch>(config_.search);
}

std::size_t LoopClosure::searchable(std::span<const core::Keyframe> keyframes,
                                    const core::Keyframe& query) const {
  const std::size_t id = indexOf(query.id);
  if (id < config_.exclude_recent) return 0;
  std::size_t count = std::min(id - config_.exclude_recent, keyframes.size());
  while (count > 0 && keyframes[count - 1].stamp > query.stamp - config_.exclude_seconds) --count;
  return count;
}

std::optional<IntraLoop> LoopClosure::detect(std::span<const core::Keyframe> keyframes,
                                             std::span<const Eigen::Isometry3d> T_world_keyframes) {
  if (keyframes.empty()) return std::nullopt;
  const core::Keyframe& query = keyframes.back();
  const std::size_t eligible = searchable(keyframes, query);
  if (eligible == 0) return std::nullopt;
  if (last_loop_query_ && indexOf(query.id) <= *last_loop_query_ + config_.skip_after_loop) {
    return std::nullopt;
  }
  ++stats_.queries;
  for (const LoopCandidate& c : search_->search(query, T_world_keyframes, eligible)) {
    ++stats_.candidates;
    LoopVerification v = verify(keyframes, T_world_keyframes, c.keyframe, query.id, eligible);
    if (v.loop) {
      ++stats_.accepted;
      last_loop_query_ = indexOf(query.id);
      return v.loop;
    }
    ++stats_.rejected;
  }
  return std::nullopt;
}

LoopVerification LoopClosure::verify(std::span<const core::Keyframe> keyframes,
                                     std::span<const Eigen::Isometry3d> T_world_keyframes,
                                     core::KeyframeId candidate, core::KeyframeId query,
                                     std::size_t searchable) const {
  const std::size_t c = indexOf(candidate);
  const std::size_t q = indexOf(query);
  LoopVerification verification;
  const std::vector<Eigen::Vector3d> points = sourcePoints(keyframes[q], config_.source_voxel_size);
  const VoxelHashMap map = submap(keyframes, T_world_keyframes, c, searchable);
  const Eigen::Isometry3d guess = T_world_keyframes[c].inverse() * T_world_keyframes[q];
  verification.registration = registerCoarseToFine(points, map, guess);
  const RegistrationResult& r = verification.registration;
  verification.inlier_share =
      points.empty() ? 0.0 : static_cast<double>(r.inliers) / static_cast<double>(points.size());
  verification.rejection = judge(r, verification.inlier_share);
  if (verification.rejection.empty()) {
    verification.loop = IntraLoop{
        candidate, query, r.T_target_source, loopInformation(r), verification.inlier_share, r.rmse};
  }
  return verification;
}

VoxelHashMap LoopClosure::submap(std::span<const core::Keyframe> keyframes,
                                 std::span<const Eigen::Isometry3d> T_world_keyframes,
                                 std::size_t candidate, std::size_t searchable) const {
  // The candidate's neighbours in its own frame; never the recent keyframes,
  // which would let the query match its own recent past instead of the place.
  VoxelHashMap map(config_.map_voxel_size, config_.max_points_per_voxel);
  const auto n = static_cast<std::size_t>(std::max(config_.submap_neighbors, 0));
  const std::size_t first = candidate > n ? candidate - n : 0;
  const std::size_t last = std::min(candidate + n + 1, searchable);
  const Eigen::Isometry3d T_candidate_world = T_world_keyframes[candidate].inverse();
  for (std::size_t j = first; j < last; ++j) {
    map.addPoints(toPoints(keyframes[j].cloud), T_candidate_world * T_world_keyframes[j]);
  }
  return map;
}

RegistrationResult LoopClosure::registerCoarseToFine(
    std::span<const Eigen::Vector3d> points, const VoxelHashMap& map,
    const Eigen::Isometry3d& T_candidate_query_guess) const {
  RegistrationResult result;
  result.T_target_source = T_candidate_query_guess;
  IcpConfig icp;
  icp.max_iterations = config_.icp_iterations;
  for (const double distance : config_.icp_distances) {
    icp.max_correspondence_distance = distance;
    icp.kernel_scale = distance / 3.0;  // KISS-ICP's kernel: a third of the threshold
    result = registerScan(points, map, result.T_target_source, icp);
  }
  return result;
}

std::string LoopClosure::judge(const RegistrationResult& result, double inlier_share) const {
  if (!result.converged) return "registration did not converge";
  if (result.degenerate) return "registration is degenerate";
  if (inlier_share < config_.min_inlier_share) return "too few query points fit the submap";
  if (result.rmse > config_.max_rmse) return "residual too large";
  return {};
}

core::Matrix6d LoopClosure::loopInformation(const RegistrationResult& result) const {
  // ICP's J^T W J is for unit residual variance: scaled by 1 / rmse^2 it is the
  // information of the fit; its covariance is floored (see LoopClosureConfig).
  const double variance = std::max(result.rmse * result.rmse, 1e-6);
  const core::Matrix6d covariance =
      backend::informationFromCovariance(result.information / variance, 1e-12);
  return backend::informationFromCovariance(covariance, config_.min_variance);
}

}  // namespace dcl::odometry
