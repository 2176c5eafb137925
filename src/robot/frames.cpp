#include <Eigen/Geometry>
#include <algorithm>
#include <deque>
#include <optional>
#include <utility>

#include <dcl/core/error.hpp>
#include <dcl/robot/frames.hpp>

namespace dcl::robot {

std::map<core::RobotId, FramePlacement> joinFrames(std::span<const FrameLink> links) {
  // Both directions of every link, per frame, in the order given.
  std::map<core::RobotId, std::vector<std::pair<core::RobotId, Eigen::Isometry3d>>> next;
  for (const FrameLink& l : links) {
    if (l.from == l.to) continue;
    next[l.from].emplace_back(l.to, l.T_to_from);
    next[l.to].emplace_back(l.from, l.T_to_from.inverse());
  }
  std::map<core::RobotId, FramePlacement> placed;
  for (const auto& [frame, unused] : next) {  // ascending: each search starts at its lowest frame
    if (placed.contains(frame)) continue;
    placed[frame] = {frame, Eigen::Isometry3d::Identity()};
    std::deque<core::RobotId> todo{frame};
    while (!todo.empty()) {
      const core::RobotId f = todo.front();
      todo.pop_front();
      const FramePlacement here = placed.at(f);
      for (const auto& [other, T_other_f] : next.at(f)) {
        if (placed.contains(other)) continue;
        placed[other] = {here.root, here.T_root_frame * T_other_f.inverse()};
        todo.push_back(other);
      }
    }
  }
  return placed;
}

std::vector<FrameLink> frameLinks(std::span<const RobotEstimates> robots,
                                  std::span<const backend::Factor> loops) {
  std::map<core::RobotId, const RobotEstimates*> by_id;
  for (const RobotEstimates& r : robots) by_id[r.robot] = &r;
  // A loop's end in robot `key.robot`'s frame, if known.
  const auto end =
      [&](const core::PoseKey& key) -> std::optional<std::pair<core::RobotId, Eigen::Isometry3d>> {
    const auto it = by_id.find(key.robot);
    if (it == by_id.end() || !it->second->frame ||
        key.keyframe.value() >= it->second->keyframes.size())
      return std::nullopt;
    return std::make_pair(*it->second->frame, it->second->keyframes[key.keyframe.value()]);
  };
  // Per pair of frames (lower, higher): poses in the higher frame, and where
  // the loops put them in the lower one.
  std::map<std::pair<core::RobotId, core::RobotId>,
           std::pair<std::vector<Eigen::Isometry3d>, std::vector<Eigen::Isometry3d>>>
      pairs;
  for (const backend::Factor& f : loops) {
    const auto from = end(f.from);
    const auto to = end(f.to);
    if (!from || !to || from->first == to->first) continue;
    // T_low_high X_to ~ X_from T_from_to, or T_low_high X_from ~ X_to T_from_to^-1.
    auto& [before, after] = pairs[std::minmax(from->first, to->first)];
    if (from->first < to->first) {
      before.push_back(to->second);
      after.push_back(from->second * f.T_from_to);
    } else {
      before.push_back(from->second);
      after.push_back(to->second * f.T_from_to.inverse());
    }
  }
  std::vector<FrameLink> links;
  for (const auto& [frames, poses] : pairs)
    links.push_back({frames.second, frames.first, fitRigidMotion(poses.first, poses.second),
                     poses.first.size()});
  std::stable_sort(links.begin(), links.end(),
                   [](const FrameLink& a, const FrameLink& b) { return a.loops > b.loops; });
  return links;
}

std::vector<std::optional<FramePlacement>> joinRobots(std::span<const RobotEstimates> robots,
                                                      std::span<const backend::Factor> loops) {
  const std::map<core::RobotId, FramePlacement> placed = joinFrames(frameLinks(robots, loops));
  std::vector<std::optional<FramePlacement>> out;
  for (const RobotEstimates& r : robots) {
    const auto it = r.frame ? placed.find(*r.frame) : placed.end();
    if (it == placed.end() || it->second.root == *r.frame)
      out.emplace_back();
    else
      out.emplace_back(it->second);
  }
  return out;
}

Eigen::Isometry3d fitRigidMotion(std::span<const Eigen::Isometry3d> before,
                                 std::span<const Eigen::Isometry3d> after) {
  if (before.size() != after.size() || before.empty())
    throw core::Error("fitRigidMotion: needs as many poses after as before, at least one");
  const auto n = static_cast<Eigen::Index>(before.size());
  Eigen::Matrix3Xd source(3, 4 * n);
  Eigen::Matrix3Xd target(3, 4 * n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Isometry3d& b = before[static_cast<std::size_t>(i)];
    const Eigen::Isometry3d& a = after[static_cast<std::size_t>(i)];
    source.col(4 * i) = b.translation();
    target.col(4 * i) = a.translation();
    for (int axis = 0; axis < 3; ++axis) {
      source.col(4 * i + 1 + axis) = b.translation() + b.linear().col(axis);
      target.col(4 * i + 1 + axis) = a.translation() + a.linear().col(axis);
    }
  }
  Eigen::Isometry3d T;
  T.matrix() = Eigen::umeyama(source, target, false);
  return T;
}

}  // namespace dcl::robot
