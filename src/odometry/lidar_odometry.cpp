#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/odometry/lidar_odometry.hpp>
#include <dcl/odometry/preprocessing.hpp>

namespace dcl::odometry {
namespace {

/// Accepted frames from one free-space carving of the map to the next.
constexpr int kFramesPerCarving = 4;

/// What one sweep sees in each direction: the nearest return per cell of 1 deg
/// of azimuth by 1 deg of elevation, around the sensor. A map point the sweep
/// sees through lies nearer than every return of its cell and the eight around
/// it, by a margin: the beams passed where it was and went on. Cells without a
/// return (sky, dropouts, between a sparse sensor's rings) tell nothing, so a
/// point whose own cell is empty stays, and so does any point in front of or
/// beside a nearer return (an occluder, a surface seen at grazing incidence).
class FreeSpace {
 public:
  explicit FreeSpace(std::span<const Eigen::Vector3d> points)
      : nearest_(static_cast<std::size_t>(kRows * kColumns),
                 std::numeric_limits<float>::infinity()) {
    for (const Eigen::Vector3d& p : points) {
      const auto cell = cellOf(p);
      if (!cell) continue;
      float& n = nearest_[*cell];
      n = std::min(n, static_cast<float>(p.norm()));
    }
  }

  /// True when the sweep saw past `p` (in the sweep's sensor frame) all round.
  [[nodiscard]] bool seesThrough(const Eigen::Vector3d& p) const {
    const double range = p.norm();
    const auto cell = cellOf(p);
    if (!cell || !std::isfinite(nearest_[*cell])) return false;
    const int row = static_cast<int>(*cell / kColumns), column = static_cast<int>(*cell % kColumns);
    float nearest = std::numeric_limits<float>::infinity();
    for (int r = std::max(0, row - 1); r <= std::min(kRows - 1, row + 1); ++r) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int c = (column + dc + kColumns) % kColumns;
        nearest = std::min(nearest, nearest_[static_cast<std::size_t>(r * kColumns + c)]);
      }
    }
    return std::isfinite(nearest) && nearest > range + kMargin + kMarginShare * range;
  }

 private:
  static constexpr int kColumns = 360;          // 1 deg of azimuth
  static constexpr int kRows = 120;             // 1 deg of elevation, -60 to +60 deg
  static constexpr double kMargin = 0.3;        // m, plus
  static constexpr double kMarginShare = 0.05;  // of the range
  static constexpr double kMinRange = 1.0;      // m, nearer points are never judged

  [[nodiscard]] static std::optional<std::size_t> cellOf(const Eigen::Vector3d& p) {
    const double horizontal = std::hypot(p.x(), p.y());
    if (horizontal + std::abs(p.z()) < kMinRange) return std::nullopt;
    const double degrees = 180.0 / M_PI;
    const int row =
        static_cast<int>(std::floor(std::atan2(p.z(), horizontal) * degrees)) + kRows / 2;
    if (row < 0 || row >= kRows) return std::nullopt;
    int column = static_cast<int>(std::floor(std::atan2(p.y(), p.x()) * degrees)) + kColumns / 2;
    column = std::clamp(column, 0, kColumns - 1);
    return static_cast<std::size_t>(row * kColumns + column);
  }

  std::vector<float> nearest_;
};

}  // namespace
}  // namespace dcl::odometry

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

const OdometryConfig& validated(const OdometryConfig& config) {
  validate(config);
  return config;
}

/// Appends `note` to a problem description.
void addProblem(std::string& problem, const std::string& note) {
  if (note.empty()) return;
  problem += problem.empty() ? note : "; " + note;
}

}  // namespace

void validate(const OdometryConfig& config) {
  core::checkConfig(config, "odometry config");
}

LidarOdometry::LidarOdometry(const OdometryConfig& config)
    : config_(validated(config)),
      map_(config.mapVoxelSize(), config.max_points_per_voxel),
      threshold_(config.threshold, config.max_range) {}

void LidarOdometry::observeUp(const Eigen::Vector3d& up_sensor) {
  const double norm = up_sensor.norm();
  if (!config_.use_imu || !std::isfinite(norm) || norm < 1e-6)
    return;  // a reading that says nothing
  pending_up_ = up_sensor / norm;
}

OdometryResult LidarOdometry::process(double stamp, const core::PointCloud& scan) {
  const std::optional<Eigen::Vector3d> up = std::exchange(pending_up_, std::nullopt);
  if (auto problem = checkStamp(stamp)) return skipped(stamp, std::move(*problem));
  const CleanScan clean = cleanScan(scan, config_.min_range, config_.max_range);
  if (clean.cloud.size() < config_.min_points) {
    return skipped(stamp, "too few usable points (" + std::to_string(clean.cloud.size()) + " of " +
                              std::to_string(scan.size()) + ")");
  }
  // 1. The pose is estimated at mid-sweep (see T_odom_reference_), predicted
  // there under constant velocity.
  const double t_mid = config_.deskew ? sweepMidTime(clean.cloud) : 0.0;
  const Eigen::Isometry3d T_predicted = predictReference(stamp + t_mid);
  // 2. Register against the local map (the first frame starts the map): the
  // sweep deskewed with the last velocity, or with its own motion when that
  // changed sharply.
  FrameRegistration frame_registration;
  frame_registration.registration.T_target_source = T_predicted;
  frame_registration.registration.converged = true;
  if (!map_.empty()) frame_registration = registerFrame(clean.cloud, stamp, t_mid, T_predicted);
  const RegistrationResult& registration = frame_registration.registration;
  // 3. Check: too few correspondences means the pose would be a guess.
  OdometryResult result = skipped(stamp, droppedNote(clean));
  result.health = healthOf(registration, result.health.problem);
  if (!map_.empty() && registration.inliers < config_.icp.min_inliers) {
    addProblem(result.health.problem,
               "registration failed: " + std::to_string(registration.inliers) + " correspondences");
    return result;
  }
  if (registration.degenerate) {
    addProblem(result.health.problem,
               "degenerate registration (the scene constrains too few directions)");
  }
  // 4. Update velocity and threshold, then the map.
  result.health.sharp_motion = frame_registration.twist.has_value();
  if (map_.empty() && t_mid != 0.0) first_sweep_ = FirstSweep{clean.cloud, t_mid, stamp};
  commit(stamp, t_mid, registration, T_predicted, frame_registration.twist, up);
  if (frame_registration.source_points > 0 && registration.inliers > 0) {
    constexpr double kWeight = 0.1;  // about the last ten frames, as rmse_average_
    const double share = static_cast<double>(registration.inliers) /
                         static_cast<double>(frame_registration.source_points);
    inlier_share_average_ = inlier_share_average_ > 0.0
                                ? (1.0 - kWeight) * inlier_share_average_ + kWeight * share
                                : share;
  }
  const std::vector<Eigen::Vector3d> deskewed = deskewedFrame(clean.cloud, t_mid);
  const std::vector<Eigen::Vector3d> frame =
      voxelDownsample(deskewed, 0.5 * config_.mapVoxelSize());
  growMap(deskewed, frame);
  result.health.accepted = true;
  result.T_odom_sensor = T_odom_sensor_;
  result.covariance = covarianceOf(registration, up.has_value() && up_odom_.has_value());
  result.registered = toCloud(frame);
  result.registered.transform(core::expSE3(t_mid * velocity_));  // mid-sweep to stamp
  result.first_frame_redone = std::exchange(first_frame_redone_, std::nullopt);
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

core::Matrix6d LidarOdometry::covarianceOf(const RegistrationResult& registration,
                                           bool levelled) const {
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
  const double tilt_floor = levelled ? config_.imu_tilt_sigma : config_.min_rotation_sigma;
  const double r2 = tilt_floor * tilt_floor;
  covariance.diagonal().head<3>().array() += t2;
  covariance.diagonal().segment<2>(3).array() += r2;
  covariance(5, 5) += config_.min_yaw_sigma * config_.min_yaw_sigma;
  return covariance;
}

std::vector<Eigen::Vector3d> LidarOdometry::deskewedFrame(const core::PointCloud& cloud,
                                                          double t_mid) const {
  return deskew(cloud, config_.deskew ? velocity_ : core::Vector6d::Zero(), t_mid);
}

std::vector<Eigen::Vector3d> LidarOdometry::thinnedFrame(const core::PointCloud& cloud,
                                                         double t_mid) const {
  return voxelDownsample(deskewedFrame(cloud, t_mid), 0.5 * config_.mapVoxelSize());
}

LidarOdometry::FrameSource LidarOdometry::sourceOf(const core::PointCloud& cloud, double t_mid,
                                                   const core::Vector6d& velocity) const {
  const std::vector<Eigen::Vector3d> deskewed =
      deskew(cloud, config_.deskew ? velocity : core::Vector6d::Zero(), t_mid);
  FrameSource source;
  const bool timed = config_.deskew && sweepDuration(cloud) > 0.0;
  for (const std::size_t i : voxelDownsampleIndices(deskewed, 1.5 * config_.mapVoxelSize())) {
    source.deskewed.push_back(deskewed[i]);
    if (!timed) continue;
    source.sweep.points.push_back(cloud.points[i].cast<double>());
    source.sweep.offsets.push_back(static_cast<double>(cloud.time[i]) - t_mid);
  }
  return source;
}

RegistrationResult LidarOdometry::registerCoarseToFine(std::span<const Eigen::Vector3d> points,
                                                       const Eigen::Isometry3d& T_start) const {
  const double learned = threshold_.sigma();
  RegistrationResult fit;
  fit.T_target_source = T_start;
  for (double sigma = config_.threshold.initial_threshold;;
       sigma = std::max(0.5 * sigma, learned)) {
    fit = registerScan(points, map_, fit.T_target_source, frameIcpConfig(sigma));
    if (fit.inliers < config_.icp.min_inliers || sigma <= learned) break;
  }
  return fit;
}

RegistrationResult LidarOdometry::registerRigid(const FrameSource& source,
                                                const Eigen::Isometry3d& T_predicted) const {
  RegistrationResult rigid =
      registerScan(source.deskewed, map_, T_predicted, frameIcpConfig(threshold_.sigma()));
  // Until the robot has moved, sigma is only the initial guess, a gate of
  // metres: wide enough to catch an unknown first motion, but against a map
  // of one or two sparse sweeps its far pairs pull the pose centimetres off
  // (mostly in height), and that offset stays. Refine with the narrowest
  // gate the map's sampling allows, from where the wide pass ended.
  if (!threshold_.learned()) {
    if (rigid.inliers >= config_.icp.min_inliers)
      rigid = registerScan(source.deskewed, map_, rigid.T_target_source, frameIcpConfig(0.0));
    return rigid;
  }
  // A turn the prediction missed (a robot that starts to spin, a car that
  // swings into a corner after a long straight) moves the far points metres
  // beyond a gate that steady motion shrank to decimetres: the fit keeps the
  // near points only, turns part of the way, and the next prediction starts
  // from there, behind again. When far fewer points pair than in the frames
  // before, fit again from the prediction, coarse to fine, and keep what
  // pairs more points.
  const double share = static_cast<double>(rigid.inliers) /
                       static_cast<double>(std::max<std::size_t>(source.deskewed.size(), 1));
  if (inlier_share_average_ > 0.0 && share < kLostShareRatio * inlier_share_average_) {
    const RegistrationResult again = registerCoarseToFine(source.deskewed, T_predicted);
    if (!again.degenerate && again.inliers > rigid.inliers) rigid = again;
  }
  return rigid;
}

LidarOdometry::FrameRegistration LidarOdometry::registerFrame(
    const core::PointCloud& cloud, double stamp, double t_mid,
    const Eigen::Isometry3d& T_predicted) const {
  const FrameSource source = sourceOf(cloud, t_mid, velocity_);
  FrameRegistration frame{registerRigid(source, T_predicted), std::nullopt, source.deskewed.size()};
  if (!motionChanged(frame.registration, stamp + t_mid, sweepDuration(cloud)) ||
      source.sweep.points.empty()) {
    return frame;
  }
  // The sweep was deskewed with a velocity the sensor no longer had, bent
  // by up to half a sweep of the difference, and the rigid fit settled on
  // the bent sweep. What the sensor did instead is best told by the motion
  // that fit measured since the last sweep: deskewed with that, the sweep
  // is fitted again, coarse to fine (its far points moved metres beyond the
  // gate that steady motion had shrunk), and from there with a twist of its
  // own. One sweep's bend pins its twist only weakly, so the estimate stays
  // near its prior, which is that measured motion: centred on the velocity
  // the sensor no longer had, it stayed there (KITTI 00's car going from 12
  // to 36 deg/s of yaw kept 14-16 deg/s for two sweeps, and the next sweep,
  // deskewed with that, was registered 1.2 deg off). Of the three fits, the
  // one that fits the map best is kept.
  const core::Vector6d measured =
      core::logSE3(T_odom_reference_.inverse() * frame.registration.T_target_source) /
      (stamp + t_mid - *last_reference_time_);
  const FrameSource redone = sourceOf(cloud, t_mid, measured);
  const RegistrationResult refit =
      registerCoarseToFine(redone.deskewed, frame.registration.T_target_source);
  const bool refit_usable = refit.inliers >= config_.icp.min_inliers && !refit.degenerate;
  SweepMotionPrior prior;
  prior.velocity = measured;
  prior.sigma << Eigen::Vector3d::Constant(config_.twist_sigma_linear),
      Eigen::Vector3d::Constant(config_.twist_sigma_angular);
  const SweepRegistration sweep = registerSweep(
      redone.sweep, map_, refit_usable ? refit.T_target_source : frame.registration.T_target_source,
      prior, frameIcpConfig(threshold_.sigma()));
  FrameRegistration best = frame;
  if (refit_usable && refit.rmse < best.registration.rmse)
    best = {refit, measured, redone.deskewed.size()};
  if (sweep.registration.inliers >= config_.icp.min_inliers && !sweep.registration.degenerate &&
      sweep.registration.rmse < best.registration.rmse)
    best = {sweep.registration, sweep.velocity, redone.deskewed.size()};
  return best;
}

bool LidarOdometry::motionChanged(const RegistrationResult& rigid, double reference_time,
                                  double duration) const {
  // Not before a velocity is known (the first two sweeps have their own fix-up).
  if (!config_.deskew || duration <= 0.0 || !last_reference_time_ || first_sweep_ ||
      reference_time <= *last_reference_time_ || rigid.inliers < config_.icp.min_inliers ||
      rigid.degenerate) {
    return false;
  }
  // A sweep bent by a change of motion fits the map far worse than the
  // sweeps before it, even where the registration stays near the prediction.
  const double ratio = config_.motion_change_rmse_ratio;
  if (ratio > 0.0 && rmse_average_ > 0.0 && rigid.rmse > ratio * rmse_average_) return true;
  if (config_.motion_change_error <= 0.0) return false;
  const core::Vector6d registered =
      core::logSE3(T_odom_reference_.inverse() * rigid.T_target_source) /
      (reference_time - *last_reference_time_);
  const core::Vector6d change = registered - velocity_;
  constexpr double kLever = 10.0;  // m, the point whose displacement is judged
  const double error =
      0.5 * duration * (change.head<3>().norm() + kLever * change.tail<3>().norm());
  return error > config_.motion_change_error;
}

void LidarOdometry::commit(double stamp, double t_mid, const RegistrationResult& registration,
                           const Eigen::Isometry3d& T_predicted,
                           const std::optional<core::Vector6d>& twist,
                           const std::optional<Eigen::Vector3d>& up) {
  const double reference_time = stamp + t_mid;
  const Eigen::Isometry3d& T_odom_reference = registration.T_target_source;
  const Eigen::Isometry3d T_last_current = T_odom_reference_.inverse() * T_odom_reference;
  if (last_reference_time_) {
    velocity_ =
        twist.value_or(core::logSE3(T_last_current) / (reference_time - *last_reference_time_));
    threshold_.update(T_predicted.inverse() * T_odom_reference,
                      T_last_current.translation().norm());
  }
  if (registration.inliers > 0) {
    constexpr double kWeight = 0.1;  // about the last ten frames
    rmse_average_ = rmse_average_ > 0.0
                        ? (1.0 - kWeight) * rmse_average_ + kWeight * registration.rmse
                        : registration.rmse;
  }
  T_odom_reference_ = T_odom_reference;
  if (first_sweep_ && last_reference_time_) redoFirstSweep();
  // Levelled after the velocity is measured: registration's own motion stays
  // its measure, and the next frame is predicted from the levelled pose.
  if (up && !first_sweep_) level(*up, t_mid, reference_time);
  last_reference_time_ = reference_time;
  T_odom_sensor_ = T_odom_reference_ * core::expSE3(-t_mid * velocity_);
  last_stamp_ = stamp;
}

void LidarOdometry::level(const Eigen::Vector3d& up_stamp, double t_mid, double reference_time) {
  // The reading is at the stamp; the pose at mid-sweep, t_mid later.
  const Eigen::Matrix3d R_stamp_reference = core::expSE3(t_mid * velocity_).rotation();
  const Eigen::Vector3d read =
      T_odom_reference_.rotation() * (R_stamp_reference.transpose() * up_stamp);
  if (!up_odom_) {
    up_odom_ = read;
    last_level_time_ = reference_time;
    return;
  }
  const double dt = std::max(0.0, reference_time - last_level_time_);
  last_level_time_ = reference_time;
  const double share = 1.0 - std::exp(-dt / config_.imu_time_constant);
  const Eigen::Quaterniond full = Eigen::Quaterniond::FromTwoVectors(read, *up_odom_);
  const Eigen::Quaterniond turn = Eigen::Quaterniond::Identity().slerp(share, full);
  T_odom_reference_.linear() =
      (turn * Eigen::Quaterniond(T_odom_reference_.rotation())).normalized().toRotationMatrix();
}

void LidarOdometry::growMap(std::span<const Eigen::Vector3d> deskewed,
                            std::span<const Eigen::Vector3d> frame) {
  // Every few frames: a ghost outlives its object by a few tenths of a second,
  // and the map is visited a few times less.
  if (config_.free_space_radius > 0.0 && !map_.empty() &&
      ++frames_since_carving_ >= kFramesPerCarving) {
    frames_since_carving_ = 0;
    const FreeSpace free(deskewed);
    const Eigen::Isometry3d T_reference_odom = T_odom_reference_.inverse();
    map_.removeNear(
        T_odom_reference_.translation(), config_.free_space_radius,
        [&](const Eigen::Vector3d& p) { return free.seesThrough(T_reference_odom * p); });
  }
  map_.addPoints(frame, T_odom_reference_);
  map_.removeFarFrom(T_odom_reference_.translation(), config_.max_range);
}

void LidarOdometry::redoFirstSweep() {
  // The first sweep was taken without a velocity: it went into the map
  // undeskewed, and its middle became the odometry frame. With the first
  // velocity known, deskew it properly and move the frame to its stamp.
  const Eigen::Isometry3d T_stamp_mid = core::expSE3(first_sweep_->t_mid * velocity_);
  const std::vector<Eigen::Vector3d> thinned =
      thinnedFrame(first_sweep_->cloud, first_sweep_->t_mid);
  map_.clear();
  map_.addPoints(thinned, T_stamp_mid);
  T_odom_reference_ = T_stamp_mid * T_odom_reference_;
  // The first frame's result went out undeskewed too: its cloud again, as
  // process() gives `registered` (thinned at mid-sweep, moved to the stamp).
  first_frame_redone_ = OdometryResult::Redone{first_sweep_->stamp, toCloud(thinned)};
  first_frame_redone_->registered.transform(T_stamp_mid);
  first_sweep_.reset();
}

}  // namespace dcl::odometry
