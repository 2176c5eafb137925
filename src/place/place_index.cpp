#include "dcl/place/place_index.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>

#include "key_tree.hpp"

namespace dcl::place {

void validate(const PlaceIndexConfig& config) {
  core::checkConfig(config, "place index config");
}

PlaceIndex::PlaceIndex(std::shared_ptr<const Descriptor> descriptor, core::RobotId robot,
                       const PlaceIndexConfig& config)
    : descriptor_(std::move(descriptor)),
      robot_(robot),
      config_(config),
      tree_(std::make_unique<detail::KeyTree>()) {
  if (!descriptor_) throw core::Error("PlaceIndex: no descriptor");
  validate(config_);
}

PlaceIndex::~PlaceIndex() = default;
PlaceIndex::PlaceIndex(PlaceIndex&&) noexcept = default;
PlaceIndex& PlaceIndex::operator=(PlaceIndex&&) noexcept = default;

void PlaceIndex::add(core::KeyframeId id, std::shared_ptr<const PlaceDescriptor> description) {
  if (!description) throw core::Error("PlaceIndex::add: no description");
  if (description->kind() != descriptor_->kind()) {
    throw core::Error("PlaceIndex::add: a " + std::string(toString(description->kind())) +
                      " description in a " + std::string(toString(descriptor_->kind())) + " index");
  }
  const std::span<const float> key = description->key();
  if (key.size() != descriptor_->keySize()) {
    throw core::Error("PlaceIndex::add: key of length " + std::to_string(key.size()) +
                      ", expected " + std::to_string(descriptor_->keySize()));
  }
  tree_->add(key);
  ids_.push_back(id);
  descriptions_.push_back(std::move(description));
}

std::size_t PlaceIndex::eligible(QueryScope scope) const {
  if (scope == QueryScope::kOtherRobot) return size();
  return size() > config_.exclude_recent ? size() - config_.exclude_recent : 0;
}

std::vector<PlaceCandidate> PlaceIndex::rank(const PlaceDescriptor& query, QueryScope scope) const {
  // Stage 1: the k nearest rotation-invariant keys (cheap, L2 in the k-d tree).
  const auto nearest = tree_->nearest(query.key(), config_.candidates, eligible(scope));
  // Stage 2: the full match on those only (paper: the Hamming distance of Eq. 6
  // is too heavy to compute against the whole history).
  std::vector<PlaceCandidate> out;
  out.reserve(nearest.size());
  for (const auto& [slot, squared] : nearest) {
    PlaceCandidate c;
    c.keyframe = {robot_, ids_[slot]};
    c.slot = slot;
    c.match = descriptor_->match(query, *descriptions_[slot]);
    c.key_distance = std::sqrt(squared);
    out.push_back(c);
  }
  std::stable_sort(out.begin(), out.end(), [](const PlaceCandidate& a, const PlaceCandidate& b) {
    return a.match.distance < b.match.distance;
  });
  return out;
}

std::optional<PlaceCandidate> PlaceIndex::query(const PlaceDescriptor& query,
                                                QueryScope scope) const {
  const auto ranked = rank(query, scope);
  if (ranked.empty() || !(ranked.front().match.distance < config_.max_distance)) {
    return std::nullopt;
  }
  return ranked.front();
}

DistinctMatch PlaceIndex::queryDistinct(const PlaceDescriptor& query,
                                        const KeyframePosition& position, QueryScope scope) const {
  const auto ranked = rank(query, scope);
  DistinctMatch out;
  if (ranked.empty() || !(ranked.front().match.distance < config_.max_distance)) return out;
  const PlaceCandidate& best = ranked.front();
  if (config_.distinct_ratio >= 1.0) {
    out.best = best;
    return out;
  }
  const Eigen::Vector3d at = position(best.keyframe.keyframe);
  for (std::size_t i = 1; i < ranked.size(); ++i) {
    if (config_.beats(best.match.distance, ranked[i].match.distance)) break;
    if ((position(ranked[i].keyframe.keyframe) - at).norm() >= config_.distinct_separation) {
      out.refused = best;
      return out;
    }
  }
  out.best = best;
  return out;
}

DistinctMatch PlaceIndex::queryDistinct(const PlaceDescriptor& query,
                                        const KeyframePosition& position,
                                        std::optional<float> look_alike) const {
  DistinctMatch out = queryDistinct(query, position, QueryScope::kOtherRobot);
  if (!out.best || !look_alike) return out;
  if (!config_.beats(out.best->match.distance, *look_alike)) {
    out.refused = out.best;
    out.best.reset();
  }
  return out;
}

std::optional<float> PlaceIndex::lookAlikeDistance(const PlaceDescriptor& query,
                                                   const Eigen::Vector3d& at,
                                                   const KeyframePosition& position,
                                                   std::size_t before) const {
  const auto alikes = lookAlikes(query, at, position, before);
  if (alikes.empty()) return std::nullopt;
  return alikes.front().second;
}

std::vector<std::pair<core::KeyframeId, float>> PlaceIndex::lookAlikes(
    const PlaceDescriptor& query, const Eigen::Vector3d& at, const KeyframePosition& position,
    std::size_t before) const {
  std::vector<std::pair<core::KeyframeId, float>> out;
  for (const auto& [slot, squared] :
       tree_->nearest(query.key(), config_.candidates, std::min(before, size()))) {
    if ((position(ids_[slot]) - at).norm() < config_.distinct_separation) continue;
    out.emplace_back(ids_[slot],
                     static_cast<float>(descriptor_->match(query, *descriptions_[slot]).distance));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const auto& x, const auto& y) { return x.second < y.second; });
  return out;
}

}  // namespace dcl::place
