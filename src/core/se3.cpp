#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include <dcl/core/se3.hpp>

namespace dcl::core {

namespace {
// Below this angle the closed forms lose precision; their Taylor series take over.
constexpr double kSmallAngle = 1e-6;
}  // namespace

Eigen::Matrix3d hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Vector3d vee(const Eigen::Matrix3d& m) {
  return {m(2, 1), m(0, 2), m(1, 0)};
}

Eigen::Matrix3d expSO3(const Eigen::Vector3d& omega) {
  const double theta = omega.norm();
  if (theta < kSmallAngle) return Eigen::Matrix3d::Identity() + hat(omega);
  return Eigen::AngleAxisd(theta, omega / theta).toRotationMatrix();
}

Eigen::Vector3d logSO3(const Eigen::Matrix3d& R) {
  // Eigen's AngleAxis goes through the quaternion, which stays accurate near pi
  // where acos of the trace does not.
  const Eigen::AngleAxisd aa(Eigen::Quaterniond(R).normalized());
  double angle = aa.angle();
  Eigen::Vector3d axis = aa.axis();
  if (angle > M_PI) {
    angle = 2.0 * M_PI - angle;
    axis = -axis;
  }
  return angle * axis;
}

Eigen::Matrix3d leftJacobianSO3(const Eigen::Vector3d& omega) {
  const double theta = omega.norm();
  const Eigen::Matrix3d W = hat(omega);
  if (theta < kSmallAngle) return Eigen::Matrix3d::Identity() + 0.5 * W + W * W / 6.0;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * W +
         (theta - std::sin(theta)) / (t2 * theta) * W * W;
}

Eigen::Matrix3d leftJacobianInverseSO3(const Eigen::Vector3d& omega) {
  const double theta = omega.norm();
  const Eigen::Matrix3d W = hat(omega);
  if (theta < kSmallAngle) return Eigen::Matrix3d::Identity() - 0.5 * W + W * W / 12.0;
  const double half = 0.5 * theta;
  const double cot_term = (1.0 - half * std::cos(half) / std::sin(half)) / (theta * theta);
  return Eigen::Matrix3d::Identity() - 0.5 * W + cot_term * W * W;
}

Eigen::Isometry3d expSE3(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = expSO3(phi);
  T.translation() = leftJacobianSO3(phi) * rho;
  return T;
}

Vector6d logSE3(const Eigen::Isometry3d& T) {
  const Eigen::Vector3d phi = logSO3(T.linear());
  Vector6d xi;
  xi.head<3>() = leftJacobianInverseSO3(phi) * T.translation();
  xi.tail<3>() = phi;
  return xi;
}

Matrix6d adjoint(const Eigen::Isometry3d& T) {
  Matrix6d ad = Matrix6d::Zero();
  const Eigen::Matrix3d R = T.linear();
  ad.topLeftCorner<3, 3>() = R;
  ad.topRightCorner<3, 3>() = hat(T.translation()) * R;
  ad.bottomRightCorner<3, 3>() = R;
  return ad;
}

double rotationAngle(const Eigen::Matrix3d& R) {
  return logSO3(R).norm();
}

Eigen::Matrix3d projectToSO3(const Eigen::Matrix3d& M) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  S(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * S * svd.matrixV().transpose();
}

Eigen::Isometry3d interpolate(const Eigen::Isometry3d& T_a, const Eigen::Isometry3d& T_b,
                              double alpha) {
  const Eigen::Quaterniond q_a(T_a.linear());
  const Eigen::Quaterniond q_b(T_b.linear());
  return makePose((1.0 - alpha) * T_a.translation() + alpha * T_b.translation(),
                  q_a.slerp(alpha, q_b));
}

Eigen::Isometry3d interpolateGeodesic(const Eigen::Isometry3d& T_a, const Eigen::Isometry3d& T_b,
                                      double alpha) {
  return T_a * expSE3(alpha * logSE3(T_a.inverse() * T_b));
}

Eigen::Isometry3d makePose(const Eigen::Vector3d& t, const Eigen::Quaterniond& q) {
  return makePose(t, q.normalized().toRotationMatrix());
}

Eigen::Isometry3d makePose(const Eigen::Vector3d& t, const Eigen::Matrix3d& R) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

Eigen::Isometry3d makePose2d(double x, double y, double yaw) {
  return makePose(Eigen::Vector3d(x, y, 0.0),
                  Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix());
}

}  // namespace dcl::core
