#include <Eigen/Eigenvalues>

#include <dcl/odometry/keyframe_selector.hpp>
#include <dcl/odometry/preprocessing.hpp>

namespace dcl::odometry {
namespace {

/// The covariance with every eigenvalue raised to at least `floor`.
core::Matrix6d withVarianceFloor(const core::Matrix6d& covariance, double floor) {
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> eigen(0.5 *
                                                            (covariance + covariance.transpose()));
  const core::Vector6d values = eigen.eigenvalues().cwiseMax(floor);
  return eigen.eigenvectors() * values.asDiagonal() * eigen.eigenvectors().transpose();
}

bool usable(const OdometryResult& frame) {
  return frame.health.accepted && frame.T_odom_sensor.matrix().allFinite();
}

}  // namespace

KeyframeSelector::KeyframeSelector(core::RobotId robot, const KeyframeConfig& config)
    : robot_(robot), config_(config) {}

std::optional<core::Keyframe> KeyframeSelector::add(const OdometryResult& frame,
                                                    const core::PointCloud& scan) {
  if (!frame.T_odom_sensor.matrix().allFinite()) return std::nullopt;
  if (T_odom_last_) accumulate(frame);
  T_odom_previous_frame_ = frame.T_odom_sensor;
  if (!usable(frame)) return std::nullopt;
  if (T_odom_last_ && !isKeyframe(T_odom_last_->inverse() * frame.T_odom_sensor)) {
    return std::nullopt;
  }
  core::Keyframe keyframe = makeKeyframe(frame, scan);
  T_odom_last_ = frame.T_odom_sensor;
  covariance_.setZero();
  ++count_;
  return keyframe;
}

bool KeyframeSelector::isKeyframe(const Eigen::Isometry3d& T_last_frame) const {
  return T_last_frame.translation().norm() > config_.translation ||
         core::rotationAngle(T_last_frame.rotation()) > config_.rotation;
}

core::Keyframe KeyframeSelector::makeKeyframe(const OdometryResult& frame,
                                              const core::PointCloud& scan) const {
  core::Keyframe keyframe;
  keyframe.robot = robot_;
  keyframe.id = core::KeyframeId(count_);
  keyframe.stamp = frame.stamp;
  keyframe.T_odom_keyframe = frame.T_odom_sensor;
  if (T_odom_last_) {
    keyframe.T_previous_keyframe = T_odom_last_->inverse() * frame.T_odom_sensor;
    keyframe.covariance = withVarianceFloor(covariance_, config_.min_variance);
  } else {
    keyframe.covariance.setZero();  // the first keyframe defines the robot's frame
  }
  keyframe.cloud = keyframeCloud(scan);
  return keyframe;
}

core::PointCloud KeyframeSelector::keyframeCloud(const core::PointCloud& scan) const {
  return voxelFilter(scan, config_.voxel_size);
}

void KeyframeSelector::accumulate(const OdometryResult& frame) {
  // Sigma_{k,i} = Ad(T_{i-1,i}^-1) Sigma_{k,i-1} Ad(T_{i-1,i}^-1)^T + Sigma_i (see the header).
  const Eigen::Isometry3d T_step = T_odom_previous_frame_.inverse() * frame.T_odom_sensor;
  const core::Matrix6d Ad = core::adjoint(T_step.inverse());
  core::Matrix6d frame_covariance = frame.covariance;
  if (!frame_covariance.allFinite()) frame_covariance.setZero();
  covariance_ = Ad * covariance_ * Ad.transpose() + frame_covariance;
}

core::PointCloud voxelFilter(const core::PointCloud& cloud, double voxel_size) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(cloud.size());
  for (const Eigen::Vector3f& p : cloud.points) {
    if (p.allFinite()) points.push_back(p.cast<double>());
  }
  return toCloud(voxelDownsample(points, voxel_size));
}

}  // namespace dcl::odometry
