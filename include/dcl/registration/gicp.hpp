#pragma once

/// Generalized ICP (Segal, Haehnel, Thrun 2009): each point carries the
/// covariance of its neighbourhood, flattened to a plane, and a correspondence
/// costs the Mahalanobis distance under the sum of both covariances, so two
/// surfaces slide along each other instead of pinning point to point. It is
/// what fast_gicp and small_gicp run; the reference transforms of the outdoor
/// pair in the test data come from them.
///
/// Conventions: the estimate is T_target_source (maps source points into the
/// target frame); its tangent is [rho; phi] with the perturbation on the right,
/// T_target_source * exp(xi), xi in the source frame, as core/se3.hpp and the
/// pose graph's factors (backend/pose_graph.hpp) use it.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/registration/point_tree.hpp>

namespace dcl::registration {

/// A cloud ready for registration: its points in a kd-tree and, per point, the
/// shape of its neighbourhood. Shapes are computed on first use and kept: a
/// submap of twenty keyframes is mostly outside the query's reach, and the
/// neighbour searches behind a shape are the largest cost of GICP. So a cloud
/// is not const while it registers and must not be shared between threads.
class RegistrationCloud {
 public:
  /// Plane thickness relative to its extent in a regularised covariance (GICP's epsilon).
  static constexpr double kPlaneEpsilon = 1e-3;

  /// Takes `points` (in the cloud's frame, sensor at the origin); shapes come
  /// from each point's `neighbors` nearest points (at least 3, at most
  /// PointTree::kMaxNeighbors).
  explicit RegistrationCloud(std::vector<Eigen::Vector3d> points = {}, int neighbors = 10);

  [[nodiscard]] const PointTree& tree() const { return tree_; }
  [[nodiscard]] const std::vector<Eigen::Vector3d>& points() const { return tree_.points(); }
  [[nodiscard]] std::size_t size() const { return tree_.size(); }
  [[nodiscard]] bool empty() const { return tree_.empty(); }

  /// The regularised covariance of point `i` (< size()): its neighbourhood's principal
  /// axes with the variances set to (epsilon, 1, 1), a plane of unit extent
  /// (GICP's plane-to-plane model; robust to the anisotropic sampling of a LiDAR).
  const Eigen::Matrix3d& covariance(std::size_t i);

  /// The unit normal at point `i` (smallest principal axis), turned towards the
  /// sensor at the origin so that normals of one surface agree.
  const Eigen::Vector3d& normal(std::size_t i);

  /// True when the neighbourhood of point `i` is flat enough for its normal to
  /// mean something: smallest variance at most 0.3 of the middle one, and the
  /// middle one at least 0.05 of the largest (not a line, as one laser ring).
  bool planar(std::size_t i);

  /// Computes every shape now (e.g. before timing-sensitive work, or for FPFH).
  void computeAllShapes();

 private:
  struct Shape {
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    bool planar = false;
  };
  const Shape& shape(std::size_t i);
  void computeShape(std::size_t i);

  PointTree tree_;
  std::size_t neighbors_;
  std::vector<Shape> shapes_;
  std::vector<std::uint8_t> ready_;
  std::vector<Neighbor> scratch_;
};

/// How GICP runs.
struct GicpConfig {
  int max_iterations = 30;                   ///< Gauss-Newton iterations at most
  double max_correspondence_distance = 1.0;  ///< m, farther nearest neighbours are not pairs
  /// Stop when the update's norm (m and rad) is below this, or the net motion
  /// of the last four updates below ten times it (pairs flipping back and forth).
  double convergence_criterion = 1e-4;
  /// m, Geman-McClure scale on the pair distance (0: no kernel): partial
  /// overlap and parked cars moved between visits must not pull.
  double kernel_scale = 0.5;
  std::size_t min_pairs = 30;  ///< fewer pairs than this: not converged
  /// m, pairs closer than this are inliers (GicpResult::inlier_share); 0: the gate
  double inlier_distance = 0.0;
  /// m, a source point keeps its partner until it moves this far (saves searches)
  double reassociation_distance = 0.05;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("max_iterations", max_iterations, "Gauss-Newton iterations at most").positive();
    v.field("max_correspondence_distance", max_correspondence_distance,
            "m, farthest nearest neighbour taken as a pair")
        .positive();
    v.field("convergence_criterion", convergence_criterion, "stop below this update norm")
        .positive();
    v.field("kernel_scale", kernel_scale, "m, Geman-McClure scale on pair distances (0: none)")
        .nonNegative();
    v.field("min_pairs", min_pairs, "fewest pairs for convergence").positive();
    v.field("inlier_distance", inlier_distance, "m, pairs closer are inliers (0: the gate)")
        .nonNegative();
    v.field("reassociation_distance", reassociation_distance,
            "m, a point keeps its partner until it moves this far")
        .nonNegative();
  }
};

/// The outcome of one GICP registration, everything evaluated at the returned pose.
struct GicpResult {
  /// The estimate: maps source points into the target frame.
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  bool converged = false;   ///< the update fell below the criterion with enough pairs
  int iterations = 0;       ///< Gauss-Newton iterations run
  std::size_t pairs = 0;    ///< source points with a partner within the correspondence distance
  std::size_t inliers = 0;  ///< source points with a partner within the inlier distance
  double inlier_share = 0;  ///< inliers / source points
  double fitness = 0.0;     ///< m, RMS distance of all pairs (not only the inliers)
  /// GICP's J^T W J over the pairs (W: inverse summed covariances, kernel weights included).
  core::Matrix6d hessian = core::Matrix6d::Zero();
  /// Covariance of the estimate from the registration: (J^T J)^-1 of the
  /// point-to-plane distances of the pairs on planar target surfaces, scaled by
  /// their residual variance sum(d^2) / (pairs - 6) (kernel weights included).
  /// Not GICP's own Hessian: its regularised covariances give every surface a
  /// unit spread in its plane, which reads the sampling pattern of a bare wall
  /// as a constraint along it; the plane distances claim only what the surfaces
  /// fix, so a direction the scene leaves free (a corridor's length) comes out
  /// large. It assumes independent pairs and is somewhat optimistic otherwise.
  core::Matrix6d covariance = core::Matrix6d::Identity();
  /// Weakest over strongest eigenvalue of that point-to-plane information
  /// (rotations scaled by the source's RMS range): near 0 when the scene leaves
  /// a direction free (a corridor, a bare plane), about 0.05-0.15 in a street.
  double degeneracy = 0.0;
};

/// Registers `source` to `target` from `T_target_source_guess` by Gauss-Newton
/// on GICP's cost. Never throws: empty clouds or too few pairs give converged =
/// false and the last estimate.
GicpResult alignGicp(RegistrationCloud& target, RegistrationCloud& source,
                     const Eigen::Isometry3d& T_target_source_guess, const GicpConfig& config);

}  // namespace dcl::registration
