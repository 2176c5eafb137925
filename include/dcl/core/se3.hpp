#pragma once

/// SO(3) and SE(3) on Eigen.
///
/// Tangent vectors of SE(3) are ordered translation first, `xi = [rho; phi]`,
/// the order of g2o's EDGE_SE3:QUAT information matrices, so that a 6x6
/// information or covariance matrix reads the same everywhere in the project.
/// Poses are `Eigen::Isometry3d` named by their frames: `T_a_b` maps points
/// from frame b into frame a.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace dcl::core {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// The skew-symmetric matrix of `v`: hat(v) * w == v.cross(w).
Eigen::Matrix3d hat(const Eigen::Vector3d& v);

/// The vector of a skew-symmetric matrix (inverse of hat).
Eigen::Vector3d vee(const Eigen::Matrix3d& m);

/// Rodrigues' formula: the rotation by |omega| radians about omega.
Eigen::Matrix3d expSO3(const Eigen::Vector3d& omega);

/// The rotation vector of `R`, angle in [0, pi]; accurate near 0 and near pi.
Eigen::Vector3d logSO3(const Eigen::Matrix3d& R);

/// The left Jacobian of SO(3) at `omega` (relates the tangent of SE(3)'s exp to translation).
Eigen::Matrix3d leftJacobianSO3(const Eigen::Vector3d& omega);

/// The inverse of leftJacobianSO3.
Eigen::Matrix3d leftJacobianInverseSO3(const Eigen::Vector3d& omega);

/// exp on SE(3): xi = [rho; phi].
Eigen::Isometry3d expSE3(const Vector6d& xi);

/// log on SE(3): returns [rho; phi].
Vector6d logSE3(const Eigen::Isometry3d& T);

/// The adjoint of `T` for tangents ordered [rho; phi]: Ad(T) xi = log(T exp(xi) T^-1).
Matrix6d adjoint(const Eigen::Isometry3d& T);

/// The rotation angle of `R` in radians, in [0, pi].
double rotationAngle(const Eigen::Matrix3d& R);

/// The nearest rotation to `M` in the Frobenius norm (the chordal projection
/// onto SO(3)), by SVD with the determinant fixed to +1.
Eigen::Matrix3d projectToSO3(const Eigen::Matrix3d& M);

/// Pose at `alpha` in [0, 1] between `T_a` (alpha = 0) and `T_b` (alpha = 1):
/// translation linearly, rotation by slerp, as trajectory tools interpolate timestamped poses.
Eigen::Isometry3d interpolate(const Eigen::Isometry3d& T_a, const Eigen::Isometry3d& T_b,
                              double alpha);

/// Pose at `alpha` along the SE(3) geodesic from `T_a` to `T_b`: T_a exp(alpha log(T_a^-1 T_b)).
Eigen::Isometry3d interpolateGeodesic(const Eigen::Isometry3d& T_a, const Eigen::Isometry3d& T_b,
                                      double alpha);

/// A pose from a translation and a (not necessarily normalised) quaternion.
Eigen::Isometry3d makePose(const Eigen::Vector3d& t, const Eigen::Quaterniond& q);

/// A pose from a translation and a rotation matrix.
Eigen::Isometry3d makePose(const Eigen::Vector3d& t, const Eigen::Matrix3d& R);

/// A planar pose (x, y, yaw) lifted to SE(3) with z = 0, roll = pitch = 0.
Eigen::Isometry3d makePose2d(double x, double y, double yaw);

/// Degrees from radians.
constexpr double rad2deg(double rad) {
  return rad * 57.29577951308232;
}
/// Radians from degrees.
constexpr double deg2rad(double deg) {
  return deg * 0.017453292519943295;
}

}  // namespace dcl::core
