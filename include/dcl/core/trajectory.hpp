#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <vector>

namespace dcl::core {

/// Timestamped poses T_world_body of one robot, in time order.
class Trajectory {
 public:
  Trajectory() = default;
  Trajectory(std::vector<double> stamps, std::vector<Eigen::Isometry3d> poses);

  /// Appends a pose; stamps should not decrease (see `isSorted`).
  void push_back(double stamp, const Eigen::Isometry3d& T_world_body);
  void reserve(std::size_t n);

  [[nodiscard]] std::size_t size() const { return poses_.size(); }
  [[nodiscard]] bool empty() const { return poses_.empty(); }
  [[nodiscard]] double stamp(std::size_t i) const { return stamps_[i]; }
  [[nodiscard]] const Eigen::Isometry3d& pose(std::size_t i) const { return poses_[i]; }
  [[nodiscard]] Eigen::Isometry3d& pose(std::size_t i) { return poses_[i]; }
  [[nodiscard]] const std::vector<double>& stamps() const { return stamps_; }
  [[nodiscard]] const std::vector<Eigen::Isometry3d>& poses() const { return poses_; }

  /// True when the stamps never decrease.
  [[nodiscard]] bool isSorted() const;

  /// The pose at time `t`, interpolated between the two poses around it
  /// (linear translation, slerp rotation); none outside [first, last] stamp.
  [[nodiscard]] std::optional<Eigen::Isometry3d> at(double t) const;

  /// Cumulative path length at each pose (0 at the first), metres.
  [[nodiscard]] std::vector<double> distances() const;

  /// Total path length, metres.
  [[nodiscard]] double length() const;

  /// Every pose left-multiplied by `T_new_world` (a change of world frame).
  void transformWorld(const Eigen::Isometry3d& T_new_world);

  /// Every pose right-multiplied by `T_body_sensor` (a change of body frame).
  void transformBody(const Eigen::Isometry3d& T_body_sensor);

 private:
  std::vector<double> stamps_;
  std::vector<Eigen::Isometry3d> poses_;
};

}  // namespace dcl::core
