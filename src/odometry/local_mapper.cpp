#include <utility>

#include <dcl/core/config.hpp>
#include <dcl/odometry/local_mapper.hpp>

namespace dcl::odometry {
namespace {

const LocalMapperConfig& validated(const LocalMapperConfig& config) {
  validate(config);
  return config;
}

}  // namespace

void validate(const LocalMapperConfig& config) {
  core::checkConfig(config, "mapper config");
}

LocalMapper::LocalMapper(core::RobotId robot, const LocalMapperConfig& config)
    : robot_(robot),
      config_(validated(config)),
      selector_(robot, config.keyframes),
      loop_closure_(config.loops) {}

MapperUpdate LocalMapper::process(const OdometryResult& frame, const core::PointCloud& scan) {
  MapperUpdate update;
  // The first keyframe's cloud, deskewed again once the odometry knew its
  // velocity (before any loop to it is verified: the next frame comes now).
  if (frame.first_frame_redone && !keyframes_.empty() &&
      keyframes_.front().stamp == frame.first_frame_redone->stamp) {
    keyframes_.front().cloud = selector_.keyframeCloud(frame.first_frame_redone->registered);
  }
  std::optional<core::Keyframe> keyframe = selector_.add(frame, scan);
  if (!keyframe) return update;
  update.keyframe = keyframe->id;
  addKeyframe(std::move(*keyframe));
  if (!config_.loop_closure) return update;
  update.loop = loop_closure_.detect(keyframes_, estimates_);
  if (update.loop) update.optimisation = addLoop(*update.loop);
  return update;
}

void LocalMapper::addKeyframe(core::Keyframe keyframe) {
  const core::PoseKey node = key(keyframe.id);
  if (estimates_.empty()) {
    // Keyframe 0 anchors the local graph at its odometry pose.
    graph_.addNode(node, keyframe.T_odom_keyframe);
    graph_.fix(node);
  } else {
    // New keyframes follow the smoothed trajectory: the odometry step from the previous one.
    graph_.addNode(node, estimates_.back() * keyframe.T_previous_keyframe);
    graph_.addFactor({key(keyframes_.back().id), node, keyframe.T_previous_keyframe,
                      backend::informationFromCovariance(keyframe.covariance),
                      backend::FactorKind::odometry});
  }
  estimates_.push_back(graph_.estimate(node));
  loop_closure_.add(keyframe);
  keyframes_.push_back(std::move(keyframe));
}

backend::SolverSummary LocalMapper::addLoop(const IntraLoop& loop) {
  loops_.push_back(loop);
  graph_.addFactor({key(loop.from), key(loop.to), loop.T_from_to, loop.information,
                    backend::FactorKind::intra_loop});
  const backend::SolverSummary summary = backend::solveCentralized(graph_, config_.solver);
  for (std::size_t i = 0; i < estimates_.size(); ++i) {
    estimates_[i] = graph_.estimate(key(core::KeyframeId(i)));
  }
  return summary;
}

core::Trajectory LocalMapper::trajectory() const {
  core::Trajectory trajectory;
  trajectory.reserve(keyframes_.size());
  for (std::size_t i = 0; i < keyframes_.size(); ++i) {
    trajectory.push_back(keyframes_[i].stamp, estimates_[i]);
  }
  return trajectory;
}

Eigen::Isometry3d LocalMapper::correction() const {
  if (keyframes_.empty()) return Eigen::Isometry3d::Identity();
  return estimates_.back() * keyframes_.back().T_odom_keyframe.inverse();
}

}  // namespace dcl::odometry
