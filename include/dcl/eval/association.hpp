#pragma once

/// Pairing an estimated trajectory with its ground truth, as evo's `associate_trajectories`
/// does (by nearest stamp) or as the KITTI devkit does (by index).

#include <cstddef>
#include <string_view>
#include <vector>

#include <dcl/core/trajectory.hpp>

namespace dcl::eval {

/// How estimate and ground-truth poses are paired.
enum class AssociationMode {
  timestamp,  ///< nearest stamp within a tolerance (TUM files, evo's default for stamped data)
  index,      ///< pose i with pose i (KITTI files, which carry no stamps)
};

/// "timestamp" or "index".
std::string_view toString(AssociationMode mode);

/// Parses "timestamp" or "index"; throws core::Error naming the accepted names otherwise.
AssociationMode parseAssociationMode(std::string_view name);

/// Settings of the association; the defaults are evo's (`--t_max_diff 0.01`, `--t_offset 0`).
struct AssociationOptions {
  AssociationMode mode = AssociationMode::timestamp;  ///< default: pair by nearest stamp
  double max_diff = 0.01;  ///< seconds; default 0.01, largest accepted |t_gt - (t_est + offset)|
  double offset = 0.0;     ///< seconds; default 0, added to the estimate's stamps before matching
};

/// Estimate and ground truth reduced to their associated poses: pose k of `estimate` goes with
/// pose k of `ground_truth`.
struct Association {
  core::Trajectory estimate;                ///< associated estimate poses, in pair order
  core::Trajectory ground_truth;            ///< associated ground-truth poses, in pair order
  std::vector<std::size_t> estimate_index;  ///< index of each pair's pose in the input estimate
  std::vector<std::size_t>
      ground_truth_index;  ///< index of each pair's pose in the input ground truth

  /// The number of pairs.
  [[nodiscard]] std::size_t size() const { return estimate.size(); }
};

/// Pairs by nearest stamp the way evo's `associate_trajectories(gt, est)` does: each pose of
/// the shorter trajectory (the estimate when both are equally long) takes the pose of the
/// longer one nearest in time, kept when within `max_diff`; the longer one's poses may be used
/// twice. Throws core::Error naming both stamp ranges and counts when nothing associates.
Association associateByTimestamp(const core::Trajectory& estimate,
                                 const core::Trajectory& ground_truth, double max_diff = 0.01,
                                 double offset = 0.0);

/// Pairs pose i with pose i. Throws core::Error when the lengths differ or both are empty.
Association associateByIndex(const core::Trajectory& estimate,
                             const core::Trajectory& ground_truth);

/// Pairs by the mode of `options`.
Association associate(const core::Trajectory& estimate, const core::Trajectory& ground_truth,
                      const AssociationOptions& options = {});

}  // namespace dcl::eval
