#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include <dcl/odometry/lidar_odometry.hpp>
#include <dcl/odometry/preprocessing.hpp>

namespace dcl::odometry {
namespace {

/// A note on points dropped as unusable; empty when none were.
std::string droppedNote(const CleanScan& clean) {
  if (clean.non_finite == 0 && clean.bad_time == 0) return {};
  return "dropped " + std::to_string(clean.non_finite + clean.bad_time) +
         " points with non-finite coordinates or times";
}

FrameHealth healthOf(const RegistrationResult& registration, std::string problem) {
  FrameHealth health;
  health.problem = std::move(problem);
  health.converged = registration.converged;
  health.degenerate = registration.degenerate;
  health.iterations = registration.iterations;
  health.correspondences = registration.inliers;
  health.residual = registration.rmse;
  return health;
}

/// Appends `note` to a problem description.
void addProblem(std::string& problem, const std::string& note) {
  if (note.empty()) return;
  problem += problem.empty() ? note : "; " + note;
}

}  // namespace

LidarOdometry::LidarOdometry(const OdometryConfig& config)
    : config_(config),
      map_(config.mapVoxelSize(), config.max_points_per_voxel),
      threshold_(config.threshold, config.max_range) {}

OdometryResult LidarOdometry::process(double stamp, const core::PointCloud& scan) {
  if (auto problem = checkStamp(stamp)) return skipped(stamp, std::move(*problem));
  const CleanScan clean = cleanScan(scan, config_.min_range, config_.max_range);
  if (clean.cloud.size() < config_.min_points) {
    return skipped(stamp, "too few usable points (" + std::to_string(clean.cloud.size()) + " of " +
                              std::to_string(scan.size()) + ")");
  }
  // 1. Undo the sweep's motion with the last frame's velocity, to mid-sweep;
  // 2. two resolutions (KISS-ICP): the map's, and a coarser one to register.
  const double t_mid = config_.deskew ? sweepMidTime(clean.cloud) : 0.0;
  std::vector<Eigen::Vector3d> frame = thinnedFrame(clean.cloud, t_mid);
  const std::vector<Eigen::Vector3d> source = voxelDownsample(frame, 1.5 * config_.mapVoxelSize());
  // 3. Constant-velocity prediction of the mid-sweep pose.
  const Eigen::Isometry3d T_predicted = predictReference(stamp + t_mid);
  // 4. Register against the local map (the first frame starts the map).
  RegistrationResult registration;
  bool redeskewed = false;
  registration.T_target_source = T_predicted;
  registration.converged = true;
  if (!map_.empty()) {
    registration = registerScan(source, map_, T_predicted, frameIcpConfig(threshold_.sigma()));
    // Until the robot has moved, sigma is only the initial guess, a gate of
    // metres: wide enough to catch an unknown first motion, but against a map
    // of one or two sparse sweeps its far pairs pull the pose centimetres off
    // (mostly in height), and that offset stays. Refine with the narrowest
    // gate the map's sampling allows, from where the wide pass ended.
    if (!threshold_.learned() && registration.inliers >= config_.icp.min_inliers) {
      registration = registerScan(source, map_, registration.T_target_source, frameIcpConfig(0.0));
    }
    redeskewed = registerAgainIfMotionChanged(clean.cloud, stamp, t_mid, registration, frame);
  }
  // 5. Check: too few correspondences means the pose would be a guess.
  OdometryResult result = skipped(stamp, droppedNote(clean));
  result.health = healthOf(registration, result.health.problem);
  result.health.redeskewed = redeskewed;
  if (!map_.empty() && registration.inliers < config_.icp.min_inliers) {
    addProblem(result.health.problem,
               "registration failed: " + std::to_string(registration.inliers) + " correspondences");
    return result;
  }
  if (registration.degenerate) {
    addProblem(result.health.problem,
               "degenerate registration (the scene constrains too few directions)");
  }
  // 6. Update velocity and threshold, then the map.
  const bool second_sweep = first_sweep_.has_value();
  if (map_.empty() && t_mid != 0.0) first_sweep_ = FirstSweep{clean.cloud, t_mid};
  commit(stamp, t_mid, registration.T_target_source, T_predicted);
  // The second sweep, like the first, was deskewed before any velocity was known.
  if (second_sweep) frame = thinnedFrame(clean.cloud, t_mid);
  growMap(frame);
  result.health.accepted = true;
  result.T_odom_sensor = T_odom_sensor_;
  result.covariance = covarianceOf(registration);
  result.registered = toCloud(frame);
  result.registered.transform(core::expSE3(t_mid * velocity_));  // mid-sweep to stamp
  return result;
}

Eigen::Isometry3d LidarOdometry::predictReference(double time) const {
  if (!last_reference_time_) return T_odom_reference_;
  return T_odom_reference_ * core::expSE3((time - *last_reference_time_) * velocity_);
}

std::optional<std::string> LidarOdometry::checkStamp(double stamp) const {
  if (!std::isfinite(stamp)) return "non-finite time stamp";
  if (last_stamp_ && stamp <= *last_stamp_) {
    return "time stamp " + std::to_string(stamp) + " not after the previous " +
           std::to_string(*last_stamp_);
  }
  return std::nullopt;
}

OdometryResult LidarOdometry::skipped(double stamp, std::string problem) const {
  OdometryResult result;
  result.stamp = stamp;
  result.health.problem = std::move(problem);
  // Report the constant-velocity prediction when the stamp moves forward, else hold.
  const bool forward = last_stamp_ && std::isfinite(stamp) && stamp > *last_stamp_;
  result.T_odom_sensor = forward ? predictReference(stamp) : T_odom_sensor_;
  result.covariance = core::Matrix6d::Identity() * config_.max_sigma * config_.max_sigma;
  return result;
}

IcpConfig LidarOdometry::frameIcpConfig(double sigma) const {
  IcpConfig icp = config_.icp;
  // A frame enters the map thinned to one point per half voxel, so even at the
  // true pose a source point's nearest map point lies up to about half a voxel
  // away. A gate below that rejects most correct pairs, and then the first
  // unpredicted turn after a stretch of steady motion (which shrinks sigma to
  // its floor) leaves too few pairs to pull the pose back: hence 3 sigma is
  // kept at least at the map's sampling spacing.
  const double sampling_sigma = 0.5 * config_.mapVoxelSize() / 3.0;
  const double gate_sigma = std::max(sigma, sampling_sigma);
  icp.max_correspondence_distance = 3.0 * gate_sigma;
  icp.kernel_scale = gate_sigma / 3.0;
  return icp;
}

core::Matrix6d LidarOdometry::covarianceOf(const RegistrationResult& registration) const {
  // Information scaled by the residual variance, bounded so that directions the
  // scene leaves open get max_sigma rather than infinity, plus a floor because
  // ICP's residuals are correlated and its raw covariance far too optimistic
  // (a lower floor about the spin axis z, which the scan pins best).
  const double noise = std::max(registration.rmse, 0.01);
  const double max_information = 1.0 / (config_.max_sigma * config_.max_sigma);
  const core::Matrix6d information =
      registration.information / (noise * noise) + max_information * core::Matrix6d::Identity();
  core::Matrix6d covariance = information.inverse();
  const double t2 = config_.min_translation_sigma * config_.min_translation_sigma;
  const double r2 = config_.min_rotation_sigma * config_.min_rotation_sigma;
  covariance.diagonal().head<3>().array() += t2;
  covariance.diagonal().segment<2>(3).array() += r2;
  covariance(5, 5) += config_.min_yaw_sigma * config_.min_yaw_sigma;
  return covariance;
}

std::vector<Eigen::Vector3d> LidarOdometry::thinnedFrame(
    const core::PointCloud& cloud, double t_mid,
    const std::optional<core::Vector6d>& velocity) const {
  const core::Vector6d v = config_.deskew ? velocity.value_or(velocity_) : core::Vector6d::Zero();
  return voxelDownsample(deskew(cloud, v, t_mid), 0.5 * config_.mapVoxelSize());
}

bool LidarOdometry::registerAgainIfMotionChanged(const core::PointCloud& cloud, double stamp,
                                                 double t_mid, RegistrationResult& registration,
                                                 std::vector<Eigen::Vector3d>& frame) const {
  // A sharp change of motion (braking into a turn) leaves the sweep deskewed
  // with a velocity the sensor no longer had, bent by up to half a sweep of
  // the difference, and the registration settles on the bent sweep. Deskew
  // it again with the motion it registered at, and register once more. Not
  // after a degenerate registration, whose motion along the open direction is
  // a guess; and the second pass is kept only if the sweep fits better.
  if (registration.inliers < config_.icp.min_inliers || registration.degenerate) return false;
  const auto velocity =
      redeskewVelocity(stamp + t_mid, registration.T_target_source, sweepDuration(cloud));
  if (!velocity) return false;
  std::vector<Eigen::Vector3d> refined = thinnedFrame(cloud, t_mid, *velocity);
  RegistrationResult again =
      registerScan(voxelDownsample(refined, 1.5 * config_.mapVoxelSize()), map_,
                   registration.T_target_source, frameIcpConfig(threshold_.sigma()));
  if (again.inliers < config_.icp.min_inliers || again.degenerate ||
      again.rmse >= registration.rmse) {
    return false;
  }
  registration = std::move(again);
  frame = std::move(refined);
  return true;
}

std::optional<core::Vector6d> LidarOdometry::redeskewVelocity(
    double reference_time, const Eigen::Isometry3d& T_odom_reference, double duration) const {
  // Not before a velocity is known (the first two sweeps have their own fix-up).
  if (!config_.deskew || config_.redeskew_error <= 0.0 || duration <= 0.0 ||
      !last_reference_time_ || first_sweep_ || reference_time <= *last_reference_time_) {
    return std::nullopt;
  }
  const core::Vector6d registered = core::logSE3(T_odom_reference_.inverse() * T_odom_reference) /
                                    (reference_time - *last_reference_time_);
  const core::Vector6d change = registered - velocity_;
  constexpr double kLever = 10.0;  // m, the point whose displacement is judged
  const double error =
      0.5 * duration * (change.head<3>().norm() + kLever * change.tail<3>().norm());
  if (error <= config_.redeskew_error) return std::nullopt;
  return registered;
}

void LidarOdometry::commit(double stamp, double t_mid, const Eigen::Isometry3d& T_odom_reference,
                           const Eigen::Isometry3d& T_predicted) {
  const double reference_time = stamp + t_mid;
  const Eigen::Isometry3d T_last_current = T_odom_reference_.inverse() * T_odom_reference;
  if (last_reference_time_) {
    velocity_ = core::logSE3(T_last_current) / (reference_time - *last_reference_time_);
    threshold_.update(T_predicted.inverse() * T_odom_reference,
                      T_last_current.translation().norm());
  }
  T_odom_reference_ = T_odom_reference;
  if (first_sweep_ && last_reference_time_) redoFirstSweep();
  last_reference_time_ = reference_time;
  T_odom_sensor_ = T_odom_reference_ * core::expSE3(-t_mid * velocity_);
  last_stamp_ = stamp;
}

void LidarOdometry::growMap(std::span<const Eigen::Vector3d> frame) {
  map_.addPoints(frame, T_odom_reference_);
  map_.removeFarFrom(T_odom_reference_.translation(), config_.max_range);
}

void LidarOdometry::redoFirstSweep() {
  // The first sweep was taken without a velocity: it went into the map
  // undeskewed, and its middle became the odometry frame. With the first
  // velocity known, deskew it properly and move the frame to its stamp.
  const Eigen::Isometry3d T_stamp_mid = core::expSE3(first_sweep_->t_mid * velocity_);
  map_.clear();
  map_.addPoints(thinnedFrame(first_sweep_->cloud, first_sweep_->t_mid), T_stamp_mid);
  T_odom_reference_ = T_stamp_mid * T_odom_reference_;
  first_sweep_.reset();
}

}  // namespace dcl::odometry
