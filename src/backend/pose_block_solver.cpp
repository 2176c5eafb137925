#include "pose_block_solver.hpp"

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <cmath>
#include <utility>

#include <dcl/core/se3.hpp>

namespace dcl::backend::detail {
namespace {

/// exp(phi) as a unit quaternion.
Eigen::Quaterniond expQuaternion(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  if (theta < 1e-10) return Eigen::Quaterniond(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z());
  return Eigen::Quaterniond(Eigen::AngleAxisd(theta, phi / theta));
}

// Ceres' bounds on Marquardt's diagonal scaling, and on the damping (the
// inverse of its trust region radius bounds).
constexpr double kMinDiagonal = 1e-6;
constexpr double kMaxDiagonal = 1e32;
constexpr double kMinLambda = 1e-16;
constexpr double kMaxLambda = 1e32;

}  // namespace

struct PoseBlockSolver::Cholesky {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> llt;
};

PoseBlockSolver::PoseBlockSolver() : cholesky_(std::make_unique<Cholesky>()) {}
PoseBlockSolver::~PoseBlockSolver() = default;

void PoseBlockSolver::setPose(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node) {
  const auto [it, added] = index_.try_emplace(key, static_cast<int>(poses_.size()));
  if (added) poses_.emplace_back();
  Pose& pose = poses_[it->second];
  pose.q = Eigen::Quaterniond(T_world_node.rotation());
  pose.t = T_world_node.translation();
}

Eigen::Isometry3d PoseBlockSolver::pose(const core::PoseKey& key) const {
  const Pose& pose = poses_[index_.at(key)];
  return core::makePose(pose.t, pose.q);
}

bool PoseBlockSolver::addFactor(const Factor& f) {
  if (f.from == f.to) return false;
  const auto from = index_.find(f.from);
  const auto to = index_.find(f.to);
  if (from == index_.end() || to == index_.end()) return false;
  edges_.push_back({from->second, to->second,
                    RelativePoseMeasurement(f.T_from_to, sqrtInformation(f.information))});
  poses_[from->second].used = poses_[to->second].used = true;
  analysed_ = false;
  return true;
}

bool PoseBlockSolver::setConstant(const core::PoseKey& key) {
  const auto it = index_.find(key);
  if (it == index_.end() || !poses_[it->second].used) return false;
  if (!poses_[it->second].constant) analysed_ = false;
  poses_[it->second].constant = true;
  return true;
}

bool PoseBlockSolver::isVariable(const core::PoseKey& key) const {
  const auto it = index_.find(key);
  return it != index_.end() && poses_[it->second].used && !poses_[it->second].constant;
}

void PoseBlockSolver::analyse() {
  unknowns_ = 0;
  for (Pose& pose : poses_) {
    pose.unknown = pose.used && !pose.constant ? unknowns_ : -1;
    if (pose.unknown >= 0) unknowns_ += 6;
  }
  // The pattern: every free pose's diagonal block, and both off-diagonal
  // blocks of every edge between two free poses.
  active_.clear();
  std::vector<Eigen::Triplet<double>> entries;
  const auto addBlock = [&entries](int row, int col) {
    for (int c = 0; c < 6; ++c) {
      for (int r = 0; r < 6; ++r) entries.emplace_back(row + r, col + c, 0.0);
    }
  };
  for (const Pose& pose : poses_) {
    if (pose.unknown >= 0) addBlock(pose.unknown, pose.unknown);
  }
  for (int e = 0; e < static_cast<int>(edges_.size()); ++e) {
    const int a = poses_[edges_[e].from].unknown;
    const int b = poses_[edges_[e].to].unknown;
    if (a < 0 && b < 0) continue;
    active_.push_back(e);
    if (a >= 0 && b >= 0) {
      addBlock(a, b);
      addBlock(b, a);
    }
  }
  hessian_.resize(unknowns_, unknowns_);
  hessian_.setFromTriplets(entries.begin(), entries.end());  // duplicates merge
  hessian_.makeCompressed();
  // Every column of a block column holds the same rows, so a block's entry
  // (r, c) sits at outer[col + c] + (its offset within column col) + r.
  const int* outer = hessian_.outerIndexPtr();
  const int* inner = hessian_.innerIndexPtr();
  const auto offset = [&](int row, int col, int c) -> std::ptrdiff_t {
    const int* first = inner + outer[col];
    const int* found = std::lower_bound(first, inner + outer[col + 1], row);
    return outer[col + c] + (found - first);
  };
  for (const int e : active_) {
    Edge& edge = edges_[e];
    const int a = poses_[edge.from].unknown;
    const int b = poses_[edge.to].unknown;
    edge.block[0] = a >= 0 ? offset(a, a, 0) : -1;
    edge.block[1] = b >= 0 ? offset(b, b, 0) : -1;
    edge.block[2] = a >= 0 && b >= 0 ? offset(a, b, 0) : -1;
    edge.block[3] = a >= 0 && b >= 0 ? offset(b, a, 0) : -1;
  }
  diagonal_.resize(unknowns_);
  for (int i = 0; i < unknowns_; ++i) diagonal_[i] = offset(i, i, 0);
  gradient_.resize(unknowns_);
  damped_ = hessian_;
  if (unknowns_ > 0) cholesky_->llt.analyzePattern(damped_);
  factorised_ = false;
  analysed_ = true;
}

double PoseBlockSolver::evaluate(const std::vector<Pose>& poses, bool normal_equations) {
  double* values = hessian_.valuePtr();
  const int* outer = hessian_.outerIndexPtr();
  if (normal_equations) {
    std::fill(values, values + hessian_.nonZeros(), 0.0);
    gradient_.setZero();
  }
  // Adds M to the block whose entry (0, 0) is at `first`: column c of the
  // block starts at first + (outer[col + c] - outer[col]).
  const auto addTo = [&](std::ptrdiff_t first, int col, const core::Matrix6d& M) {
    for (int c = 0; c < 6; ++c) {
      double* column = values + first + (outer[col + c] - outer[col]);
      for (int r = 0; r < 6; ++r) column[r] += M(r, c);
    }
  };
  double cost = 0.0;
  core::Matrix6d J_from;
  core::Matrix6d J_to;
  for (const int e : active_) {
    const Edge& edge = edges_[e];
    const Pose& from = poses[edge.from];
    const Pose& to = poses[edge.to];
    if (!normal_equations) {
      cost += edge.measurement.residual(from.q, from.t, to.q, to.t).squaredNorm();
      continue;
    }
    const core::Vector6d r = edge.measurement.linearise(from.q, from.t, to.q, to.t, J_from, J_to);
    cost += r.squaredNorm();
    const int a = poses_[edge.from].unknown;
    const int b = poses_[edge.to].unknown;
    if (a >= 0) {
      addTo(edge.block[0], a, J_from.transpose() * J_from);
      gradient_.segment<6>(a) += J_from.transpose() * r;
    }
    if (b >= 0) {
      addTo(edge.block[1], b, J_to.transpose() * J_to);
      gradient_.segment<6>(b) += J_to.transpose() * r;
    }
    if (a >= 0 && b >= 0) {
      const core::Matrix6d cross = J_from.transpose() * J_to;
      addTo(edge.block[2], b, cross);
      addTo(edge.block[3], a, cross.transpose());
    }
  }
  return cost;
}

std::vector<PoseBlockSolver::Pose> PoseBlockSolver::stepped(const Eigen::VectorXd& delta) const {
  std::vector<Pose> poses = poses_;
  for (Pose& pose : poses) {
    if (pose.unknown < 0) continue;
    const core::Vector6d d = delta.segment<6>(pose.unknown);
    pose.t += pose.q * d.head<3>();
    pose.q = (pose.q * expQuaternion(d.tail<3>())).normalized();
  }
  return poses;
}

bool PoseBlockSolver::factorise() {
  // (J^T J + lambda D) delta = -J^T r, D the clamped diagonal of J^T J.
  double* damped = damped_.valuePtr();
  std::copy(hessian_.valuePtr(), hessian_.valuePtr() + hessian_.nonZeros(), damped);
  for (const std::ptrdiff_t d : diagonal_) {
    damped[d] += lambda_ * std::clamp(damped[d], kMinDiagonal, kMaxDiagonal);
  }
  cholesky_->llt.factorize(damped_);
  factorised_ = cholesky_->llt.info() == Eigen::Success;
  reused_ = 0;
  return factorised_;
}

void PoseBlockSolver::reject() {
  lambda_ = std::min(lambda_ * nu_, kMaxLambda);
  nu_ *= 2.0;
  factorised_ = false;
}

BlockSolveSummary PoseBlockSolver::solve(const BlockSolveOptions& options) {
  BlockSolveSummary summary;
  if (!analysed_) analyse();
  if (unknowns_ == 0) {
    summary.initial_cost = summary.final_cost = evaluate(poses_, false);
    return summary;
  }
  double cost = evaluate(poses_, true);
  summary.initial_cost = cost;
  while (summary.iterations < options.max_iterations) {
    if (gradient_.lpNorm<Eigen::Infinity>() <= options.gradient_tolerance) break;
    ++summary.iterations;
    const bool stale = factorised_ && reused_ < options.factorisation_reuse;
    if (stale) {
      ++reused_;
    } else if (!factorise()) {
      reject();
      continue;
    }
    const Eigen::VectorXd delta = cholesky_->llt.solve(-gradient_);
    // The Gauss-Newton model's decrease of the chi-square: -(2 g.d + d^T H d).
    const double predicted = -(2.0 * gradient_.dot(delta) + delta.dot(hessian_ * delta));
    std::vector<Pose> candidate = stepped(delta);
    const double candidate_cost = evaluate(candidate, false);
    if (!std::isfinite(candidate_cost) || candidate_cost >= cost || predicted <= 0.0) {
      if (stale) {
        factorised_ = false;  // try again at once with a fresh factorisation
        --summary.iterations;
        continue;
      }
      reject();
      continue;
    }
    if (!stale) {  // the damping follows how well the model of its own factorisation predicts
      const double rho = (cost - candidate_cost) / predicted;
      lambda_ =
          std::max(lambda_ * std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)), kMinLambda);
      nu_ = 2.0;
    }
    double norm = 0.0;
    for (const Pose& pose : poses_) {
      if (pose.unknown >= 0) norm += pose.t.squaredNorm() + 1.0;  // |q| = 1
    }
    const bool small_step = delta.norm() <= options.parameter_tolerance *
                                                (std::sqrt(norm) + options.parameter_tolerance);
    const double decrease = (cost - candidate_cost) / cost;
    poses_ = std::move(candidate);
    cost = evaluate(poses_, true);
    if (decrease < options.function_tolerance || small_step) break;
  }
  summary.final_cost = cost;
  return summary;
}

}  // namespace dcl::backend::detail
