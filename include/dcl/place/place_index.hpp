#pragma once

/// The place index of one robot's keyframes (paper §III-B, "Search"): a k-d tree
/// over the descriptors' rotation-invariant keys (the LiDAR-Iris row key, Eq. 5)
/// finds the k nearest keys, then the full match (phase-correlation shift and
/// masked Hamming distance, Eq. 3-4 and 6) re-ranks them; the closest candidate
/// below the acceptance threshold is the loop candidate.
///
/// A robot keeps one index of its own keyframes and one per neighbour, of the
/// descriptors that neighbour sent. Keyframes are added as they arrive; the
/// tree grows incrementally (a logarithmic set of static trees), so a query
/// never waits for a full rebuild.

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/place/descriptor.hpp>

namespace dcl::place {

namespace detail {
class KeyTree;
}

/// How an index searches (DESIGN.md §6).
struct PlaceIndexConfig {
  static constexpr std::size_t kMaxCandidates = 1000;  ///< candidates at most (each is matched)

  /// Nearest keys re-ranked by the full match (paper and DESIGN §6: 10).
  std::size_t candidates = 10;
  /// Accept the best candidate when its match distance is below this. The paper
  /// chose 0.3 for LiDAR-Iris (0.35 for Scan Context) from its PR curves.
  double max_distance = 0.3;
  /// Own keyframes, the most recently added, that an intra-robot query skips:
  /// they are the robot's immediate past, not a revisit (50 keyframes, about
  /// 50 m at the paper's 1 m keyframe spacing).
  std::size_t exclude_recent = 50;
  /// A neighbour's scan is matched to one place only if it is clearly that
  /// place: a stored keyframe elsewhere (`distinct_separation` m or more from the
  /// best, by the index robot's own estimate) whose distance is within the best's
  /// divided by this ratio makes the match ambiguous, and it is refused.
  /// Repeated structure (identical blocks, a corridor) matches every repeat
  /// almost equally, and the loops it yields agree with each other whether
  /// right or wrong; a real place usually beats its look-alikes by a margin.
  /// RobotNode applies the same ratio to each robot's own repeats of the
  /// place (how closely its route passes a place like it elsewhere).
  /// 1: off (the paper).
  double distinct_ratio = 0.9;
  /// m, how far apart two stored keyframes must be to count as different places.
  double distinct_separation = 20.0;

  /// Whether a match at descriptor distance `match` clearly beats a look-alike
  /// of its place at distance `repeat` (distinct_ratio; always when off).
  [[nodiscard]] bool beats(double match, double repeat) const {
    return distinct_ratio >= 1.0 || match < distinct_ratio * repeat;
  }

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("candidates", candidates, "nearest keys re-ranked by the full match (paper: 10)")
        .within(1, kMaxCandidates);
    // Match distances lie in [0, 1]: 0 accepts nothing, 1 everything.
    v.field("max_distance", max_distance,
            "accept a match distance below this (paper: 0.3 LiDAR-Iris, 0.35 Scan Context)")
        .within(0.0, 1.0, core::Interval::open_low);
    v.field("exclude_recent", exclude_recent,
            "most recent own keyframes skipped by intra-robot queries");
    v.field("distinct_ratio", distinct_ratio,
            "refuse a match when another place's distance is within the best's / this (1: off)")
        .within(0.0, 1.0, core::Interval::open_low);
    v.field("distinct_separation", distinct_separation,
            "m, stored keyframes this far apart are different places")
        .nonNegative();
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const PlaceIndexConfig& config);

/// Whose keyframes a query is looking for.
enum class QueryScope {
  kOtherRobot,  ///< a neighbour's descriptor against this index: every keyframe is eligible
  kSameRobot,   ///< the index's own robot: the most recent keyframes are skipped
};

/// A stored keyframe that matched a query.
struct PlaceCandidate {
  core::PoseKey keyframe;  ///< which robot's which keyframe
  std::size_t slot = 0;    ///< its position in the index (insertion order)
  Match match;             ///< full match: distance, yaw of T_query_candidate
  float key_distance = 0;  ///< L2 distance between the keys
};

/// Where the index robot estimates a stored keyframe to be (any fixed frame).
using KeyframePosition = std::function<Eigen::Vector3d(core::KeyframeId)>;

/// What a query that tells places apart found.
struct DistinctMatch {
  std::optional<PlaceCandidate> best;     ///< the match, when below the threshold and distinct
  std::optional<PlaceCandidate> refused;  ///< the match refused as ambiguous, if one was
};

/// One robot's keyframe descriptors, searchable by key and re-ranked by match.
class PlaceIndex {
 public:
  /// An empty index of robot `robot`'s keyframes, made and matched by `descriptor`.
  PlaceIndex(std::shared_ptr<const Descriptor> descriptor, core::RobotId robot,
             const PlaceIndexConfig& config = {});
  ~PlaceIndex();
  PlaceIndex(PlaceIndex&&) noexcept;
  PlaceIndex& operator=(PlaceIndex&&) noexcept;

  /// Adds keyframe `id`'s description; searchable by the next query. Throws
  /// core::Error when its kind or key length differs from the index's descriptor.
  void add(core::KeyframeId id, std::shared_ptr<const PlaceDescriptor> description);

  /// The candidates: up to `config.candidates` nearest keys, matched and sorted
  /// by match distance (closest first), no threshold applied.
  [[nodiscard]] std::vector<PlaceCandidate> rank(const PlaceDescriptor& query,
                                                 QueryScope scope = QueryScope::kOtherRobot) const;

  /// The closest candidate when its distance is below `config.max_distance`.
  [[nodiscard]] std::optional<PlaceCandidate> query(
      const PlaceDescriptor& query, QueryScope scope = QueryScope::kOtherRobot) const;

  /// As query(), but a match that another place (by `position`) nearly equals
  /// is refused as ambiguous (see PlaceIndexConfig::distinct_ratio).
  [[nodiscard]] DistinctMatch queryDistinct(const PlaceDescriptor& query,
                                            const KeyframePosition& position,
                                            QueryScope scope = QueryScope::kOtherRobot) const;

  /// queryDistinct for a neighbour's query that also knows the query's own
  /// look-alike distance (lookAlikeDistance on the neighbour's index): a
  /// match not clearly closer than the place the query resembles elsewhere
  /// on its own robot's route is refused as well. Repeated structure that one
  /// robot has passed twice makes any match of it ambiguous, even where the
  /// other robot holds only one of the repeats (the aliases of a repeated
  /// block three blocks apart, each robot having seen one of them).
  [[nodiscard]] DistinctMatch queryDistinct(const PlaceDescriptor& query,
                                            const KeyframePosition& position,
                                            std::optional<float> look_alike) const;

  /// The smallest match distance from `query`, a keyframe of this index's
  /// robot at `at` (its own estimate), to its keyframes stored before slot
  /// `before` that lie distinct_separation or more from it: how closely the
  /// place repeats elsewhere on the robot's route. None when no such keyframe
  /// is among the nearest keys.
  [[nodiscard]] std::optional<float> lookAlikeDistance(const PlaceDescriptor& query,
                                                       const Eigen::Vector3d& at,
                                                       const KeyframePosition& position,
                                                       std::size_t before) const;

  /// The keyframes lookAlikeDistance compares `query` with, each with its
  /// match distance, closest first: those among the nearest keys stored
  /// before slot `before` that lie distinct_separation or more from `at`.
  [[nodiscard]] std::vector<std::pair<core::KeyframeId, float>> lookAlikes(
      const PlaceDescriptor& query, const Eigen::Vector3d& at, const KeyframePosition& position,
      std::size_t before) const;

  /// Number of keyframes stored.
  [[nodiscard]] std::size_t size() const { return ids_.size(); }
  /// The robot whose keyframes these are.
  [[nodiscard]] core::RobotId robot() const { return robot_; }
  /// The keyframe stored at `slot` (insertion order).
  [[nodiscard]] core::KeyframeId id(std::size_t slot) const { return ids_.at(slot); }
  /// The description stored at `slot`.
  [[nodiscard]] const PlaceDescriptor& description(std::size_t slot) const {
    return *descriptions_.at(slot);
  }
  /// The configuration.
  [[nodiscard]] const PlaceIndexConfig& config() const { return config_; }

 private:
  [[nodiscard]] std::size_t eligible(QueryScope scope) const;

  std::shared_ptr<const Descriptor> descriptor_;
  core::RobotId robot_;
  PlaceIndexConfig config_;
  std::vector<core::KeyframeId> ids_;
  std::vector<std::shared_ptr<const PlaceDescriptor>> descriptions_;
  std::unique_ptr<detail::KeyTree> tree_;
};

}  // namespace dcl::place
