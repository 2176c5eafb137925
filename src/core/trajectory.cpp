#include <algorithm>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/core/trajectory.hpp>

namespace dcl::core {

Trajectory::Trajectory(std::vector<double> stamps, std::vector<Eigen::Isometry3d> poses)
    : stamps_(std::move(stamps)), poses_(std::move(poses)) {
  if (stamps_.size() != poses_.size()) {
    throw Error("Trajectory: " + std::to_string(stamps_.size()) + " stamps but " +
                std::to_string(poses_.size()) + " poses");
  }
}

void Trajectory::push_back(double stamp, const Eigen::Isometry3d& T_world_body) {
  stamps_.push_back(stamp);
  poses_.push_back(T_world_body);
}

void Trajectory::reserve(std::size_t n) {
  stamps_.reserve(n);
  poses_.reserve(n);
}

bool Trajectory::isSorted() const {
  return std::is_sorted(stamps_.begin(), stamps_.end());
}

std::optional<Eigen::Isometry3d> Trajectory::at(double t) const {
  if (empty() || t < stamps_.front() || t > stamps_.back()) return std::nullopt;
  const auto upper = std::lower_bound(stamps_.begin(), stamps_.end(), t);
  const auto j = static_cast<std::size_t>(upper - stamps_.begin());
  if (stamps_[j] == t || j == 0) return poses_[j];
  const std::size_t i = j - 1;
  const double span = stamps_[j] - stamps_[i];
  const double alpha = span > 0.0 ? (t - stamps_[i]) / span : 0.0;
  return interpolate(poses_[i], poses_[j], alpha);
}

std::vector<double> Trajectory::distances() const {
  std::vector<double> d(size(), 0.0);
  for (std::size_t i = 1; i < size(); ++i) {
    d[i] = d[i - 1] + (poses_[i].translation() - poses_[i - 1].translation()).norm();
  }
  return d;
}

double Trajectory::length() const {
  return empty() ? 0.0 : distances().back();
}

void Trajectory::transformWorld(const Eigen::Isometry3d& T_new_world) {
  for (auto& T : poses_) T = T_new_world * T;
}

void Trajectory::transformBody(const Eigen::Isometry3d& T_body_sensor) {
  for (auto& T : poses_) T = T * T_body_sensor;
}

}  // namespace dcl::core
