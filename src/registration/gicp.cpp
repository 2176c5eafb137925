#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <dcl/core/step_window.hpp>
#include <dcl/registration/gicp.hpp>

namespace dcl::registration {
namespace {

using core::Matrix6d;
using core::Vector6d;

/// The sums of one Gauss-Newton linearisation.
struct LinearSystem {
  Matrix6d H = Matrix6d::Zero();  ///< sum w J^T W J
  Vector6d b = Vector6d::Zero();  ///< sum w J^T W r
  /// Point-to-plane sums of the final pass: information sum w j j^T, weighted
  /// squared distances sum w (n . r)^2 and the number of planar pairs.
  Matrix6d planes = Matrix6d::Zero();
  double plane_residuals = 0.0;
  std::size_t plane_pairs = 0;
  double squared_distances = 0.0;  ///< sum |r|^2, for the RMS fitness
  std::size_t pairs = 0;           ///< pairs
  std::size_t inliers = 0;         ///< pairs within the inlier distance (final pass only)
};

/// Geman-McClure weight of a squared distance (1 without a kernel).
double kernelWeight(double squared_distance, double scale) {
  if (scale <= 0.0) return 1.0;
  const double k2 = scale * scale;
  const double ratio = k2 / (k2 + squared_distance);
  return ratio * ratio;
}

/// Adds the GICP pair (source point `p`, target point `t`). Residual r = t - T p,
/// right perturbation: T exp(xi) p ~ T p + R (rho + phi x p), so dr/dxi = [-R, R hat(p)].
void addPair(const Eigen::Vector3d& p, const Eigen::Vector3d& t, const Eigen::Matrix3d& C_source,
             const Eigen::Matrix3d& C_target, const Eigen::Isometry3d& T, double kernel_scale,
             LinearSystem& system) {
  const Eigen::Matrix3d& R = T.linear();
  const Eigen::Vector3d r = t - T * p;
  const Eigen::Matrix3d W = (C_target + R * C_source * R.transpose()).inverse();
  Eigen::Matrix<double, 3, 6> J;
  J.leftCols<3>() = -R;
  J.rightCols<3>() = R * core::hat(p);
  const double d2 = r.squaredNorm();
  const double w = kernelWeight(d2, kernel_scale);
  const Eigen::Matrix<double, 6, 3> JtW = w * J.transpose() * W;
  system.H.noalias() += JtW * J;
  system.b.noalias() += JtW * r;
  system.squared_distances += d2;
  ++system.pairs;
}

/// Adds the point-to-plane terms of the pair (source point `p`, target point
/// `t` with normal `n`, target frame): residual n . (T p - t), and
/// d(n . (T p))/dxi = [n_s; p x n_s] with n_s = R^T n.
void addPlane(const Eigen::Vector3d& p, const Eigen::Vector3d& t, const Eigen::Vector3d& n,
              const Eigen::Isometry3d& T, double kernel_scale, LinearSystem& system) {
  const Eigen::Vector3d q = T * p;
  const double r = n.dot(q - t);
  const double w = kernelWeight((q - t).squaredNorm(), kernel_scale);
  const Eigen::Vector3d n_source = T.linear().transpose() * n;
  Vector6d j;
  j << n_source, p.cross(n_source);
  system.planes.noalias() += w * j * j.transpose();
  system.plane_residuals += w * r * r;
  ++system.plane_pairs;
}

/// A source point's partner: the nearest target point where it was last searched.
struct Association {
  Eigen::Vector3d searched_at = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  std::uint32_t target = 0;
  bool valid = false;  ///< a target point was within the gate
};

/// The partner of a source point now at `q`, searched again only once the
/// point has moved `reassociation` metres since the last search: late
/// Gauss-Newton steps move points by millimetres, and the searches are most of
/// the cost of an iteration.
const Association& associate(const RegistrationCloud& target, const Eigen::Vector3d& q, double gate,
                             double reassociation, Association& a) {
  if ((q - a.searched_at).squaredNorm() <= reassociation * reassociation) return a;
  a.searched_at = q;
  const auto nearest = target.tree().nearest(q, gate);
  a.valid = nearest.has_value();
  if (nearest) a.target = nearest->index;
  return a;
}

/// The GICP system of all source points at `T`; with `final_pass`, also the
/// inliers and the point-to-plane terms of the covariance and degeneracy.
LinearSystem linearize(RegistrationCloud& target, RegistrationCloud& source,
                       const Eigen::Isometry3d& T, const GicpConfig& config,
                       std::vector<Association>& associations, bool final_pass) {
  LinearSystem system;
  const std::vector<Eigen::Vector3d>& points = source.points();
  const double gate2 = config.max_correspondence_distance * config.max_correspondence_distance;
  const double inlier =
      config.inlier_distance > 0.0 ? config.inlier_distance : config.max_correspondence_distance;
  const double inlier2 = inlier * inlier;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d q = T * points[i];
    const Association& a =
        associate(target, q, config.max_correspondence_distance,
                  final_pass ? 0.0 : config.reassociation_distance, associations[i]);
    if (!a.valid || (target.points()[a.target] - q).squaredNorm() > gate2) continue;
    const std::size_t j = a.target;
    addPair(points[i], target.points()[j], source.covariance(i), target.covariance(j), T,
            config.kernel_scale, system);
    if (!final_pass) continue;
    if ((target.points()[j] - q).squaredNorm() < inlier2) ++system.inliers;
    if (target.planar(j))
      addPlane(points[i], target.points()[j], target.normal(j), T, config.kernel_scale, system);
  }
  return system;
}

/// The Gauss-Newton step, lightly damped so that directions the scene leaves
/// free stay where they are instead of jumping.
Vector6d solveStep(const LinearSystem& system) {
  const double damping = 1e-9 * std::max(system.H.trace(), 1e-12);
  return -(system.H + damping * Matrix6d::Identity()).ldlt().solve(system.b);
}

/// The RMS distance of `points` from the origin (m), at least 1: the lever arm
/// that turns a rotation into a displacement.
double rmsRange(const std::vector<Eigen::Vector3d>& points) {
  double sum = 0.0;
  for (const Eigen::Vector3d& p : points) sum += p.squaredNorm();
  return points.empty() ? 1.0 : std::max(std::sqrt(sum / static_cast<double>(points.size())), 1.0);
}

/// Weakest over strongest eigenvalue of `information` with rotations expressed
/// as displacements at `lever` metres, so that the six directions share a unit.
double eigenvalueRatio(const Matrix6d& information, double lever) {
  Vector6d scale;
  scale << 1.0, 1.0, 1.0, 1.0 / lever, 1.0 / lever, 1.0 / lever;
  const Matrix6d scaled = scale.asDiagonal() * information * scale.asDiagonal();
  const Vector6d eigenvalues = Eigen::SelfAdjointEigenSolver<Matrix6d>(scaled).eigenvalues();
  return eigenvalues(5) > 0.0 ? std::max(eigenvalues(0), 0.0) / eigenvalues(5) : 0.0;
}

/// sigma^2 J^T W J^-1 of the point-to-plane terms, sigma^2 their residual
/// variance, through the eigen decomposition: eigenvalues are floored so that
/// the result is symmetric positive definite even when a direction is free, and
/// variances are capped at kUnknownVariance.
Matrix6d covarianceOf(const LinearSystem& system) {
  constexpr double kUnknownVariance = 1e6;  // m^2 and rad^2: nothing is known
  if (system.plane_pairs <= 6) return kUnknownVariance * Matrix6d::Identity();
  const double variance = system.plane_residuals / static_cast<double>(system.plane_pairs - 6);
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(system.planes);
  const Vector6d lambda = solver.eigenvalues();
  const double floor = std::max(lambda(5) * 1e-12, std::numeric_limits<double>::min());
  Vector6d inverse;
  for (int k = 0; k < 6; ++k)
    inverse(k) = std::min(variance / std::max(lambda(k), floor), kUnknownVariance);
  const Matrix6d covariance =
      solver.eigenvectors() * inverse.asDiagonal() * solver.eigenvectors().transpose();
  return 0.5 * (covariance + covariance.transpose());
}

}  // namespace

RegistrationCloud::RegistrationCloud(std::vector<Eigen::Vector3d> points, int neighbors)
    : tree_(std::move(points)),
      neighbors_(std::clamp<std::size_t>(static_cast<std::size_t>(std::max(neighbors, 3)), 3,
                                         PointTree::kMaxNeighbors)),
      shapes_(tree_.size()),
      ready_(tree_.size(), 0) {}

const Eigen::Matrix3d& RegistrationCloud::covariance(std::size_t i) {
  return shape(i).covariance;
}

const Eigen::Vector3d& RegistrationCloud::normal(std::size_t i) {
  return shape(i).normal;
}

bool RegistrationCloud::planar(std::size_t i) {
  return shape(i).planar;
}

void RegistrationCloud::computeAllShapes() {
  for (std::size_t i = 0; i < size(); ++i) shape(i);
}

const RegistrationCloud::Shape& RegistrationCloud::shape(std::size_t i) {
  if (ready_[i] == 0) computeShape(i);
  return shapes_[i];
}

void RegistrationCloud::computeShape(std::size_t i) {
  const Eigen::Vector3d& p = points()[i];
  tree_.nearest(p, neighbors_, std::numeric_limits<double>::infinity(), scratch_);
  Shape& s = shapes_[i];
  ready_[i] = 1;
  if (scratch_.size() < 3) return;  // isotropic, no normal: the defaults
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Neighbor& n : scratch_) mean += points()[n.index];
  mean /= static_cast<double>(scratch_.size());
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (const Neighbor& n : scratch_) {
    const Eigen::Vector3d d = points()[n.index] - mean;
    spread.noalias() += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(spread);
  const Eigen::Matrix3d& V = solver.eigenvectors();
  const Eigen::Vector3d& lambda = solver.eigenvalues();  // increasing
  s.covariance = V * Eigen::Vector3d(kPlaneEpsilon, 1.0, 1.0).asDiagonal() * V.transpose();
  s.normal = V.col(0);
  if (s.normal.dot(p) > 0.0) s.normal = -s.normal;  // towards the sensor at the origin
  s.planar = lambda(0) <= 0.3 * lambda(1) && lambda(1) >= 0.05 * lambda(2);
}

GicpResult alignGicp(RegistrationCloud& target, RegistrationCloud& source,
                     const Eigen::Isometry3d& T_target_source_guess, const GicpConfig& config) {
  GicpResult result;
  result.T_target_source = T_target_source_guess;
  if (target.empty() || source.empty()) return result;
  std::vector<Association> associations(source.size());
  core::StepWindow<4> window;  // cycles of period 1, 2 and 4
  bool converged = false;
  for (int iteration = 0; iteration < config.max_iterations && !converged; ++iteration) {
    const LinearSystem system =
        linearize(target, source, result.T_target_source, config, associations, false);
    result.iterations = iteration + 1;
    if (system.pairs < 6) break;
    const Vector6d step = solveStep(system);
    if (!step.allFinite()) break;
    result.T_target_source = result.T_target_source * core::expSE3(step);
    converged = step.norm() < config.convergence_criterion ||
                window.add(step) < 10.0 * config.convergence_criterion;
  }
  const LinearSystem final_system =
      linearize(target, source, result.T_target_source, config, associations, true);
  result.pairs = final_system.pairs;
  result.inliers = final_system.inliers;
  result.inlier_share =
      static_cast<double>(final_system.inliers) / static_cast<double>(source.size());
  result.fitness =
      final_system.pairs > 0
          ? std::sqrt(final_system.squared_distances / static_cast<double>(final_system.pairs))
          : 0.0;
  result.converged = converged && final_system.pairs >= config.min_pairs;
  result.hessian = final_system.H;
  result.covariance = covarianceOf(final_system);
  result.degeneracy = eigenvalueRatio(final_system.planes, rmsRange(source.points()));
  return result;
}

}  // namespace dcl::registration
