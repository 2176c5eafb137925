#include <Eigen/SVD>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/eval/alignment.hpp>

namespace dcl::eval {

namespace {

// Below this ratio of the second to the first singular value of the cross-covariance the
// points lie on a line (or on one point) and the rotation about that line is undetermined.
constexpr double kDegenerateRatio = 1e-12;

void checkShapes(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target) {
  if (source.cols() != target.cols()) {
    throw core::Error(fmt::format("Umeyama alignment: {} source points but {} target points",
                                  source.cols(), target.cols()));
  }
  if (source.cols() < 3) {
    throw core::Error(
        fmt::format("Umeyama alignment needs at least 3 point pairs, got {}", source.cols()));
  }
}

void checkRank(const Eigen::Vector3d& singular_values) {
  if (!(singular_values(1) > kDegenerateRatio * singular_values(0))) {
    throw core::Error(
        "Umeyama alignment is not possible: the points are collinear or coincident "
        "(degenerate covariance rank)");
  }
}

}  // namespace

std::string_view toString(Alignment alignment) {
  switch (alignment) {
    case Alignment::se3:
      return "se3";
    case Alignment::sim3:
      return "sim3";
    case Alignment::none:
      break;
  }
  return "none";
}

Alignment parseAlignment(std::string_view name) {
  if (name == "none") return Alignment::none;
  if (name == "se3") return Alignment::se3;
  if (name == "sim3") return Alignment::sim3;
  throw core::Error(fmt::format("unknown alignment '{}' (expected none, se3 or sim3)", name));
}

Sim3 umeyamaAlignment(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                      bool with_scale) {
  checkShapes(source, target);
  const auto n = static_cast<double>(source.cols());
  const Eigen::Vector3d mean_x = source.rowwise().mean();
  const Eigen::Vector3d mean_y = target.rowwise().mean();
  const Eigen::Matrix3Xd x = source.colwise() - mean_x;
  const Eigen::Matrix3Xd y = target.colwise() - mean_y;
  const double sigma_x = x.squaredNorm() / n;            // eq. 36
  const Eigen::Matrix3d cov_xy = y * x.transpose() / n;  // eq. 38
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov_xy, Eigen::ComputeFullU | Eigen::ComputeFullV);
  checkRank(svd.singularValues());
  Eigen::Vector3d S = Eigen::Vector3d::Ones();  // eq. 43, a proper rotation
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2) = -1.0;
  Sim3 result;
  result.R = svd.matrixU() * S.asDiagonal() * svd.matrixV().transpose();  // eq. 40
  result.s = with_scale ? svd.singularValues().dot(S) / sigma_x : 1.0;    // eq. 42
  result.t = mean_y - result.s * result.R * mean_x;                       // eq. 41
  return result;
}

Eigen::Matrix3Xd positions(const core::Trajectory& trajectory) {
  Eigen::Matrix3Xd p(3, static_cast<Eigen::Index>(trajectory.size()));
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    p.col(static_cast<Eigen::Index>(i)) = trajectory.pose(i).translation();
  }
  return p;
}

Sim3 computeAlignment(const Association& pairs, Alignment alignment) {
  if (alignment == Alignment::none) return {};
  return umeyamaAlignment(positions(pairs.estimate), positions(pairs.ground_truth),
                          alignment == Alignment::sim3);
}

core::Trajectory transformed(const core::Trajectory& trajectory, const Sim3& S_target_source) {
  core::Trajectory out = trajectory;
  for (std::size_t i = 0; i < out.size(); ++i) {
    Eigen::Isometry3d& T = out.pose(i);
    T.translation() = S_target_source * T.translation().eval();
    T.linear() = (S_target_source.R * T.linear()).eval();
  }
  return out;
}

}  // namespace dcl::eval
