#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <dcl/registration/ransac.hpp>

namespace dcl::registration {
namespace {

/// The correspondences as two aligned point lists.
struct PointPairs {
  Eigen::Matrix3Xd source;
  Eigen::Matrix3Xd target;

  [[nodiscard]] Eigen::Index size() const { return source.cols(); }
};

PointPairs gather(std::span<const Eigen::Vector3d> source, std::span<const Eigen::Vector3d> target,
                  std::span<const Correspondence> correspondences) {
  std::vector<Correspondence> valid;
  for (const Correspondence& c : correspondences)
    if (c.source < source.size() && c.target < target.size()) valid.push_back(c);
  PointPairs pairs{Eigen::Matrix3Xd(3, static_cast<Eigen::Index>(valid.size())),
                   Eigen::Matrix3Xd(3, static_cast<Eigen::Index>(valid.size()))};
  for (std::size_t i = 0; i < valid.size(); ++i) {
    pairs.source.col(static_cast<Eigen::Index>(i)) = source[valid[i].source];
    pairs.target.col(static_cast<Eigen::Index>(i)) = target[valid[i].target];
  }
  return pairs;
}

/// True when the triangles of the sample have matching edges: a rigid motion
/// keeps lengths, so any edge that changed beyond `similarity` marks an outlier.
/// Edges shorter than `min_edge` are refused too: a tiny or thin triangle fixes
/// the rotation poorly.
bool consistentSample(const PointPairs& pairs, const std::array<Eigen::Index, 3>& s,
                      double similarity, double min_edge) {
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3;
    const double ls = (pairs.source.col(s[a]) - pairs.source.col(s[b])).norm();
    const double lt = (pairs.target.col(s[a]) - pairs.target.col(s[b])).norm();
    if (std::min(ls, lt) < min_edge || std::min(ls, lt) < similarity * std::max(ls, lt))
      return false;
  }
  return true;
}

/// The rigid motion mapping the selected source columns onto the target ones.
Eigen::Isometry3d fit(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix() = Eigen::umeyama(source, target, false);
  return T;
}

/// The indices of the correspondences `T` explains.
std::vector<Eigen::Index> explained(const PointPairs& pairs, const Eigen::Isometry3d& T,
                                    double distance) {
  std::vector<Eigen::Index> inliers;
  const double d2 = distance * distance;
  for (Eigen::Index i = 0; i < pairs.size(); ++i)
    if ((T * pairs.source.col(i) - pairs.target.col(i)).squaredNorm() < d2) inliers.push_back(i);
  return inliers;
}

/// How many correspondences `T` explains (the scoring loop: no allocation).
std::size_t countExplained(const PointPairs& pairs, const Eigen::Isometry3d& T, double distance) {
  const double d2 = distance * distance;
  std::size_t count = 0;
  for (Eigen::Index i = 0; i < pairs.size(); ++i)
    count += (T * pairs.source.col(i) - pairs.target.col(i)).squaredNorm() < d2 ? 1 : 0;
  return count;
}

/// Samples needed to draw an all-inlier triple with `confidence` at inlier ratio `ratio`.
double samplesNeeded(double ratio, double confidence) {
  const double p = ratio * ratio * ratio;
  if (p >= 1.0) return 1.0;
  if (p <= 0.0) return std::numeric_limits<double>::infinity();
  return std::log(1.0 - confidence) / std::log(1.0 - p);
}

/// Refits `T` to every correspondence it explains.
Eigen::Isometry3d refit(const PointPairs& pairs, const std::vector<Eigen::Index>& inliers) {
  Eigen::Matrix3Xd s(3, static_cast<Eigen::Index>(inliers.size()));
  Eigen::Matrix3Xd t(3, static_cast<Eigen::Index>(inliers.size()));
  for (std::size_t i = 0; i < inliers.size(); ++i) {
    s.col(static_cast<Eigen::Index>(i)) = pairs.source.col(inliers[i]);
    t.col(static_cast<Eigen::Index>(i)) = pairs.target.col(inliers[i]);
  }
  return fit(s, t);
}

}  // namespace

RansacResult ransacRegistration(std::span<const Eigen::Vector3d> source,
                                std::span<const Eigen::Vector3d> target,
                                std::span<const Correspondence> correspondences,
                                const RansacConfig& config) {
  RansacResult result;
  const PointPairs pairs = gather(source, target, correspondences);
  if (pairs.size() < 3) return result;
  std::mt19937_64 rng(config.seed);
  std::uniform_int_distribution<Eigen::Index> pick(0, pairs.size() - 1);
  std::size_t best = 0;
  Eigen::Matrix3d s;
  Eigen::Matrix3d t;
  for (int iteration = 0; iteration < config.max_iterations; ++iteration) {
    result.iterations = iteration + 1;
    const std::array<Eigen::Index, 3> sample{pick(rng), pick(rng), pick(rng)};
    if (sample[0] == sample[1] || sample[1] == sample[2] || sample[0] == sample[2]) continue;
    if (!consistentSample(pairs, sample, config.edge_similarity, config.inlier_distance)) continue;
    for (int k = 0; k < 3; ++k) {
      s.col(k) = pairs.source.col(sample[static_cast<std::size_t>(k)]);
      t.col(k) = pairs.target.col(sample[static_cast<std::size_t>(k)]);
    }
    const Eigen::Isometry3d T = fit(s, t);
    const std::size_t count = countExplained(pairs, T, config.inlier_distance);
    if (count > best) {
      best = count;
      result.T_target_source = T;
    }
    const double ratio = static_cast<double>(best) / static_cast<double>(pairs.size());
    if (best >= config.min_inliers && iteration + 1 >= samplesNeeded(ratio, config.confidence))
      break;
  }
  if (best < std::max<std::size_t>(config.min_inliers, 3)) return result;
  const std::vector<Eigen::Index> inliers =
      explained(pairs, result.T_target_source, config.inlier_distance);
  const Eigen::Isometry3d refined = refit(pairs, inliers);
  const std::size_t refined_count = countExplained(pairs, refined, config.inlier_distance);
  if (refined_count >= inliers.size()) result.T_target_source = refined;
  result.inliers = std::max(refined_count, inliers.size());
  result.found = true;
  return result;
}

}  // namespace dcl::registration
