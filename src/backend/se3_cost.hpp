#pragma once

/// The SE(3) factor cost on Ceres, shared by the centralized solver and the
/// distributed refinement so that both minimise the very same function: each
/// pose is a unit quaternion (EigenQuaternionManifold) and a translation, each
/// factor's residual the SE(3) log of its measurement error (pose_graph.hpp)
/// whitened by the square root of its information. Internal to the backend.

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstddef>
#include <map>
#include <memory>

#include <ceres/ceres.h>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::backend::detail {

template <class T>
using Vector3 = Eigen::Matrix<T, 3, 1>;

/// log on SO(3) from a unit quaternion; the w >= 0 hemisphere gives angles in [0, pi].
/// Near the identity the exact 2 atan2(|v|, w) / |v| has a 0/0 that autodiff
/// cannot differentiate, so its limit 2 / w is used (relative error |v|^2 / 3).
template <class T>
Vector3<T> logQuaternion(const Eigen::Quaternion<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  const T sign = q_in.w() < T(0) ? T(-1) : T(1);
  const T w = sign * q_in.w();
  const Vector3<T> v = sign * q_in.vec();
  const T sin_squared = v.squaredNorm();
  if (sin_squared < T(1e-14)) return (T(2) / w) * v;
  const T sin_half = sqrt(sin_squared);
  return (T(2) * atan2(sin_half, w) / sin_half) * v;
}

/// J_l^-1(phi) t = t - phi x t / 2 + c phi x (phi x t), c = 1/theta^2 - 1/(2 theta tan(theta/2)),
/// which stays finite up to theta = pi; its Taylor series below theta^2 = 1e-4.
template <class T>
Vector3<T> applyLeftJacobianInverse(const Vector3<T>& phi, const Vector3<T>& t) {
  using std::sqrt;
  using std::tan;
  const T theta_squared = phi.squaredNorm();
  T c;
  if (theta_squared < T(1e-4)) {
    c = T(1.0 / 12.0) + theta_squared / T(720.0);
  } else {
    const T theta = sqrt(theta_squared);
    c = T(1) / theta_squared - T(1) / (T(2) * theta * tan(theta / T(2)));
  }
  const Vector3<T> phi_t = phi.cross(t);
  return t - T(0.5) * phi_t + c * phi.cross(phi_t);
}

/// The factor residual of pose_graph.hpp, r = log(T_from_to^-1 T_world_from^-1 T_world_to)
/// in [rho; phi], whitened: S r with S^T S = Omega, so |S r|^2 is the g2o chi-square.
class RelativePoseError {
 public:
  RelativePoseError(const Eigen::Isometry3d& T_from_to, const core::Matrix6d& sqrt_information)
      : q_to_from_(Eigen::Quaterniond(T_from_to.rotation()).conjugate()),
        t_from_to_(T_from_to.translation()),
        sqrt_information_(sqrt_information) {}

  template <class T>
  bool operator()(const T* q_from_data, const T* t_from_data, const T* q_to_data,
                  const T* t_to_data, T* residual_data) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_from(q_from_data);
    const Eigen::Map<const Eigen::Quaternion<T>> q_to(q_to_data);
    const Eigen::Map<const Vector3<T>> t_from(t_from_data);
    const Eigen::Map<const Vector3<T>> t_to(t_to_data);
    // T_from^-1 T_to, then the measurement's inverse applied on the left.
    const Eigen::Quaternion<T> q_rel = q_from.conjugate() * q_to;
    const Vector3<T> t_rel = q_from.conjugate() * (t_to - t_from);
    const Eigen::Quaternion<T> q_meas_inv = q_to_from_.cast<T>();
    const Eigen::Quaternion<T> q_error = q_meas_inv * q_rel;
    const Vector3<T> t_error = q_meas_inv * (t_rel - t_from_to_.cast<T>());
    Eigen::Matrix<T, 6, 1> xi;
    xi.template tail<3>() = logQuaternion(q_error);
    xi.template head<3>() = applyLeftJacobianInverse<T>(xi.template tail<3>(), t_error);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> residual(residual_data);
    residual = sqrt_information_.cast<T>() * xi;
    return true;
  }

  /// The autodiff form of this cost, kept as the reference the analytic
  /// Jacobians of RelativePoseCost are checked against.
  static ceres::CostFunction* createAutoDiff(const Factor& factor,
                                             const core::Matrix6d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<RelativePoseError, 6, 4, 3, 4, 3>(
        new RelativePoseError(factor.T_from_to, sqrt_information));
  }

 private:
  Eigen::Quaterniond q_to_from_;
  Eigen::Vector3d t_from_to_;
  core::Matrix6d sqrt_information_;
};

/// J_r^-1 of SE(3) at xi = [rho; phi]: the derivative of log(exp(xi) exp(d)) in d
/// at d = 0. It is J_l^-1(-xi) = [A, -A Q A; 0, A] with A = J_l^-1(-phi) of SO(3)
/// and Q(-rho, -phi) the coupling block of SE(3)'s left Jacobian (Barfoot,
/// "State Estimation for Robotics", eq. 7.86); its coefficients switch to their
/// Taylor series below theta^2 = 1e-2, where the closed forms cancel.
inline core::Matrix6d rightJacobianInverseSE3(const core::Vector6d& xi) {
  const Eigen::Vector3d rho = -xi.head<3>();
  const Eigen::Vector3d phi = -xi.tail<3>();
  const double theta_squared = phi.squaredNorm();
  double c1;
  double c2;
  double c3;
  if (theta_squared < 1e-2) {
    const double t2 = theta_squared;
    c1 = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0;
    c2 = 1.0 / 24.0 - t2 / 720.0 + t2 * t2 / 40320.0;
    c3 = 1.0 / 120.0 - t2 / 2520.0 + t2 * t2 / 120960.0;
  } else {
    const double theta = std::sqrt(theta_squared);
    const double sin_theta = std::sin(theta);
    const double cos_theta = std::cos(theta);
    const double theta_cubed = theta_squared * theta;
    c1 = (theta - sin_theta) / theta_cubed;
    c2 = (theta_squared + 2.0 * cos_theta - 2.0) / (2.0 * theta_squared * theta_squared);
    c3 = (2.0 * theta - 3.0 * sin_theta + theta * cos_theta) / (2.0 * theta_cubed * theta_squared);
  }
  const Eigen::Matrix3d P = core::hat(phi);
  const Eigen::Matrix3d V = core::hat(rho);
  const Eigen::Matrix3d PV = P * V;
  const Eigen::Matrix3d VP = V * P;
  const Eigen::Matrix3d PVP = PV * P;
  const Eigen::Matrix3d PP = P * P;
  const Eigen::Matrix3d Q = 0.5 * V + c1 * (PV + VP + PVP) + c2 * (PP * V + VP * P - 3.0 * PVP) +
                            c3 * (PVP * P + P * PVP);
  const Eigen::Matrix3d A = core::leftJacobianInverseSO3(phi);
  core::Matrix6d J;
  J.topLeftCorner<3, 3>() = A;
  J.topRightCorner<3, 3>() = -A * Q * A;
  J.bottomLeftCorner<3, 3>().setZero();
  J.bottomRightCorner<3, 3>() = A;
  return J;
}

/// A factor's whitened residual and its Jacobians with respect to right
/// perturbations [rho; phi] of its two poses, T exp(d). With E = Z^-1 T_from^-1
/// T_to and r0 = log(E), perturbing T_to gives dr0 = J_r^-1(r0) d, and
/// perturbing T_from gives dr0 = -J_r^-1(r0) Ad(T_to^-1 T_from) d. To first
/// order, exp([rho; phi]) moves the translation by R rho and the rotation to
/// R exp(phi).
struct RelativePoseMeasurement {
  Eigen::Quaterniond q_to_from;  ///< the measured rotation, inverted
  Eigen::Vector3d t_from_to;     ///< the measured translation
  core::Matrix6d sqrt_information;

  RelativePoseMeasurement(const Eigen::Isometry3d& T_from_to, const core::Matrix6d& sqrt_info)
      : q_to_from(Eigen::Quaterniond(T_from_to.rotation()).conjugate()),
        t_from_to(T_from_to.translation()),
        sqrt_information(sqrt_info) {}

  /// The whitened residual S log(Z^-1 T_from^-1 T_to); its unwhitened log in `xi` when asked.
  [[nodiscard]] core::Vector6d residual(const Eigen::Quaterniond& q_from,
                                        const Eigen::Vector3d& t_from,
                                        const Eigen::Quaterniond& q_to, const Eigen::Vector3d& t_to,
                                        core::Vector6d* xi_out = nullptr) const {
    const Eigen::Quaterniond q_error = q_to_from * (q_from.conjugate() * q_to);
    const Eigen::Vector3d t_error = q_to_from * (q_from.conjugate() * (t_to - t_from) - t_from_to);
    core::Vector6d xi;
    xi.tail<3>() = logQuaternion(q_error);
    xi.head<3>() = applyLeftJacobianInverse<double>(xi.tail<3>(), t_error);
    if (xi_out != nullptr) *xi_out = xi;
    return sqrt_information * xi;
  }

  /// The residual, and the Jacobians for right perturbations of each pose.
  core::Vector6d linearise(const Eigen::Quaterniond& q_from, const Eigen::Vector3d& t_from,
                           const Eigen::Quaterniond& q_to, const Eigen::Vector3d& t_to,
                           core::Matrix6d& J_from, core::Matrix6d& J_to) const {
    core::Vector6d xi;
    const core::Vector6d r = residual(q_from, t_from, q_to, t_to, &xi);
    J_to = sqrt_information * rightJacobianInverseSE3(xi);
    // -J_to Ad(T_to^-1 T_from), Ad(R, t) = [R, t^ R; 0, R].
    const Eigen::Matrix3d R_to_transpose = q_to.toRotationMatrix().transpose();
    const Eigen::Matrix3d R = R_to_transpose * q_from.toRotationMatrix();
    const Eigen::Vector3d t = R_to_transpose * (t_from - t_to);
    J_from.leftCols<3>() = -J_to.leftCols<3>() * R;
    J_from.rightCols<3>() = -J_to.leftCols<3>() * (core::hat(t) * R) - J_to.rightCols<3>() * R;
    return r;
  }
};

/// RelativePoseError with analytic Jacobians (RelativePoseMeasurement):
/// autodiff through the SE(3) log dominates the solvers' time. A translation
/// step dt is the right perturbation [R^T dt; 0]; a quaternion step delta of
/// EigenQuaternionManifold, q' = [cos|delta|, sin|delta| delta/|delta|] q, is
/// the rotation exp(2 delta) R, i.e. the right perturbation [0; 2 R^T delta].
/// Ceres multiplies the ambient (4-column) Jacobian by the manifold's
/// PlusJacobian P, whose columns are orthonormal, so J_tangent P^T is an
/// ambient Jacobian that reproduces J_tangent.
class RelativePoseCost final : public ceres::SizedCostFunction<6, 4, 3, 4, 3> {
 public:
  RelativePoseCost(const Eigen::Isometry3d& T_from_to, const core::Matrix6d& sqrt_information)
      : measurement_(T_from_to, sqrt_information) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Quaterniond> q_from(parameters[0]);
    const Eigen::Map<const Eigen::Vector3d> t_from(parameters[1]);
    const Eigen::Map<const Eigen::Quaterniond> q_to(parameters[2]);
    const Eigen::Map<const Eigen::Vector3d> t_to(parameters[3]);
    Eigen::Map<core::Vector6d> residual(residuals);
    if (jacobians == nullptr) {
      residual = measurement_.residual(q_from, t_from, q_to, t_to);
      return true;
    }
    core::Matrix6d J_from;
    core::Matrix6d J_to;
    residual = measurement_.linearise(q_from, t_from, q_to, t_to, J_from, J_to);

    using Jacobian3 = Eigen::Matrix<double, 6, 3, Eigen::RowMajor>;
    using Jacobian4 = Eigen::Matrix<double, 6, 4, Eigen::RowMajor>;
    if (jacobians[0] != nullptr || jacobians[1] != nullptr) {
      const Eigen::Matrix3d R_from = q_from.toRotationMatrix();
      if (jacobians[1] != nullptr) {
        Eigen::Map<Jacobian3>{jacobians[1]} = J_from.leftCols<3>() * R_from.transpose();
      }
      if (jacobians[0] != nullptr) {
        Eigen::Map<Jacobian4>{jacobians[0]} =
            J_from.rightCols<3>() * ambientFromTangent(q_from, R_from);
      }
    }
    if (jacobians[2] != nullptr || jacobians[3] != nullptr) {
      const Eigen::Matrix3d R_to = q_to.toRotationMatrix();
      if (jacobians[3] != nullptr) {
        Eigen::Map<Jacobian3>{jacobians[3]} = J_to.leftCols<3>() * R_to.transpose();
      }
      if (jacobians[2] != nullptr) {
        Eigen::Map<Jacobian4>{jacobians[2]} = J_to.rightCols<3>() * ambientFromTangent(q_to, R_to);
      }
    }
    return true;
  }

  static ceres::CostFunction* create(const Factor& factor, const core::Matrix6d& sqrt_information) {
    return new RelativePoseCost(factor.T_from_to, sqrt_information);
  }

 private:
  /// 2 R^T P^T with P = [w I - v^; -v^T], the PlusJacobian of EigenQuaternionManifold at q.
  static Eigen::Matrix<double, 3, 4> ambientFromTangent(
      const Eigen::Map<const Eigen::Quaterniond>& q, const Eigen::Matrix3d& R) {
    Eigen::Matrix<double, 3, 4> plus_transpose;
    plus_transpose.leftCols<3>() = q.w() * Eigen::Matrix3d::Identity() + core::hat(q.vec());
    plus_transpose.col(3) = -q.vec();
    return 2.0 * R.transpose() * plus_transpose;
  }

  RelativePoseMeasurement measurement_;
};

/// S with S^T S = Omega, from the eigen-decomposition (negative eigenvalues of a
/// slightly indefinite matrix read as zero).
inline core::Matrix6d sqrtInformation(const core::Matrix6d& information) {
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> eigen(
      0.5 * (information + information.transpose()));
  const core::Vector6d root = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return root.asDiagonal() * eigen.eigenvectors().transpose();
}

/// One node's parameter blocks, as Ceres optimises them.
struct PoseBlock {
  double q[4];  ///< x y z w (Eigen's storage order, EigenQuaternionManifold)
  double t[3];
};

inline PoseBlock toBlock(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  const Eigen::Vector3d t = T.translation();
  return {{q.x(), q.y(), q.z(), q.w()}, {t.x(), t.y(), t.z()}};
}

inline Eigen::Isometry3d fromBlock(const PoseBlock& block) {
  const Eigen::Quaterniond q(block.q[3], block.q[0], block.q[1], block.q[2]);
  return core::makePose(Eigen::Vector3d(block.t[0], block.t[1], block.t[2]), q);
}

/// A Ceres problem over named poses and the factors between them. Poses live
/// in a std::map (stable addresses for Ceres); constant poses are the gauge or
/// a neighbour's separators, whose values may be replaced between solves.
class Se3Problem {
 public:
  Se3Problem() {
    ceres::Problem::Options options;
    options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(options);
  }
  Se3Problem(const Se3Problem&) = delete;  // Ceres holds pointers into the members
  Se3Problem& operator=(const Se3Problem&) = delete;

  /// Adds pose `key` at `T_world_node` (or replaces its value when it exists).
  void setPose(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node) {
    blocks_.insert_or_assign(key, toBlock(T_world_node));
  }

  [[nodiscard]] bool hasPose(const core::PoseKey& key) const { return blocks_.contains(key); }

  /// The current value of pose `key` (which must exist).
  [[nodiscard]] Eigen::Isometry3d pose(const core::PoseKey& key) const {
    return fromBlock(blocks_.at(key));
  }

  /// Adds the factor's residual (`loss` not owned, may be null); false, and
  /// nothing added, when an end is not a pose or both ends are the same pose
  /// (its cost is a constant, and Ceres rejects a block named twice).
  bool addFactor(const Factor& f, ceres::LossFunction* loss = nullptr) {
    if (f.from == f.to) return false;
    const auto from = blocks_.find(f.from);
    const auto to = blocks_.find(f.to);
    if (from == blocks_.end() || to == blocks_.end()) return false;
    PoseBlock& a = from->second;
    PoseBlock& b = to->second;
    problem_->AddResidualBlock(RelativePoseCost::create(f, sqrtInformation(f.information)), loss,
                               a.q, a.t, b.q, b.t);
    problem_->SetManifold(a.q, &quaternion_manifold_);
    problem_->SetManifold(b.q, &quaternion_manifold_);
    ++factors_;
    return true;
  }

  /// Holds pose `key` constant when a factor uses it; false when none does.
  bool setConstant(const core::PoseKey& key) {
    const auto it = blocks_.find(key);
    if (it == blocks_.end() || !problem_->HasParameterBlock(it->second.q)) return false;
    problem_->SetParameterBlockConstant(it->second.q);
    problem_->SetParameterBlockConstant(it->second.t);
    return true;
  }

  /// True when pose `key` is in a factor and free to move.
  [[nodiscard]] bool isVariable(const core::PoseKey& key) const {
    const auto it = blocks_.find(key);
    return it != blocks_.end() && problem_->HasParameterBlock(it->second.q) &&
           !problem_->IsParameterBlockConstant(it->second.q);
  }

  /// Every pose by key (the lowest first).
  [[nodiscard]] const std::map<core::PoseKey, PoseBlock>& blocks() const { return blocks_; }

  [[nodiscard]] ceres::Problem& problem() { return *problem_; }
  [[nodiscard]] std::size_t factors() const { return factors_; }

 private:
  std::map<core::PoseKey, PoseBlock> blocks_;
  ceres::EigenQuaternionManifold quaternion_manifold_;
  std::unique_ptr<ceres::Problem> problem_;  // destroyed first: it points into the members above
  std::size_t factors_ = 0;
};

/// Levenberg-Marquardt with sparse Cholesky, silent.
inline ceres::Solver::Options levenbergMarquardt(int max_iterations, int threads,
                                                 double function_tolerance) {
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.max_num_iterations = max_iterations;
  options.num_threads = threads;
  options.function_tolerance = function_tolerance;
  options.logging_type = ceres::SILENT;
  return options;
}

}  // namespace dcl::backend::detail
