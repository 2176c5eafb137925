#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include <nanoflann.hpp>

#include <dcl/registration/fpfh.hpp>

namespace dcl::registration {
namespace {

constexpr int kBins = 11;

/// The three SPFH angles of a pair (Rusu 2009, Eq. 2), computed in the Darboux
/// frame of the point whose normal is closer to the line joining them, as PCL
/// does, so that the feature does not depend on which point comes first.
/// False when the pair has no frame (coincident points, normal along the line).
bool pairFeature(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1, const Eigen::Vector3d& p2,
                 const Eigen::Vector3d& n2, std::array<int, 3>& bins) {
  Eigen::Vector3d d = p2 - p1;
  const double distance = d.norm();
  if (distance <= 0.0) return false;
  d /= distance;
  const bool swap = std::abs(n1.dot(d)) < std::abs(n2.dot(d));  // the other point is the source
  const Eigen::Vector3d& u = swap ? n2 : n1;
  const Eigen::Vector3d& n = swap ? n1 : n2;
  if (swap) d = -d;
  const double theta = u.dot(d);
  Eigen::Vector3d v = d.cross(u);
  const double v_norm = v.norm();
  if (v_norm <= 1e-12) return false;
  v /= v_norm;
  const Eigen::Vector3d w = u.cross(v);
  const double alpha = v.dot(n);
  const double phi = std::atan2(w.dot(n), u.dot(n));
  auto bin = [](double unit) { return std::clamp(static_cast<int>(unit * kBins), 0, kBins - 1); };
  bins = {bin((phi + std::numbers::pi) / (2.0 * std::numbers::pi)), bin((alpha + 1.0) * 0.5),
          bin((theta + 1.0) * 0.5)};
  return true;
}

/// Each point's neighbours within the radius (without itself), nearest first.
std::vector<std::vector<Neighbor>> neighbourhoods(const RegistrationCloud& cloud,
                                                  const FpfhConfig& config) {
  std::vector<std::vector<Neighbor>> all(cloud.size());
  std::vector<Neighbor> found;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    cloud.tree().nearest(cloud.points()[i], config.max_neighbors + 1, config.radius, found);
    for (const Neighbor& n : found)
      if (n.index != i) all[i].push_back(n);
  }
  return all;
}

/// The SPFH of point `i` with its neighbours: one count per pair and angle,
/// each part normalised to 100.
FpfhFeature spfh(RegistrationCloud& cloud, std::size_t i, const std::vector<Neighbor>& neighbours) {
  FpfhFeature h = FpfhFeature::Zero();
  int pairs = 0;
  std::array<int, 3> bins{};
  for (const Neighbor& n : neighbours) {
    if (!pairFeature(cloud.points()[i], cloud.normal(i), cloud.points()[n.index],
                     cloud.normal(n.index), bins))
      continue;
    for (int k = 0; k < 3; ++k) h(k * kBins + bins[static_cast<std::size_t>(k)]) += 1.0F;
    ++pairs;
  }
  if (pairs > 0) h *= 100.0F / static_cast<float>(pairs);
  return h;
}

/// Scales each 11-bin part of `h` to sum to 100 (a zero part stays zero).
void normalise(FpfhFeature& h) {
  for (int k = 0; k < 3; ++k) {
    const float sum = h.segment<kBins>(k * kBins).sum();
    if (sum > 0.0F) h.segment<kBins>(k * kBins) *= 100.0F / sum;
  }
}

/// The features as nanoflann's dataset adaptor.
struct FeatureSet {
  const std::vector<FpfhFeature>& features;
  std::vector<std::uint32_t> ids;  ///< non-zero features only

  [[nodiscard]] std::size_t kdtree_get_point_count() const { return ids.size(); }
  [[nodiscard]] float kdtree_get_pt(std::size_t i, std::size_t dim) const {
    return features[ids[i]](static_cast<Eigen::Index>(dim));
  }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox& /*bbox*/) const {
    return false;
  }
};

using FeatureTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, FeatureSet>, FeatureSet,
                                        33, std::uint32_t>;

FeatureSet featureSet(const std::vector<FpfhFeature>& features) {
  FeatureSet set{features, {}};
  for (std::size_t i = 0; i < features.size(); ++i)
    if (features[i].squaredNorm() > 0.0F) set.ids.push_back(static_cast<std::uint32_t>(i));
  return set;
}

/// The index (into `set.features`) of the feature nearest `query`.
std::uint32_t nearestFeature(const FeatureTree& tree, const FeatureSet& set,
                             const FpfhFeature& query, float approximation) {
  std::uint32_t id = 0;
  float distance = 0.0F;
  nanoflann::KNNResultSet<float, std::uint32_t> result(1);
  result.init(&id, &distance);
  tree.findNeighbors(result, query.data(), nanoflann::SearchParams(32, approximation));
  return set.ids[id];
}

}  // namespace

std::vector<FpfhFeature> computeFpfh(RegistrationCloud& cloud, const FpfhConfig& config) {
  const std::vector<std::vector<Neighbor>> neighbours = neighbourhoods(cloud, config);
  std::vector<FpfhFeature> spfhs(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) spfhs[i] = spfh(cloud, i, neighbours[i]);
  std::vector<FpfhFeature> features(cloud.size(), FpfhFeature::Zero());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (neighbours[i].size() < 2) continue;
    FpfhFeature blended = FpfhFeature::Zero();
    for (const Neighbor& n : neighbours[i]) {
      const double distance = std::max(std::sqrt(n.squared_distance), 1e-3);
      blended += spfhs[n.index] * static_cast<float>(1.0 / distance);
    }
    normalise(blended);  // the neighbours' mean shape, as much as the point's own
    features[i] = spfhs[i] + blended;
    normalise(features[i]);
  }
  return features;
}

std::vector<Correspondence> matchFeatures(const std::vector<FpfhFeature>& source,
                                          const std::vector<FpfhFeature>& target,
                                          double approximation) {
  const auto eps = static_cast<float>(std::max(approximation, 0.0));
  const FeatureSet source_set = featureSet(source);
  const FeatureSet target_set = featureSet(target);
  std::vector<Correspondence> pairs;
  if (source_set.ids.empty() || target_set.ids.empty()) return pairs;
  const FeatureTree source_tree(33, source_set, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  const FeatureTree target_tree(33, target_set, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  for (const std::uint32_t s : source_set.ids) {
    const std::uint32_t t = nearestFeature(target_tree, target_set, source[s], eps);
    if (nearestFeature(source_tree, source_set, target[t], eps) == s) pairs.push_back({s, t});
  }
  return pairs;
}

}  // namespace dcl::registration
