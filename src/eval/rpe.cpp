#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/rpe.hpp>

namespace dcl::eval {

namespace {

// One KITTI segment's errors, already divided by the nominal length (devkit's `errors`).
struct KittiSegment {
  double length_m = 0.0;
  double t_err_per_m = 0.0;
  double r_err_rad_per_m = 0.0;
};

// evo's path filter, all pairs: the first j > i whose path length from i is nearest `delta`
// (np.argmin over the accumulated distances), searched by bisection since they never decrease.
std::size_t nearestPathIndex(const std::vector<double>& dist, std::size_t i, double delta) {
  auto path = [&](std::size_t j) { return dist[j] - dist[i]; };
  const auto first = dist.begin() + static_cast<std::ptrdiff_t>(i + 1);
  const auto it = std::lower_bound(first, dist.end(), delta,
                                   [&](double d, double value) { return d - dist[i] < value; });
  std::size_t j = std::min(static_cast<std::size_t>(it - dist.begin()), dist.size() - 1);
  if (j > i + 1 && std::abs(path(j - 1) - delta) <= std::abs(path(j) - delta)) --j;
  while (j > i + 1 && path(j - 1) == path(j)) --j;
  return j;
}

std::vector<IndexPair> pathPairsAll(const std::vector<double>& dist, double delta, double tol) {
  std::vector<IndexPair> pairs;
  for (std::size_t i = 0; i + 1 < dist.size(); ++i) {
    const std::size_t j = nearestPathIndex(dist, i, delta);
    if (std::abs((dist[j] - dist[i]) - delta) <= tol) pairs.emplace_back(i, j);
  }
  return pairs;
}

// evo's path filter, consecutive: a pose is kept when the path since the last kept one (or
// since pose 0 for the first) reaches `delta`; kept poses are paired in turn.
std::vector<IndexPair> pathPairsConsecutive(const core::Trajectory& trajectory, double delta) {
  std::vector<std::size_t> ids;
  double path = 0.0;
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    if (i > 0)
      path += (trajectory.pose(i).translation() - trajectory.pose(i - 1).translation()).norm();
    if (path >= delta) {
      ids.push_back(i);
      path = 0.0;
    }
  }
  std::vector<IndexPair> pairs;
  for (std::size_t k = 1; k < ids.size(); ++k) pairs.emplace_back(ids[k - 1], ids[k]);
  return pairs;
}

std::size_t framesDelta(double delta) {
  if (!(delta >= 1.0) || std::floor(delta) != delta) {
    throw core::Error(
        fmt::format("RPE: a delta in frames must be a positive integer, got {}", delta));
  }
  return static_cast<std::size_t>(delta);
}

std::vector<IndexPair> selectPairs(const core::Trajectory& trajectory, const RpeOptions& options) {
  if (options.delta_unit == DeltaUnit::frames) {
    return pairsByIndex(trajectory.size(), framesDelta(options.delta), options.all_pairs);
  }
  if (!(options.delta > 0.0)) {
    throw core::Error(
        fmt::format("RPE: a delta in meters must be positive, got {}", options.delta));
  }
  return pairsByPath(trajectory, options.delta, options.delta * options.rel_delta_tol,
                     options.all_pairs);
}

// The devkit's lastFrameFromSegmentLength: the first frame whose path from `first` exceeds
// `length`.
std::optional<std::size_t> lastFrame(const std::vector<double>& dist, std::size_t first,
                                     double length) {
  const double target = dist[first] + length;
  const auto it =
      std::upper_bound(dist.begin() + static_cast<std::ptrdiff_t>(first), dist.end(), target);
  if (it == dist.end()) return std::nullopt;
  return static_cast<std::size_t>(it - dist.begin());
}

// The devkit inverts with a general matrix inverse, not a transpose; KITTI poses are only
// orthonormal to about 1e-7, which shows in the acos of small angles.
Eigen::Matrix4d between(const Eigen::Isometry3d& T_i, const Eigen::Isometry3d& T_j) {
  return T_i.matrix().inverse() * T_j.matrix();
}

KittiSegment segmentError(const Association& pairs, std::size_t first, std::size_t last,
                          double length) {
  const Eigen::Matrix4d delta_gt =
      between(pairs.ground_truth.pose(first), pairs.ground_truth.pose(last));
  const Eigen::Matrix4d delta_est = between(pairs.estimate.pose(first), pairs.estimate.pose(last));
  const Eigen::Matrix4d error = delta_est.inverse() * delta_gt;
  const double d = 0.5 * (error.topLeftCorner<3, 3>().trace() - 1.0);
  const double r_err = std::acos(std::clamp(d, -1.0, 1.0));
  const double t_err = error.topRightCorner<3, 1>().norm();
  return {length, t_err / length, r_err / length};
}

std::vector<KittiSegment> kittiSegments(const Association& pairs, const KittiOptions& options) {
  if (options.step == 0) throw core::Error("KITTI metric: the step between segments must be > 0");
  const std::vector<double> dist = pairs.ground_truth.distances();
  std::vector<KittiSegment> segments;
  for (std::size_t first = 0; first < pairs.size(); first += options.step) {
    for (const double length : options.lengths) {
      const auto last = lastFrame(dist, first, length);
      if (last) segments.push_back(segmentError(pairs, first, *last, length));
    }
  }
  return segments;
}

KittiLength summariseLength(const std::vector<KittiSegment>& segments, double length) {
  KittiLength out;
  out.length_m = length;
  for (const auto& s : segments) {
    if (s.length_m != length) continue;
    ++out.segments;
    out.translation_percent += s.t_err_per_m;
    out.rotation_deg_per_100m += s.r_err_rad_per_m;
  }
  if (out.segments == 0) return out;
  const auto n = static_cast<double>(out.segments);
  out.translation_percent = 100.0 * out.translation_percent / n;
  out.rotation_deg_per_100m = 100.0 * core::rad2deg(out.rotation_deg_per_100m / n);
  return out;
}

KittiResult summariseKitti(const std::vector<KittiSegment>& segments, const KittiOptions& options) {
  KittiResult result;
  result.segments = segments.size();
  double t_sum = 0.0;
  double r_sum = 0.0;
  for (const auto& s : segments) {
    t_sum += s.t_err_per_m;
    r_sum += s.r_err_rad_per_m;
  }
  const auto n = static_cast<double>(segments.size());
  result.translation_percent = 100.0 * t_sum / n;
  result.rotation_deg_per_m = core::rad2deg(r_sum / n);
  result.rotation_deg_per_100m = 100.0 * result.rotation_deg_per_m;
  for (const double length : options.lengths) {
    const KittiLength per_length = summariseLength(segments, length);
    if (per_length.segments > 0) result.per_length.push_back(per_length);
  }
  return result;
}

void measurePairs(RpeResult& result, const core::Trajectory& ground_truth,
                  const core::Trajectory& estimate) {
  for (const auto& [i, j] : result.pairs) {
    const Eigen::Isometry3d E = relativeError(ground_truth.pose(i), ground_truth.pose(j),
                                              estimate.pose(i), estimate.pose(j));
    result.translation_errors.push_back(E.translation().norm());
    result.rotation_errors.push_back(core::rad2deg(core::rotationAngle(E.linear())));
  }
  result.translation_m = computeStatistics(result.translation_errors);
  result.rotation_deg = computeStatistics(result.rotation_errors);
}

}  // namespace

std::string_view toString(DeltaUnit unit) {
  return unit == DeltaUnit::meters ? "meters" : "frames";
}

DeltaUnit parseDeltaUnit(std::string_view name) {
  if (name == "frames" || name == "f") return DeltaUnit::frames;
  if (name == "meters" || name == "m") return DeltaUnit::meters;
  throw core::Error(fmt::format("unknown delta unit '{}' (expected frames or meters)", name));
}

std::vector<IndexPair> pairsByIndex(std::size_t size, std::size_t delta, bool all_pairs) {
  if (delta == 0) throw core::Error("RPE: the delta in frames must be at least 1");
  std::vector<IndexPair> pairs;
  if (all_pairs) {
    for (std::size_t i = 0; i + delta < size; ++i) pairs.emplace_back(i, i + delta);
  } else {
    for (std::size_t i = 0; i + delta < size; i += delta) pairs.emplace_back(i, i + delta);
  }
  return pairs;
}

std::vector<IndexPair> pairsByPath(const core::Trajectory& trajectory, double delta, double tol,
                                   bool all_pairs) {
  if (all_pairs) return pathPairsAll(trajectory.distances(), delta, tol);
  return pathPairsConsecutive(trajectory, delta);
}

Eigen::Isometry3d relativeError(const Eigen::Isometry3d& Q_i, const Eigen::Isometry3d& Q_j,
                                const Eigen::Isometry3d& P_i, const Eigen::Isometry3d& P_j) {
  const Eigen::Isometry3d Q_rel = Q_i.inverse() * Q_j;
  const Eigen::Isometry3d P_rel = P_i.inverse() * P_j;
  return Q_rel.inverse() * P_rel;
}

RpeResult computeRpe(const Association& pairs, const RpeOptions& options) {
  RpeResult result;
  result.alignment = options.alignment;
  result.S_gt_est = computeAlignment(pairs, options.alignment);
  Association aligned = pairs;
  aligned.estimate = transformed(pairs.estimate, result.S_gt_est);
  result.pairs =
      selectPairs(options.pairs_from_reference ? aligned.ground_truth : aligned.estimate, options);
  if (result.pairs.empty()) {
    throw core::Error(fmt::format(
        "RPE: delta = {} ({}) gives no pose pairs among {} associated poses; try a smaller delta",
        options.delta, toString(options.delta_unit), pairs.size()));
  }
  measurePairs(result, aligned.ground_truth, aligned.estimate);
  if (options.kitti) result.kitti = computeKittiMetric(aligned, options.kitti_options);
  return result;
}

RpeResult computeRpe(const core::Trajectory& estimate, const core::Trajectory& ground_truth,
                     const RpeOptions& options) {
  return computeRpe(associate(estimate, ground_truth, options.association), options);
}

std::optional<KittiResult> computeKittiMetric(const Association& pairs,
                                              const KittiOptions& options) {
  const std::vector<KittiSegment> segments = kittiSegments(pairs, options);
  if (segments.empty()) return std::nullopt;
  return summariseKitti(segments, options);
}

}  // namespace dcl::eval
