#include <dcl/comm/messages.hpp>
#include <dcl/comm/transport.hpp>

namespace dcl::comm {

std::string_view name(MessageKind kind) {
  switch (kind) {
    case MessageKind::heartbeat:
      return "heartbeat";
    case MessageKind::descriptor:
      return "descriptor";
    case MessageKind::loop_candidate:
      return "loop_candidate";
    case MessageKind::loop_measurement:
      return "loop_measurement";
    case MessageKind::dgs_state:
      return "dgs_state";
    case MessageKind::rotation_estimates:
      return "rotation_estimates";
    case MessageKind::pose_estimates:
      return "pose_estimates";
    case MessageKind::summary_request:
      return "summary_request";
    case MessageKind::trajectory_summary:
      return "trajectory_summary";
    case MessageKind::map_summary:
      return "map_summary";
  }
  return "unknown";
}

bool isReliable(MessageKind kind) {
  switch (kind) {
    case MessageKind::descriptor:
    case MessageKind::loop_candidate:
    case MessageKind::loop_measurement:
    case MessageKind::summary_request:
    case MessageKind::trajectory_summary:
    case MessageKind::map_summary:
      return true;
    default:
      return false;
  }
}

Qos qosOf(MessageKind kind) {
  return kind == MessageKind::heartbeat || kind == MessageKind::descriptor ? Qos::best_effort
                                                                           : Qos::reliable;
}

MessageKind kindOf(const Body& body) {
  return static_cast<MessageKind>(body.index());
}

std::string_view name(DropReason reason) {
  switch (reason) {
    case DropReason::oversized:
      return "oversized";
    case DropReason::malformed:
      return "malformed";
    case DropReason::wrong_version:
      return "wrong_version";
    case DropReason::invalid_field:
      return "invalid_field";
    case DropReason::sender_mismatch:
      return "sender_mismatch";
    case DropReason::stale_incarnation:
      return "stale_incarnation";
    case DropReason::duplicate:
      return "duplicate";
    case DropReason::out_of_window:
      return "out_of_window";
    case DropReason::not_for_me:
      return "not_for_me";
  }
  return "unknown";
}

}  // namespace dcl::comm
