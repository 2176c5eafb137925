#pragma once

/// Umeyama alignment of an estimated trajectory onto its ground truth, as evo aligns
/// (`evo_ape -a` for SE(3), `-as` for Sim(3)).

#include <Eigen/Core>
#include <string_view>

#include <dcl/core/trajectory.hpp>
#include <dcl/eval/association.hpp>

namespace dcl::eval {

/// Which transformation maps the estimate's world frame onto the ground truth's.
enum class Alignment {
  none,  ///< compare as given
  se3,   ///< rotation and translation
  sim3,  ///< rotation, translation and scale (monocular estimates)
};

/// "none", "se3" or "sim3".
std::string_view toString(Alignment alignment);

/// Parses "none", "se3" or "sim3"; throws core::Error naming the accepted names otherwise.
Alignment parseAlignment(std::string_view name);

/// A similarity transformation x -> s R x + t (a rigid one when s == 1).
struct Sim3 {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  ///< rotation
  Eigen::Vector3d t = Eigen::Vector3d::Zero();      ///< translation, metres of the target frame
  double s = 1.0;                                   ///< scale

  /// Maps the point `p`: s R p + t.
  [[nodiscard]] Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return s * R * p + t; }
};

/// The least-squares S minimising sum |target_i - S source_i|^2 (Umeyama 1991, eqs. 34-43,
/// as evo's `umeyama_alignment`); scale 1 unless `with_scale`. Points are columns. Throws
/// core::Error for mismatched sizes, fewer than 3 points, or collinear / coincident points.
Sim3 umeyamaAlignment(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                      bool with_scale);

/// The positions of `trajectory` as the columns of a matrix.
Eigen::Matrix3Xd positions(const core::Trajectory& trajectory);

/// The alignment S_gt_est of the associated estimate onto the ground truth, from all pairs'
/// positions; identity for Alignment::none.
Sim3 computeAlignment(const Association& pairs, Alignment alignment);

/// `trajectory` mapped by `S_target_source` as evo's `align` does: positions scaled by s, then
/// every pose left-multiplied by (R, t); orientations become R R_i, positions s R p_i + t.
core::Trajectory transformed(const core::Trajectory& trajectory, const Sim3& S_target_source);

}  // namespace dcl::eval
