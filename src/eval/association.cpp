#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/eval/association.hpp>

namespace dcl::eval {

namespace {

// The index of the stamp nearest `t` in `stamps` (shifted by `shift`), the first one on a tie,
// as np.argmin(np.abs(stamps + shift - t)) picks it.
std::size_t nearestIndex(const std::vector<double>& stamps, double shift, double t) {
  std::size_t best = 0;
  double best_diff = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    const double diff = std::abs((stamps[k] + shift) - t);
    if (diff < best_diff) {
      best_diff = diff;
      best = k;
    }
  }
  return best;
}

// The same on sorted stamps, by bisection: the candidates are the last stamp below `t` and
// the first one at or above it; the earliest of equal stamps wins a tie, as argmin's does.
std::size_t nearestIndexSorted(const std::vector<double>& shifted, double t) {
  const auto upper = std::lower_bound(shifted.begin(), shifted.end(), t);
  std::size_t j = static_cast<std::size_t>(upper - shifted.begin());
  if (j == shifted.size()) --j;
  if (j > 0 && std::abs(shifted[j - 1] - t) <= std::abs(shifted[j] - t)) --j;
  while (j > 0 && shifted[j - 1] == shifted[j]) --j;
  return j;
}

std::string describeStamps(const core::Trajectory& trajectory) {
  if (trajectory.empty()) return "no poses";
  return fmt::format("{} poses, stamps {:.6f} .. {:.6f} s", trajectory.size(),
                     trajectory.stamps().front(), trajectory.stamps().back());
}

void appendPair(Association& out, const core::Trajectory& estimate,
                const core::Trajectory& ground_truth, std::size_t i_est, std::size_t i_gt) {
  out.estimate.push_back(estimate.stamp(i_est), estimate.pose(i_est));
  out.ground_truth.push_back(ground_truth.stamp(i_gt), ground_truth.pose(i_gt));
  out.estimate_index.push_back(i_est);
  out.ground_truth_index.push_back(i_gt);
}

// evo's matching_time_indices: for each short stamp, the nearest long stamp (shifted).
std::vector<std::pair<std::size_t, std::size_t>> matchStamps(
    const std::vector<double>& short_stamps, const std::vector<double>& long_stamps, double shift,
    double max_diff) {
  std::vector<double> shifted(long_stamps);
  for (double& t : shifted) t += shift;
  const bool sorted = std::is_sorted(shifted.begin(), shifted.end());
  std::vector<std::pair<std::size_t, std::size_t>> matches;
  for (std::size_t i = 0; i < short_stamps.size(); ++i) {
    const double t = short_stamps[i];
    const std::size_t j =
        sorted ? nearestIndexSorted(shifted, t) : nearestIndex(long_stamps, shift, t);
    if (std::abs(shifted[j] - t) <= max_diff) matches.emplace_back(i, j);
  }
  return matches;
}

}  // namespace

std::string_view toString(AssociationMode mode) {
  return mode == AssociationMode::index ? "index" : "timestamp";
}

AssociationMode parseAssociationMode(std::string_view name) {
  if (name == "timestamp") return AssociationMode::timestamp;
  if (name == "index") return AssociationMode::index;
  throw core::Error(fmt::format("unknown association '{}' (expected timestamp or index)", name));
}

Association associateByTimestamp(const core::Trajectory& estimate,
                                 const core::Trajectory& ground_truth, double max_diff,
                                 double offset) {
  // evo matches the shorter trajectory into the longer one; the offset moves the estimate.
  const bool estimate_longer = estimate.size() > ground_truth.size();
  const auto& shorter = estimate_longer ? ground_truth : estimate;
  const auto& longer = estimate_longer ? estimate : ground_truth;
  const double shift = estimate_longer ? offset : -offset;
  Association out;
  if (!shorter.empty() && !longer.empty()) {
    for (const auto& [i_short, i_long] :
         matchStamps(shorter.stamps(), longer.stamps(), shift, max_diff)) {
      if (estimate_longer)
        appendPair(out, estimate, ground_truth, i_long, i_short);
      else
        appendPair(out, estimate, ground_truth, i_short, i_long);
    }
  }
  if (out.size() == 0) {
    throw core::Error(fmt::format(
        "no matching timestamps between the estimate ({}) and the ground truth ({}) within "
        "max. diff {} s and offset {} s",
        describeStamps(estimate), describeStamps(ground_truth), max_diff, offset));
  }
  return out;
}

Association associateByIndex(const core::Trajectory& estimate,
                             const core::Trajectory& ground_truth) {
  if (estimate.size() != ground_truth.size()) {
    throw core::Error(
        fmt::format("cannot pair by index: the estimate has {} poses but the ground truth {}",
                    estimate.size(), ground_truth.size()));
  }
  if (estimate.empty()) throw core::Error("cannot pair by index: both trajectories are empty");
  Association out;
  for (std::size_t i = 0; i < estimate.size(); ++i) appendPair(out, estimate, ground_truth, i, i);
  return out;
}

Association associate(const core::Trajectory& estimate, const core::Trajectory& ground_truth,
                      const AssociationOptions& options) {
  if (options.mode == AssociationMode::index) return associateByIndex(estimate, ground_truth);
  return associateByTimestamp(estimate, ground_truth, options.max_diff, options.offset);
}

}  // namespace dcl::eval
