#pragma once

/// The frames the robots' estimates are in, and how to put them in one.
///
/// A robot's estimates are in the frame of the robots it last optimised
/// with, named by the robot whose odometry frame it is (the lowest robot of
/// the first round that set it up): its own until a round places it. Groups
/// of robots out of each other's range set up frames of their own, and a
/// robot a later round moves into another frame cannot tell the robots it
/// left, out of range, that their frame moved. Robots in different frames
/// still share the inter-robot loops of their earlier rounds: the loops
/// between two frames give the rigid motion from one to the other (a
/// least-squares fit; no estimate changes shape), and the links between
/// frames put every robot in the lowest frame they join its own to. This is
/// how `run` and `swarm` merge the robots' outputs into one map for every
/// set of robots that ever met.

#include <Eigen/Geometry>
#include <map>
#include <optional>
#include <span>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::robot {

/// Frame `from` lies in frame `to` as `T_to_from` says (it takes poses in
/// `from` to `to`), by `loops` inter-robot loops.
struct FrameLink {
  core::RobotId from;
  core::RobotId to;
  Eigen::Isometry3d T_to_from = Eigen::Isometry3d::Identity();
  std::size_t loops = 0;
};

/// Where a frame lies in the frame the links join it to: `root` is the
/// lowest frame connected to it by links.
struct FramePlacement {
  core::RobotId root;
  Eigen::Isometry3d T_root_frame = Eigen::Isometry3d::Identity();
};

/// Every frame named by a link, placed in the lowest frame it is linked to
/// (breadth first from that frame, at each frame its links taken in the order
/// given: a frame two paths place differently takes the first). A frame in
/// no link is its own root; it is not in the answer.
[[nodiscard]] std::map<core::RobotId, FramePlacement> joinFrames(std::span<const FrameLink> links);

/// One robot's final estimates: the frame they are in (none: unknown, joined
/// to no other) and its keyframes' poses in keyframe order.
struct RobotEstimates {
  core::RobotId robot;
  std::optional<core::RobotId> frame;
  std::vector<Eigen::Isometry3d> keyframes;
};

/// The links the inter-robot `loops` give between the robots' frames, one
/// per pair of frames that loops join (the rigid motion that best carries
/// the loops' ends in one frame onto where the loops put them from the
/// other), the pairs with most loops first. Loops within one frame, or
/// naming a robot or keyframe not in `robots`, are passed over.
[[nodiscard]] std::vector<FrameLink> frameLinks(std::span<const RobotEstimates> robots,
                                                std::span<const backend::Factor> loops);

/// Per robot of `robots`, in order: the frame the loops between frames join
/// its own to (the lowest they reach) and the motion into it; none for a
/// robot of unknown frame or already in that frame. frameLinks, then
/// joinFrames.
[[nodiscard]] std::vector<std::optional<FramePlacement>> joinRobots(
    std::span<const RobotEstimates> robots, std::span<const backend::Factor> loops);

/// The rigid motion T minimising sum |T p_before - p_after|^2 over the
/// keyframes' positions and, a metre along each axis, their orientations
/// (so one keyframe, or a straight path, still fixes it). Both spans have
/// the same length, at least one pose; throws core::Error otherwise.
[[nodiscard]] Eigen::Isometry3d fitRigidMotion(std::span<const Eigen::Isometry3d> before,
                                               std::span<const Eigen::Isometry3d> after);

}  // namespace dcl::robot
