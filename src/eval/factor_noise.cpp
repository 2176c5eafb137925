#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <utility>

#include <fmt/format.h>

#include <dcl/eval/factor_noise.hpp>

namespace dcl::eval {
namespace {

core::Matrix6d covarianceOf(const backend::Factor& f) {
  return f.information.ldlt().solve(core::Matrix6d::Identity());
}

/// The residual of a measurement T_from_to (as the solvers define it: log(T_from_to^-1 T_from^-1
/// T_to) in [rho; phi]) at the ground truth.
core::Vector6d trueResidual(const Eigen::Isometry3d& T_from_to,
                            const Eigen::Isometry3d& T_world_from,
                            const Eigen::Isometry3d& T_world_to) {
  return core::logSE3(T_from_to.inverse() * T_world_from.inverse() * T_world_to);
}

/// Robot r's odometry compounded over `span` keyframes, windows `span / 2` apart, into `row`.
void addOdometry(const RobotGraph& r, std::size_t span, FactorNoise& row) {
  std::map<std::size_t, const backend::Factor*> chain;  ///< by the keyframe it starts at
  for (const backend::Factor& f : r.graph.factors()) {
    if (f.kind == backend::FactorKind::odometry && f.from.robot == r.id && f.to.robot == r.id &&
        f.to.keyframe.value() == f.from.keyframe.value() + 1)
      chain[f.from.keyframe.value()] = &f;
  }
  const std::size_t step = std::max<std::size_t>(1, span / 2);
  for (std::size_t first = 0; first + span < r.T_world_gt.size(); first += step) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    core::Matrix6d covariance = core::Matrix6d::Zero();
    bool whole = true;
    for (std::size_t k = first; k < first + span; ++k) {
      const auto it = chain.find(k);
      if (it == chain.end()) {
        whole = false;
        break;
      }
      const core::Matrix6d Ad = core::adjoint(it->second->T_from_to.inverse());
      covariance = Ad * covariance * Ad.transpose() + covarianceOf(*it->second);
      T = T * it->second->T_from_to;
    }
    if (!whole) continue;
    row.add(trueResidual(T, r.T_world_gt[first], r.T_world_gt[first + span]), covariance);
  }
}

}  // namespace

void FactorNoise::add(const core::Vector6d& r, const core::Matrix6d& covariance) {
  ++count;
  error_axes += r.cwiseAbs2();
  sigma_axes += covariance.diagonal();
  nees += r.dot(covariance.ldlt().solve(r));
}

double FactorNoise::rms(double sum) const {
  return count == 0 ? 0.0 : std::sqrt(sum / static_cast<double>(count));
}

core::Vector6d FactorNoise::rms(const core::Vector6d& sums) const {
  return count == 0 ? core::Vector6d::Zero()
                    : core::Vector6d((sums / static_cast<double>(count)).cwiseSqrt());
}

double FactorNoise::errorRms(int block) const {
  return rms(error_axes.segment<3>(3 * block).sum());
}

double FactorNoise::sigmaRms(int block) const {
  return rms(sigma_axes.segment<3>(3 * block).sum());
}

double FactorNoise::neesPerDof() const {
  return count == 0 ? 0.0 : nees / (6.0 * static_cast<double>(count));
}

std::vector<FactorNoise> factorNoise(const std::vector<RobotGraph>& robots,
                                     const std::vector<std::size_t>& spans) {
  std::vector<FactorNoise> rows;
  for (const std::size_t span : spans) {
    FactorNoise row{fmt::format("odometry, {} keyframe{}", span, span == 1 ? "" : "s")};
    for (const RobotGraph& r : robots) addOdometry(r, span, row);
    rows.push_back(row);
  }
  std::map<core::RobotId, const RobotGraph*> by_id;
  for (const RobotGraph& r : robots) by_id[r.id] = &r;
  FactorNoise intra{"own loops"};
  FactorNoise inter{"inter-robot loops"};
  std::set<std::pair<core::PoseKey, core::PoseKey>> seen;
  for (const RobotGraph& r : robots) {
    for (const backend::Factor& f : r.graph.factors()) {
      if (f.kind == backend::FactorKind::odometry) continue;
      if (f.from.robot == f.to.robot && f.from.robot != r.id) continue;
      if (!by_id.contains(f.from.robot) || !by_id.contains(f.to.robot)) continue;
      if (!seen.insert(std::minmax(f.from, f.to)).second) continue;
      const RobotGraph& a = *by_id.at(f.from.robot);
      const RobotGraph& b = *by_id.at(f.to.robot);
      const std::size_t i = f.from.keyframe.value(), j = f.to.keyframe.value();
      if (i >= a.T_world_gt.size() || j >= b.T_world_gt.size()) continue;
      (f.from.robot == f.to.robot ? intra : inter)
          .add(trueResidual(f.T_from_to, a.T_world_gt[i], b.T_world_gt[j]), covarianceOf(f));
    }
  }
  rows.push_back(intra);
  rows.push_back(inter);
  return rows;
}

}  // namespace dcl::eval
