#pragma once

/// backend::DgsMessage on the wire and back: its state (round, stage, step,
/// flags, the group's progress) as comm::DgsState, with the separator
/// estimates as comm::RotationEstimates (stage 1) or comm::PoseEstimates
/// (stage 2). A robot sends its own separators only, so the keyframe ids are
/// the sender's.

#include <Eigen/Geometry>
#include <map>
#include <optional>

#include <dcl/backend/dgs.hpp>
#include <dcl/comm/messages.hpp>

namespace dcl::robot {

/// The body for `message` (its sender and receiver go in the header).
comm::Body toWire(const backend::DgsMessage& message);

/// The DGS message a received DGS body carries; none for other kinds.
std::optional<backend::DgsMessage> fromWire(const comm::Message& message);

/// How the round a DGS body belongs to starts (comm::DgsState's frame and warm).
struct RoundOrigin {
  std::optional<core::RobotId> frame;  ///< none: not said, or not a DGS body
  bool warm = false;
};
RoundOrigin roundOrigin(const comm::Message& message);

/// One message of the distributed refinement that follows DGS in a round
/// (backend::RefineAgent, backend::RefineSchedule): in refinement step `step`,
/// either the sender's separator poses for the receiver (after its block step;
/// step 0: where its refinement starts from) or the sender's share of the graph's cost
/// (RefineAgent::ownedCost) at the end of that step. On the wire: a
/// comm::PoseEstimates, or a comm::DgsState carrying the share in `change`,
/// both with stage `refine`. Poses go to one member; a share is broadcast
/// (every member needs it, and one transmission reaches them all), or sent
/// again to one member that lost it.
struct RefineMessage {
  core::RobotId from;
  std::optional<core::RobotId> to;  ///< none: every robot in range (a share)
  std::uint32_t round = 0;
  std::uint32_t step = 0;
  std::map<core::PoseKey, Eigen::Isometry3d> poses;  ///< the sender's own poses
  std::optional<float> cost_share;                   ///< set: a share, not poses
  /// `poses` are increments T_last^-1 T from the poses of the sender's
  /// previous step (comm::PoseEstimates::increments).
  bool increments = false;
  /// A share sent again by a robot whose refinement of the round has ended,
  /// to a member still waiting for it: an answer, never itself answered.
  bool finished = false;
};

comm::Body toWire(const RefineMessage& message);

/// The refinement message a received body carries; none for other kinds.
std::optional<RefineMessage> refineFromWire(const comm::Message& message);

}  // namespace dcl::robot
