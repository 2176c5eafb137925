#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/format.h>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/odometry/external_odometry.hpp>

namespace dcl::odometry {
namespace {

/// Below this distance (m) a step counts as this long in the motion covariance,
/// so a robot standing still still reports some uncertainty.
constexpr double kMinCovarianceDistance = 0.1;

/// T_body_sensor of a validated config.
Eigen::Isometry3d bodySensorOf(const ExternalOdometryConfig& config) {
  validate(config);
  const Eigen::Matrix<double, 7, 1>& v = config.T_body_sensor;
  return core::makePose(v.head<3>(), Eigen::Quaterniond(v[6], v[3], v[4], v[5]));
}

/// Rigid poses: KITTI files print rotations to 7 digits.
core::Trajectory projected(core::Trajectory trajectory) {
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    Eigen::Isometry3d& T = trajectory.pose(i);
    T.linear() = core::projectToSO3(T.linear());
  }
  return trajectory;
}

}  // namespace

void validate(const ExternalOdometryConfig& config) {
  core::checkConfig(config, "external odometry config");
}

ExternalOdometry::ExternalOdometry(core::Trajectory T_world_body,
                                   const ExternalOdometryConfig& config)
    : T_world_body_(projected(std::move(T_world_body))),
      T_body_sensor_(bodySensorOf(config)),
      config_(config) {
  if (T_world_body_.empty()) throw core::Error("external odometry: the trajectory is empty");
  if (!T_world_body_.isSorted()) {
    throw core::Error("external odometry: the trajectory's stamps decrease");
  }
}

ExternalOdometry::ExternalOdometry(Streaming, const ExternalOdometryConfig& config)
    : T_body_sensor_(bodySensorOf(config)), config_(config) {}

ExternalOdometry ExternalOdometry::streaming(const ExternalOdometryConfig& config) {
  return ExternalOdometry(Streaming{}, config);
}

bool ExternalOdometry::append(double stamp, const Eigen::Isometry3d& T_world_body) {
  if (!std::isfinite(stamp) || !T_world_body.matrix().allFinite()) return false;
  if (!T_world_body_.empty() && stamp <= T_world_body_.stamps().back()) return false;
  // Let go of the poses before the one that brackets the last frame: a live
  // front-end sends them for hours.
  constexpr std::size_t kMostKept = 4096;
  if (T_world_body_.size() >= kMostKept && last_stamp_) {
    core::Trajectory kept;
    const auto& stamps = T_world_body_.stamps();
    std::size_t first = 0;
    while (first + 1 < stamps.size() && stamps[first + 1] <= *last_stamp_) ++first;
    for (std::size_t i = first; i < stamps.size(); ++i)
      kept.push_back(stamps[i], T_world_body_.pose(i));
    T_world_body_ = std::move(kept);
  }
  core::Trajectory one;
  one.push_back(stamp, T_world_body);
  T_world_body_.push_back(stamp, projected(std::move(one)).pose(0));
  return true;
}

void ExternalOdometry::requireOverlap(double first_stamp, double last_stamp) const {
  if (first_stamp <= lastStamp() && last_stamp >= firstStamp()) return;
  throw core::Error(fmt::format(
      "external odometry: its poses span {:.6f} .. {:.6f} s, the scans {:.6f} .. {:.6f} s: no "
      "scan falls in the poses' time range (are they on the same clock?)",
      firstStamp(), lastStamp(), first_stamp, last_stamp));
}

OdometryResult ExternalOdometry::process(double stamp, const core::PointCloud& /*scan*/) {
  if (!std::isfinite(stamp)) return held(stamp, "stamp is not finite");
  if (last_stamp_ && stamp < *last_stamp_) return held(stamp, "stamp goes backwards");
  const std::optional<Eigen::Isometry3d> T_world_body = T_world_body_.at(stamp);
  if (!T_world_body) return held(stamp, "stamp outside the external trajectory");
  const Eigen::Isometry3d T_world_sensor = *T_world_body * T_body_sensor_;
  if (!T_world_odom_) T_world_odom_ = T_world_sensor;
  const Eigen::Isometry3d T_odom_sensor = T_world_odom_->inverse() * T_world_sensor;
  OdometryResult result;
  result.stamp = stamp;
  result.T_odom_sensor = T_odom_sensor;
  result.covariance = motionCovariance(T_odom_sensor_.inverse() * T_odom_sensor);
  result.health.accepted = true;
  result.health.converged = true;
  T_odom_sensor_ = T_odom_sensor;
  last_stamp_ = stamp;
  return result;
}

OdometryResult ExternalOdometry::held(double stamp, std::string problem) const {
  OdometryResult result;
  result.stamp = stamp;
  result.T_odom_sensor = T_odom_sensor_;
  result.covariance = motionCovariance(Eigen::Isometry3d::Identity());
  result.health.problem = std::move(problem);
  return result;
}

core::Matrix6d ExternalOdometry::motionCovariance(const Eigen::Isometry3d& T_step) const {
  // A random walk in distance: variances grow linearly with the metres moved.
  const double d = std::max(T_step.translation().norm(), kMinCovarianceDistance);
  core::Vector6d variances;
  variances.head<3>().setConstant(config_.translation_sigma * config_.translation_sigma * d);
  variances.tail<3>().setConstant(config_.rotation_sigma * config_.rotation_sigma * d);
  return variances.asDiagonal();
}

}  // namespace dcl::odometry
