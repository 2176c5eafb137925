#include <Eigen/Eigenvalues>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <vector>

#include <ceres/ceres.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/core/error.hpp>

namespace dcl::backend {
namespace {

template <class T>
using Vector3 = Eigen::Matrix<T, 3, 1>;

/// log on SO(3) from a unit quaternion; the w >= 0 hemisphere gives angles in [0, pi].
/// Near the identity the exact 2 atan2(|v|, w) / |v| has a 0/0 that autodiff
/// cannot differentiate, so its limit 2 / w is used (relative error |v|^2 / 3).
template <class T>
Vector3<T> logQuaternion(const Eigen::Quaternion<T>& q_in) {
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
core::Matrix6d sqrtInformation(const core::Matrix6d& information) {
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

PoseBlock toBlock(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  const Eigen::Vector3d t = T.translation();
  return {{q.x(), q.y(), q.z(), q.w()}, {t.x(), t.y(), t.z()}};
}

Eigen::Isometry3d fromBlock(const PoseBlock& block) {
  const Eigen::Quaterniond q(block.q[3], block.q[0], block.q[1], block.q[2]);
  return core::makePose(Eigen::Vector3d(block.t[0], block.t[1], block.t[2]), q);
}

ceres::LossFunction* makeLoopLoss(const SolverConfig& config) {
  if (config.loop_loss == "none") return nullptr;
  if (config.loop_loss == "huber") return new ceres::HuberLoss(config.loss_scale);
  if (config.loop_loss == "cauchy") return new ceres::CauchyLoss(config.loss_scale);
  throw core::Error("solver: unknown loop_loss '" + config.loop_loss +
                    "' (expected none, huber or cauchy)");
}

/// The Ceres problem over a graph: blocks for every node a factor touches.
class GraphProblem {
 public:
  GraphProblem(const PoseGraph& graph, const SolverConfig& config) {
    ceres::Problem::Options options;
    options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(options);
    loop_loss_.reset(makeLoopLoss(config));
    for (const auto& [key, pose] : graph.nodes()) blocks_.emplace(key, toBlock(pose));
    for (const Factor& f : graph.factors()) addFactor(graph, f);
    fixGauge(graph, config.fix_lowest);
  }

  ceres::Problem& problem() { return *problem_; }
  [[nodiscard]] std::size_t factors() const { return factors_; }
  [[nodiscard]] std::size_t skipped() const { return skipped_; }

  /// Writes the optimised blocks back; fixed and unconstrained nodes keep their exact estimates.
  void writeBack(PoseGraph& graph) {
    for (auto& [key, block] : blocks_) {
      if (!problem_->HasParameterBlock(block.q) || problem_->IsParameterBlockConstant(block.q)) {
        continue;
      }
      graph.setEstimate(key, fromBlock(block));
    }
  }

 private:
  void addFactor(const PoseGraph& graph, const Factor& f) {
    if (!graph.connects(f)) {
      ++skipped_;
      return;
    }
    PoseBlock& from = blocks_.at(f.from);
    PoseBlock& to = blocks_.at(f.to);
    ceres::LossFunction* loss = isLoop(f.kind) ? loop_loss_.get() : nullptr;
    problem_->AddResidualBlock(RelativePoseError::create(f, sqrtInformation(f.information)), loss,
                               from.q, from.t, to.q, to.t);
    problem_->SetManifold(from.q, &quaternion_manifold_);
    problem_->SetManifold(to.q, &quaternion_manifold_);
    ++factors_;
  }

  void fixGauge(const PoseGraph& graph, bool fix_lowest) {
    std::vector<core::PoseKey> fixed(graph.fixedNodes().begin(), graph.fixedNodes().end());
    if (fixed.empty() && fix_lowest && !blocks_.empty()) fixed.push_back(blocks_.begin()->first);
    for (const core::PoseKey& key : fixed) {
      const auto it = blocks_.find(key);
      if (it == blocks_.end() || !problem_->HasParameterBlock(it->second.q)) continue;
      problem_->SetParameterBlockConstant(it->second.q);
      problem_->SetParameterBlockConstant(it->second.t);
    }
  }

  std::map<core::PoseKey, PoseBlock> blocks_;  // std::map: stable addresses for Ceres
  ceres::EigenQuaternionManifold quaternion_manifold_;
  std::unique_ptr<ceres::LossFunction> loop_loss_;
  std::unique_ptr<ceres::Problem> problem_;  // destroyed first: it points into the members above
  std::size_t factors_ = 0;
  std::size_t skipped_ = 0;
};

ceres::Solver::Options solverOptions(const SolverConfig& config) {
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.max_num_iterations = config.max_iterations;
  options.num_threads = config.threads;
  options.function_tolerance = config.function_tolerance;
  options.logging_type = ceres::SILENT;
  return options;
}

}  // namespace

SolverSummary solveCentralized(PoseGraph& graph, const SolverConfig& config) {
  const auto start = std::chrono::steady_clock::now();
  SolverSummary summary;
  summary.initial_cost = graphCost(graph);
  GraphProblem problem(graph, config);
  summary.factors = problem.factors();
  summary.skipped_factors = problem.skipped();
  if (problem.factors() > 0) {
    ceres::Solver::Summary ceres_summary;
    ceres::Solve(solverOptions(config), &problem.problem(), &ceres_summary);
    problem.writeBack(graph);
    summary.iterations = ceres_summary.num_successful_steps + ceres_summary.num_unsuccessful_steps;
    summary.converged = ceres_summary.termination_type == ceres::CONVERGENCE;
    summary.message = ceres_summary.message;
  } else {
    summary.converged = true;
    summary.message = "no factor to optimise";
  }
  summary.final_cost = graphCost(graph);
  summary.time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace dcl::backend
