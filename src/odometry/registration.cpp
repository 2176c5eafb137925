#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <dcl/core/step_window.hpp>
#include <dcl/odometry/preprocessing.hpp>
#include <dcl/odometry/registration.hpp>

namespace dcl::odometry {
namespace {

using Vector6d = core::Vector6d;
using Matrix6d = core::Matrix6d;

/// The normal equations of one Gauss-Newton step, summed over correspondences.
/// With a sweep's twist estimated too, a point fired at offset tau moves by
/// tau times the twist, so its Jacobian for the twist is tau times the one for
/// the pose (to first order within the sweep) and the 12x12 system is made of
/// the sums of w J^T J weighted by 1, tau and tau^2.
struct LinearSystem {
  Matrix6d H = Matrix6d::Zero();             ///< J^T W J (pose)
  Vector6d b = Vector6d::Zero();             ///< J^T W r (pose)
  Matrix6d H_pose_twist = Matrix6d::Zero();  ///< sum tau J^T W J
  Matrix6d H_twist = Matrix6d::Zero();       ///< sum tau^2 J^T W J
  Vector6d b_twist = Vector6d::Zero();       ///< sum tau J^T W r
  double squared_residuals = 0.0;            ///< sum of r^2 (unweighted), for the RMSE
  std::size_t inliers = 0;                   ///< correspondences
  bool twist = false;                        ///< the twist blocks are summed

  LinearSystem& operator+=(const LinearSystem& other) {
    H += other.H;
    b += other.b;
    if (twist) {
      H_pose_twist += other.H_pose_twist;
      H_twist += other.H_twist;
      b_twist += other.b_twist;
    }
    squared_residuals += other.squared_residuals;
    inliers += other.inliers;
    return *this;
  }

  /// Adds one correspondence's w J^T J and w J^T r, fired at offset `tau`.
  void add(const Matrix6d& JtJ, const Vector6d& Jtr, double tau) {
    H += JtJ;
    b += Jtr;
    if (!twist) return;
    H_pose_twist.noalias() += tau * JtJ;
    H_twist.noalias() += (tau * tau) * JtJ;
    b_twist.noalias() += tau * Jtr;
  }
};

/// The Geman-McClure weight of a squared residual: downweights pairs beyond
/// `kernel_scale` smoothly (KISS-ICP's robust kernel), so outliers that pass
/// the correspondence gate barely pull.
double gemanMcClureWeight(double squared_residual, double kernel_scale) {
  const double k2 = kernel_scale * kernel_scale;
  const double denominator = k2 + squared_residual;
  return k2 * k2 / (denominator * denominator);
}

/// The `k` map points nearest a query, closest first (k at most kMaxNeighbors).
constexpr auto kMaxNeighbors = static_cast<std::size_t>(IcpConfig::kMaxNormalNeighbors);
struct NearestSet {
  std::array<Eigen::Vector3d, kMaxNeighbors> points;
  std::array<double, kMaxNeighbors> squared_distances;
  std::size_t size = 0;
  std::size_t capacity = 1;

  /// Keeps `point` if it is among the `capacity` nearest seen so far (insertion sort).
  void offer(const Eigen::Vector3d& point, double d2) {
    if (size == capacity && d2 >= squared_distances[size - 1]) return;
    std::size_t i = size < capacity ? size++ : size - 1;
    for (; i > 0 && squared_distances[i - 1] > d2; --i) {
      points[i] = points[i - 1];
      squared_distances[i] = squared_distances[i - 1];
    }
    points[i] = point;
    squared_distances[i] = d2;
  }
};

NearestSet nearestPoints(const VoxelHashMap& map, const Eigen::Vector3d& query, std::size_t k) {
  NearestSet set;
  set.capacity = std::clamp<std::size_t>(k, 1, kMaxNeighbors);
  map.forEachPointNear(query, [&](const Eigen::Vector3d& point) {
    set.offer(point, (point - query).squaredNorm());
  });
  return set;
}

/// A local plane: a point on it and its unit normal.
struct Plane {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
};

/// The plane fitted to the neighbours by their covariance; none when fewer than
/// three, when they are not flat (smallest/middle eigenvalue above
/// `max_planarity`: a pole, a corner, a bush) or when they lie along a line
/// (middle/largest eigenvalue below `min_spread`). The last matters most: on
/// the ground, a sparse map's nearest points often come from one laser ring,
/// whose "normal" is then arbitrary around the ring, often horizontal; such
/// constraints move with the sensor and drag the estimate towards standing still.
std::optional<Plane> fitPlane(const NearestSet& set, double max_planarity, double min_spread) {
  if (set.size < 3) return std::nullopt;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < set.size; ++i) mean += set.points[i];
  mean /= static_cast<double>(set.size);
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < set.size; ++i) {
    const Eigen::Vector3d d = set.points[i] - mean;
    covariance += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(covariance);
  const Eigen::Vector3d& eigenvalues = solver.eigenvalues();  // increasing
  if (!(eigenvalues(0) <= max_planarity * eigenvalues(1))) return std::nullopt;
  if (!(eigenvalues(1) >= min_spread * eigenvalues(2))) return std::nullopt;
  return Plane{mean, solver.eigenvectors().col(0)};
}

/// Adds the point-to-point residual of source point `p` (mapped to `q` = T p,
/// fired at offset `tau`) to `system`. Right perturbation, T exp(xi) p ~ q + R
/// (rho + phi x p), so the system lives in the source (sensor) frame and is
/// well scaled however far the sensor is from the map origin.
void addPointToPoint(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Matrix3d& R,
                     const Eigen::Vector3d& target, double kernel_scale, double tau,
                     LinearSystem& system) {
  const Eigen::Vector3d r = q - target;
  const Eigen::Vector3d r_source = R.transpose() * r;
  Eigen::Matrix<double, 3, 6> J;
  J.leftCols<3>().setIdentity();
  J.rightCols<3>() = -core::hat(p);
  const double w = gemanMcClureWeight(r.squaredNorm(), kernel_scale);
  system.add(w * J.transpose() * J, w * J.transpose() * r_source, tau);
  system.squared_residuals += r.squaredNorm();
  ++system.inliers;
}

/// Adds the point-to-plane residual n . (q - c): with n_s = R^T n the normal in
/// the source frame, d/drho = n_s and d/dphi = p x n_s.
void addPointToPlane(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Matrix3d& R,
                     const Plane& plane, double kernel_scale, double tau, LinearSystem& system) {
  const double r = plane.normal.dot(q - plane.point);
  const Eigen::Vector3d n_source = R.transpose() * plane.normal;
  Vector6d J;
  J << n_source, p.cross(n_source);
  const double w = gemanMcClureWeight(r * r, kernel_scale);
  system.add(w * J * J.transpose(), w * J * r, tau);
  system.squared_residuals += r * r;
  ++system.inliers;
}

/// One source point's correspondence: the local plane (point-to-plane) or the
/// nearest map point (point-to-point, as `plane.point`), and where it was searched.
struct Association {
  Eigen::Vector3d searched_at = Eigen::Vector3d::Zero();  ///< T p when it was searched
  Plane plane{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ()};
  bool searched = false;  ///< a search was made
  bool valid = false;     ///< the search found a usable correspondence
};

/// Searches the map around `q` for a correspondence within the gate.
Association associate(const Eigen::Vector3d& q, const VoxelHashMap& map, const IcpConfig& config,
                      bool point_to_plane) {
  Association association;
  association.searched_at = q;
  association.searched = true;
  const std::size_t k = point_to_plane ? static_cast<std::size_t>(config.normal_neighbors) : 1;
  const NearestSet nearest = nearestPoints(map, q, k);
  const double gate = config.max_correspondence_distance;
  if (nearest.size == 0 || nearest.squared_distances[0] > gate * gate) return association;
  if (!point_to_plane) {
    association.plane.point = nearest.points[0];
    association.valid = true;
  } else if (const auto plane = fitPlane(nearest, config.max_planarity, config.min_spread)) {
    association.plane = *plane;
    association.valid = true;
  }
  return association;
}

/// The residual of source point `p` (deskewed, fired at offset `tau`) added
/// to `system`. A plane correspondence is searched again only once T p has
/// moved `reassociation_distance` since the last search: the map does not
/// change during a registration, a plane stays valid as a point slides along
/// it, and late Gauss-Newton steps move points by millimetres, so this skips
/// most of the 27-voxel searches and plane fits, which are nearly all of the
/// cost. Point-to-point needs a fresh nearest point every iteration (a fixed
/// one pins the point in place).
void linearizePoint(const Eigen::Vector3d& p, double tau, const Eigen::Isometry3d& T,
                    const VoxelHashMap& map, const IcpConfig& config, bool point_to_plane,
                    Association& association, LinearSystem& system) {
  const Eigen::Vector3d q = T * p;
  const double reassociate = config.reassociation_distance;
  if (!point_to_plane || !association.searched ||
      (q - association.searched_at).squaredNorm() > reassociate * reassociate) {
    association = associate(q, map, config, point_to_plane);
  }
  if (!association.valid) return;
  const Eigen::Matrix3d R = T.linear();
  if (point_to_plane) {
    addPointToPlane(p, q, R, association.plane, config.kernel_scale, tau, system);
  } else {
    addPointToPoint(p, q, R, association.plane.point, config.kernel_scale, tau, system);
  }
}

/// The source as one linearisation sees it: points in the sensor frame at
/// their firing times and, for a sweep whose twist is estimated, their
/// offsets and the motion that deskews them at the current twist.
struct Source {
  std::span<const Eigen::Vector3d> points;
  std::span<const double> offsets;      ///< empty: a rigid scan
  const SweepMotion* motion = nullptr;  ///< with offsets: exp(tau * twist)

  [[nodiscard]] bool sweep() const { return motion != nullptr; }
  /// Point `i` in the sensor frame at the reference time.
  [[nodiscard]] Eigen::Vector3d deskewed(std::size_t i) const {
    return sweep() ? Eigen::Vector3d(motion->at(offsets[i]) * points[i]) : points[i];
  }
};

/// The normal equations of all source points at `T_target_source`, reduced in
/// parallel. Deterministic: fixed chunks summed in a fixed order, whatever the
/// thread count, so a run is reproducible.
LinearSystem linearize(const Source& source, const VoxelHashMap& map,
                       const Eigen::Isometry3d& T_target_source, const IcpConfig& config,
                       bool point_to_plane, std::span<Association> associations) {
  constexpr std::size_t kGrain = 256;
  LinearSystem empty;
  empty.twist = source.sweep();
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, source.points.size(), kGrain), empty,
      [&](const tbb::blocked_range<std::size_t>& range, LinearSystem system) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
          const double tau = source.sweep() ? source.offsets[i] : 0.0;
          linearizePoint(source.deskewed(i), tau, T_target_source, map, config, point_to_plane,
                         associations[i], system);
        }
        return system;
      },
      [](LinearSystem a, const LinearSystem& b) { return a += b; });
}

/// The Gauss-Newton step for `system`, lightly damped so that directions the
/// scene does not constrain (e.g. sliding along a plane) stay where they are.
Vector6d solveStep(const LinearSystem& system) {
  const double damping = 1e-9 * std::max(system.H.trace(), 1e-12);
  const Matrix6d H = system.H + damping * Matrix6d::Identity();
  return -H.ldlt().solve(system.b);
}

/// The RMS range of the source points (m): the lever arm that turns a rotation
/// into a displacement, used to compare rotational and translational information.
double rmsRange(std::span<const Eigen::Vector3d> source) {
  double sum = 0.0;
  for (const Eigen::Vector3d& p : source) sum += p.squaredNorm();
  return source.empty() ? 1.0 : std::max(std::sqrt(sum / static_cast<double>(source.size())), 1.0);
}

/// True when the weakest direction of `information` (right perturbation) holds
/// less than `threshold` of the strongest, rotations expressed as displacements
/// at the scan's RMS range so the six directions share one unit.
bool isDegenerate(const Matrix6d& information, double rms_range, double threshold) {
  Vector6d scale;
  scale << 1.0, 1.0, 1.0, 1.0 / rms_range, 1.0 / rms_range, 1.0 / rms_range;
  const Matrix6d scaled = scale.asDiagonal() * information * scale.asDiagonal();
  const Vector6d eigenvalues = Eigen::SelfAdjointEigenSolver<Matrix6d>(scaled).eigenvalues();
  return !(eigenvalues(0) > threshold * eigenvalues(5));
}

/// The point-to-plane information at `T`, with fresh correspondences.
Matrix6d planeInformation(std::span<const Eigen::Vector3d> points, const VoxelHashMap& map,
                          const Eigen::Isometry3d& T, const IcpConfig& config) {
  std::vector<Association> associations(points.size());
  return linearize(Source{points, {}, nullptr}, map, T, config, true, associations).H;
}

/// A pose step and a twist step.
struct SweepStep {
  Vector6d pose;
  Vector6d twist;
};

/// The Gauss-Newton step of a sweep's pose and twist: the points' system read
/// as residuals of `noise` m, and the prior on the twist, which sits at `twist`.
SweepStep solveSweepStep(const LinearSystem& system, const Vector6d& twist,
                         const SweepMotionPrior& prior, double noise) {
  using Matrix12d = Eigen::Matrix<double, 12, 12>;
  using Vector12d = Eigen::Matrix<double, 12, 1>;
  Matrix12d H;
  H << system.H, system.H_pose_twist, system.H_pose_twist, system.H_twist;
  Vector12d b;
  b << system.b, system.b_twist;
  const double scale = 1.0 / (noise * noise);
  H *= scale;
  b *= scale;
  const Vector6d information = prior.sigma.array().square().inverse();
  H.diagonal().tail<6>() += information;
  b.tail<6>() += information.cwiseProduct(twist - prior.velocity);
  H.diagonal().array() += 1e-9 * std::max(H.trace(), 1e-12);
  const Vector12d step = -H.ldlt().solve(b);
  return {step.head<6>(), step.tail<6>()};
}

/// The first and last offset of a sweep.
std::pair<double, double> offsetSpan(std::span<const double> offsets) {
  const auto [first, last] = std::minmax_element(offsets.begin(), offsets.end());
  return {*first, *last};
}

/// Registration of `points` (with `offsets` and a twist `prior`: a sweep)
/// against `map`; the shared loop of registerScan and registerSweep.
SweepRegistration registerPoints(std::span<const Eigen::Vector3d> points,
                                 std::span<const double> offsets, const VoxelHashMap& map,
                                 const Eigen::Isometry3d& T_guess, const SweepMotionPrior* prior,
                                 const IcpConfig& config) {
  SweepRegistration out;
  RegistrationResult& result = out.registration;
  result.T_target_source = T_guess;
  if (prior) out.velocity = prior->velocity;
  if (points.empty() || map.empty()) return out;
  const bool sweep = prior && !offsets.empty() && offsets.size() == points.size();
  const auto [t_min, t_max] = sweep ? offsetSpan(offsets) : std::pair{0.0, 0.0};
  const double half_span = 0.5 * (t_max - t_min);
  std::vector<Association> associations(points.size());
  LinearSystem system;
  core::StepWindow<8> window;  // cycles of period 1, 2, 4 and 8
  bool converged = false;
  for (int iteration = 0; iteration < config.max_iterations && !converged; ++iteration) {
    const std::optional<SweepMotion> motion =
        sweep ? std::optional<SweepMotion>(std::in_place, out.velocity, t_min, t_max)
              : std::nullopt;
    const Source source{points, offsets, motion ? &*motion : nullptr};
    system =
        linearize(source, map, result.T_target_source, config, config.point_to_plane, associations);
    result.iterations = iteration + 1;
    if (system.inliers < 6) break;
    const SweepStep step = sweep ? solveSweepStep(system, out.velocity, *prior, config.kernel_scale)
                                 : SweepStep{solveStep(system), Vector6d::Zero()};
    if (!step.pose.allFinite() || !step.twist.allFinite()) break;
    result.T_target_source = result.T_target_source * core::expSE3(step.pose);
    out.velocity += step.twist;
    const double twist_step = half_span * step.twist.norm();  // m or rad at the sweep's ends
    converged = std::max(step.pose.norm(), twist_step) < config.convergence_criterion ||
                (window.add(step.pose) < 10.0 * config.convergence_criterion &&
                 twist_step < 10.0 * config.convergence_criterion);
  }
  result.inliers = system.inliers;
  result.rmse = system.inliers > 0
                    ? std::sqrt(system.squared_residuals / static_cast<double>(system.inliers))
                    : 0.0;
  result.converged = converged && system.inliers >= config.min_inliers;
  result.information = system.H;
  // Point-to-point information is full rank even on a single plane, so
  // degeneracy is always judged on the point-to-plane information.
  const Matrix6d plane_information =
      config.point_to_plane ? result.information
                            : planeInformation(points, map, result.T_target_source, config);
  result.degenerate = system.inliers < 6 || isDegenerate(plane_information, rmsRange(points),
                                                         config.degeneracy_threshold);
  return out;
}

}  // namespace

RegistrationResult registerScan(std::span<const Eigen::Vector3d> source_points,
                                const VoxelHashMap& target_map,
                                const Eigen::Isometry3d& T_target_source_guess,
                                const IcpConfig& config) {
  return registerPoints(source_points, {}, target_map, T_target_source_guess, nullptr, config)
      .registration;
}

SweepRegistration registerSweep(const SweepPoints& sweep, const VoxelHashMap& target_map,
                                const Eigen::Isometry3d& T_target_source_guess,
                                const SweepMotionPrior& prior, const IcpConfig& config) {
  return registerPoints(sweep.points, sweep.offsets, target_map, T_target_source_guess, &prior,
                        config);
}

AdaptiveThreshold::AdaptiveThreshold(const AdaptiveThresholdConfig& config, double max_range)
    : config_(config), max_range_(max_range) {}

void AdaptiveThreshold::update(const Eigen::Isometry3d& T_deviation, double motion) {
  if (motion < config_.min_motion) return;
  // The largest displacement the deviation causes to a point within max_range:
  // a rotation by theta moves a point at range R by 2 R sin(theta / 2).
  const double theta = core::rotationAngle(T_deviation.rotation());
  const double error = 2.0 * max_range_ * std::sin(theta / 2.0) + T_deviation.translation().norm();
  sum_squared_ += error * error;
  ++count_;
}

double AdaptiveThreshold::sigma() const {
  if (count_ == 0) return config_.initial_threshold;
  return std::max(std::sqrt(sum_squared_ / static_cast<double>(count_)), config_.min_threshold);
}

}  // namespace dcl::odometry
