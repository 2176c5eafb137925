#pragma once

/// Every message robots exchange (DESIGN.md §4, paper §III), as plain C++
/// values. The wire format is protobuf (proto/dcl.proto) with fixed-layout
/// packed fields where precision allows; it stays inside dcl::comm, so no
/// other module includes protobuf. Large payloads travel as the bytes of the
/// codecs that own them (place::encodeIris, registration::encodeVerificationCloud),
/// which validate themselves when the receiver decodes them.
///
/// encode() writes one message; decode() never trusts its input: sizes,
/// counts, ranges, enum values, versions and payload bounds are checked, and
/// anything wrong comes back as a DropReason with a one-line detail, never as
/// an exception or a crash.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::comm {

/// The schema version every message carries; a decoder drops any other.
inline constexpr std::uint32_t kSchemaVersion = 1;
/// The largest encoded message a decoder looks at (a map summary's cloud is the largest payload).
inline constexpr std::size_t kMaxMessageBytes = 2 * 1024 * 1024;
/// Payload bounds checked before anything is decoded.
inline constexpr std::size_t kMaxDescriptorBytes = 64 * 1024;
inline constexpr std::size_t kMaxCloudBytes = 1024 * 1024;
/// Estimates or poses in one message at most.
inline constexpr std::size_t kMaxEstimates = 100'000;
/// Neighbours acknowledged in one heartbeat at most.
inline constexpr std::size_t kMaxAcks = 255;

/// What a message is; also the traffic meter's categories.
enum class MessageKind : std::uint8_t {
  heartbeat,           ///< neighbour state and acknowledgements
  descriptor,          ///< stage 1: a keyframe's place descriptor
  loop_candidate,      ///< stage 2: a candidate match with the compact keyframe cloud
  loop_measurement,    ///< stage 3: the verified relative pose and covariance, or the refusal
  dgs_state,           ///< DGS: a robot's optimisation state
  rotation_estimates,  ///< DGS stage 1: separator rotation estimates
  pose_estimates,      ///< DGS stage 2 and the refinement: separator pose estimates
  summary_request,     ///< asks a robot for its trajectory or map summary
  trajectory_summary,  ///< a robot's keyframe poses
  map_summary,         ///< a robot's voxel-filtered map
};
inline constexpr std::size_t kMessageKinds = 10;

/// "heartbeat", "descriptor", ... (metrics and logs).
std::string_view name(MessageKind kind);

/// Reliable kinds are kept by the sender until acknowledged and sent again to
/// a neighbour that missed them (Messenger); the others are current state,
/// worthless once stale, and sent once.
[[nodiscard]] bool isReliable(MessageKind kind);

/// Who sent a message to whom, in which stream and order.
struct Header {
  std::uint32_t version = kSchemaVersion;
  core::RobotId sender;
  std::optional<core::RobotId> receiver;  ///< nullopt: every robot in range
  /// The sender's process life: a restarted robot has a larger one, so its
  /// neighbours reset what they know of it instead of taking its new
  /// messages for replays.
  std::uint32_t incarnation = 0;
  /// Per sender: reliable broadcasts, reliable messages to each receiver and
  /// best-effort messages are three counters, each from 1.
  std::uint64_t sequence = 0;
};

/// A neighbour's acknowledgement of what it received from one robot.
struct Ack {
  core::RobotId peer;             ///< the robot acknowledged
  std::uint32_t incarnation = 0;  ///< of the peer, as the acknowledging robot knows it
  std::uint64_t broadcast = 0;    ///< every reliable broadcast up to this one received
  std::uint64_t unicast = 0;  ///< every reliable message to the acknowledging robot up to this one
  /// Received beyond the first gap: bit i set when broadcast + 2 + i arrived
  /// (unicast + 2 + i), so that a loss does not make the sender repeat what followed it.
  std::uint64_t broadcast_above = 0;
  std::uint64_t unicast_above = 0;
};

struct Heartbeat {
  double stamp = 0.0;           ///< s, the sender's clock
  std::uint32_t keyframes = 0;  ///< keyframes the sender holds
  std::vector<Ack> acks;
};

/// The sender's odometry factor from its previous keyframe to this one: with
/// every descriptor, a neighbour holds the sender's odometry chain, which PCM
/// needs to check two loops against each other (paper Eq. 8).
struct OdometryStep {
  core::KeyframeId previous;
  Eigen::Isometry3d T_previous_keyframe = Eigen::Isometry3d::Identity();
  core::Matrix6d covariance = core::Matrix6d::Identity();  ///< [rho; phi]
};

/// An earlier keyframe of the sender's, distinct_separation or more from the
/// new one by its odometry, whose place the new one resembles.
struct Resemblance {
  core::KeyframeId keyframe;
  float distance = 0.0F;  ///< the descriptor distance, [0, 1]; on the wire in 16 bits
};
inline constexpr std::size_t kMaxResemblances = 16;

/// Stage 1.
struct DescriptorMessage {
  core::KeyframeId keyframe;
  double stamp = 0.0;                    ///< s, the keyframe's time
  std::vector<std::uint8_t> descriptor;  ///< place::encodeIris (or the Scan Context codec)
  std::optional<OdometryStep> odometry;  ///< none for a robot's first keyframe
  /// The descriptor distance from this keyframe to the closest place like it
  /// elsewhere on the sender's own route (place::PlaceIndex::lookAlikeDistance),
  /// in [0, 1]; none when the sender knows none. On the wire in 16 bits.
  std::optional<float> look_alike;
  /// The sender's earlier keyframes this one is compared with for its
  /// look-alike distance (far from it on its route), closest first, at most
  /// kMaxResemblances: where its route may repeat a place. A robot that asked
  /// for a loop at one of them judges it again against this keyframe
  /// (RobotNode): a match that does not clearly beat the repeat was an alias.
  std::vector<Resemblance> resembles;
};

/// Stage 2: the sender's keyframe `query` seems to be the receiver's `match`.
struct LoopCandidate {
  core::KeyframeId query;           ///< the sender's keyframe
  core::KeyframeId match;           ///< the receiver's keyframe
  float yaw = 0.0F;                 ///< rad, the descriptor's yaw of query in match, [-pi, pi]
  float distance = 0.0F;            ///< the descriptor distance, [0, 1]
  std::vector<std::uint8_t> cloud;  ///< registration::encodeVerificationCloud of query's keyframe
};

/// A verification's outcome: registration::RejectReason, in its order, and two
/// refusals before any registration.
enum class LoopStatus : std::uint8_t {
  verified,
  too_few_points,
  not_converged,
  low_inlier_share,
  high_fitness,
  degenerate,
  no_submap,  ///< the receiver holds no keyframes around `match`
  bad_cloud,  ///< the candidate's cloud did not decode
  /// Not an answer but a notice about a loop both robots hold: the solution
  /// of optimisation round `round` does not explain it, as the sender sees
  /// it (backend/loop_check.hpp). A loop both robots give notice of for one
  /// round is withdrawn by both.
  unexplained,
  symmetric,  ///< the query aligns as well turned half a turn (registration::RejectReason)
  /// Not an answer but a notice about a loop both robots hold: the robot that
  /// asked for it withdrew it, one of its places having turned out to repeat
  /// on its robot's route as closely as the match (RobotNode). The receiver
  /// withdraws it too.
  repeated,
};
inline constexpr std::uint8_t kLoopStatuses = 11;

/// Stage 3: the answer to a LoopCandidate, sent back to the robot that asked.
struct LoopMeasurement {
  core::KeyframeId query;  ///< the receiver's keyframe (the candidate's query)
  core::KeyframeId match;  ///< the sender's keyframe
  LoopStatus status = LoopStatus::verified;
  Eigen::Isometry3d T_match_query = Eigen::Isometry3d::Identity();  ///< when verified
  core::Matrix6d covariance = core::Matrix6d::Identity();           ///< [rho; phi], when verified
  std::uint32_t round = 0;  ///< when unexplained: the optimisation round whose solution it was
};

/// Which optimisation a DGS message belongs to, and where in it the sender is.
enum class OptimisationStage : std::uint8_t { idle, rotation, pose, refine, done };
inline constexpr std::uint8_t kOptimisationStages = 5;

/// What the sender knows of one member of its group (backend::DgsProgress).
struct MemberProgress {
  core::RobotId robot;
  std::int32_t iteration = 0;  ///< its latest step heard of
  std::int32_t converged_since =
      -1;  ///< first step of its current run of converged steps; -1: none
  bool finished = false;
};

/// A robot's optimisation state (Algorithm 1, backend::DgsMessage without the
/// estimates): round, stage and step, whether it has initialised in this
/// stage, whether its last change was under the threshold, and its view of
/// the group's progress, which ends the stage for everyone alike. Sent alone
/// when there are no estimates to send (or to abandon a round), and as part
/// of every RotationEstimates and PoseEstimates message.
struct DgsState {
  std::uint32_t round = 0;
  OptimisationStage stage = OptimisationStage::idle;
  std::uint32_t iteration = 0;
  bool initialised = false;
  bool converged = false;
  bool abort = false;   ///< the sender abandons the round (a member went silent)
  float change = 0.0F;  ///< the last step's estimate change, >= 0
  std::vector<MemberProgress> progress;
  /// In a round's DGS messages: the robot whose first keyframe anchors the
  /// round's estimates (the initiator's frame); none: unknown.
  std::optional<core::RobotId> frame;
  /// In a round's DGS messages: the round goes on from the members' current
  /// estimates (those in `frame`) instead of from DGS's.
  bool warm = false;
};

/// Separator rotation estimates of DGS stage 1: the chordal relaxation's
/// 3x3 matrices, not projected (entries within +/-2), of the sender's poses.
struct RotationEstimates {
  DgsState state;
  std::vector<std::pair<core::KeyframeId, Eigen::Matrix3d>> rotations;
};

/// Separator pose estimates of the sender's poses (DGS stage 2, the refinement).
struct PoseEstimates {
  DgsState state;
  std::vector<std::pair<core::KeyframeId, Eigen::Isometry3d>> poses;
  /// Rotations to 1e-9 rad (25 B a pose) instead of 3e-5 rad (19 B): the
  /// refinement's separators, where loops are tight enough for the difference
  /// to matter.
  bool precise = false;
  /// `poses` are increments T_last^-1 T from the poses the receiver last had
  /// from the sender (not `precise`): the refinement's later steps, whose
  /// separators move by micrometres. Rotation vector to 1e-8 rad and
  /// translation to 1e-6 m in zigzag varints: 7-14 B a pose where it moves
  /// little. An increment's rotation is at most pi, its translation at most
  /// kMaxIncrement m.
  bool increments = false;
};
inline constexpr double kMaxIncrement = 2000.0;

enum class SummaryKind : std::uint8_t { trajectory, map };

struct SummaryRequest {
  SummaryKind what = SummaryKind::trajectory;
};

/// A robot's keyframe poses T_world_keyframe in its own world frame.
struct TrajectorySummary {
  std::vector<std::pair<core::KeyframeId, Eigen::Isometry3d>> poses;
};

/// A robot's map: its keyframe clouds, voxel-filtered, in its own world frame.
struct MapSummary {
  std::uint32_t keyframes = 0;      ///< keyframes merged
  std::vector<std::uint8_t> cloud;  ///< registration::encodeVerificationCloud
};

using Body =
    std::variant<Heartbeat, DescriptorMessage, LoopCandidate, LoopMeasurement, DgsState,
                 RotationEstimates, PoseEstimates, SummaryRequest, TrajectorySummary, MapSummary>;

/// The kind of a body (its index in Body).
[[nodiscard]] MessageKind kindOf(const Body& body);

struct Message {
  Header header;
  Body body;

  [[nodiscard]] MessageKind kind() const { return kindOf(body); }
};

/// Why a received message was dropped (counted per reason and peer).
enum class DropReason : std::uint8_t {
  oversized,          ///< over kMaxMessageBytes
  malformed,          ///< not a protobuf message of the schema (truncated, corrupt)
  wrong_version,      ///< another schema version
  invalid_field,      ///< a field out of range or a payload over its bound
  sender_mismatch,    ///< the header's sender is not the robot it came from
  stale_incarnation,  ///< from an earlier life of the sender
  duplicate,          ///< already delivered (a retransmission or a replay)
  out_of_window,      ///< a sequence too far ahead of what was received
  not_for_me,         ///< addressed to another robot (normal on a shared medium)
};
inline constexpr std::size_t kDropReasons = 9;

std::string_view name(DropReason reason);

/// A decoded message, or why there is none.
struct Decoded {
  std::optional<Message> message;
  DropReason reason = DropReason::malformed;  ///< when there is no message
  std::string detail;                         ///< one line naming the field and what was wrong
};

/// The wire bytes of `message`. Throws core::Error when a value cannot be
/// encoded (an id out of range, a rotation entry beyond +/-2, a payload over
/// its bound): a sender's bug, not a peer's.
std::vector<std::uint8_t> encode(const Message& message);

/// Decodes and validates one message; never throws.
Decoded decode(std::span<const std::uint8_t> bytes);

/// `body` as its receivers will decode it: poses, rotations and covariances
/// rounded to their records. A sender that keeps what it sends (a loop it
/// verified, its own odometry steps) keeps this, so that both sides of an
/// exchange hold the very same numbers and decide alike. Throws core::Error
/// when the body cannot be encoded.
Body asDelivered(const Body& body);

}  // namespace dcl::comm
