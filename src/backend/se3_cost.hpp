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

  static ceres::CostFunction* create(const Factor& factor, const core::Matrix6d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<RelativePoseError, 6, 4, 3, 4, 3>(
        new RelativePoseError(factor.T_from_to, sqrt_information));
  }

 private:
  Eigen::Quaterniond q_to_from_;
  Eigen::Vector3d t_from_to_;
  core::Matrix6d sqrt_information_;
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
    problem_->AddResidualBlock(RelativePoseError::create(f, sqrtInformation(f.information)), loss,
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
