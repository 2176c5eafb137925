#pragma once

/// backend::DgsMessage on the wire and back: its state (round, stage, step,
/// flags, the group's progress) as comm::DgsState, with the separator
/// estimates as comm::RotationEstimates (stage 1) or comm::PoseEstimates
/// (stage 2). A robot sends its own separators only, so the keyframe ids are
/// the sender's.

#include <optional>

#include <dcl/backend/dgs.hpp>
#include <dcl/comm/messages.hpp>

namespace dcl::robot {

/// The body for `message` (its sender and receiver go in the header).
comm::Body toWire(const backend::DgsMessage& message);

/// The DGS message a received DGS body carries; none for other kinds.
std::optional<backend::DgsMessage> fromWire(const comm::Message& message);

}  // namespace dcl::robot
