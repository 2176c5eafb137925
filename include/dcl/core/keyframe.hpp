#pragma once

#include <Eigen/Geometry>

#include <dcl/core/ids.hpp>
#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::core {

/// A keyframe: a scan kept for place recognition, loop verification and the
/// map, with the odometry pose at which it was taken and the odometry factor
/// that ties it to the previous keyframe of the same robot.
struct Keyframe {
  RobotId robot;
  KeyframeId id;
  double stamp = 0.0;                                                 ///< seconds
  Eigen::Isometry3d T_odom_keyframe = Eigen::Isometry3d::Identity();  ///< odometry pose
  /// Relative pose from the previous keyframe (identity for the first).
  Eigen::Isometry3d T_previous_keyframe = Eigen::Isometry3d::Identity();
  /// Covariance of T_previous_keyframe, tangent ordered [rho; phi] (see se3.hpp).
  Matrix6d covariance = Matrix6d::Identity();
  PointCloud cloud;  ///< the keyframe's scan, in the keyframe's frame
};

}  // namespace dcl::core
