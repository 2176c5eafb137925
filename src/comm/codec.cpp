#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <string>
#include <utility>

#include <dcl.pb.h>

#include <dcl/comm/messages.hpp>
#include <dcl/core/error.hpp>

namespace dcl::comm {
namespace {

static_assert(std::endian::native == std::endian::little, "the packed records are little-endian");

// Record sizes of proto/dcl.proto's packed layouts.
constexpr std::size_t kPoseRecord = 19;
constexpr std::size_t kPrecisePoseRecord = 25;
constexpr std::size_t kRotationRecord = 18;
constexpr std::size_t kCovarianceRecord = 42;

constexpr double kQuaternionScale = 32767.0 * std::numbers::sqrt2;  // components within 1/sqrt(2)
constexpr double kPreciseQuaternionScale = 2147483647.0 * std::numbers::sqrt2;
constexpr double kRotationScale = 16384.0;          // relaxed entries within +/-2
constexpr double kIncrementRotationScale = 1e8;     // 1e-8 rad
constexpr double kIncrementTranslationScale = 1e6;  // 1e-6 m
constexpr double kLookAlikeScale = 65534.0;         // a descriptor distance in [0, 1]
constexpr double kLogSigmaOffset = 32.0;            // sigma within 2^-32 .. 2^32
constexpr double kLogSigmaScale = 1024.0;
constexpr double kCorrelationScale = 32767.0;
constexpr std::uint64_t kMaxKeyframe = core::PoseKey::kIndexMask;
constexpr std::uint32_t kMaxRobot = 254;  // 255 is RobotId's invalid value

/// A decoded value out of range: what decode() turns into a Decoded.
struct Invalid {
  DropReason reason;
  std::string detail;
};

[[noreturn]] void invalid(std::string detail) {
  throw Invalid{DropReason::invalid_field, std::move(detail)};
}

void check(bool ok, const char* what) {
  if (!ok) invalid(what);
}

// ---------------------------------------------------------------- records

template <class T>
void put(std::string& out, T value) {
  char raw[sizeof(T)];
  std::memcpy(raw, &value, sizeof(T));
  out.append(raw, sizeof(T));
}

template <class T>
T take(const char*& in) {
  T value;
  std::memcpy(&value, in, sizeof(T));
  in += sizeof(T);
  return value;
}

std::int16_t quantise(double value, double scale, const char* what) {
  const double q = std::round(value * scale);
  if (!(std::abs(q) <= 32767.0))
    throw core::Error(std::string("encode: ") + what + " out of range");
  return static_cast<std::int16_t>(q);
}

/// The quaternion's smallest three components as Int (int16: the pose
/// record, int32: the precise one), scaled by `scale`.
template <class Int>
void putPose(std::string& out, const Eigen::Isometry3d& T, double scale) {
  const Eigen::Vector3d t = T.translation();
  if (!t.allFinite() || t.cwiseAbs().maxCoeff() > std::numeric_limits<float>::max())
    throw core::Error("encode: a pose translation is not finite");
  Eigen::Quaterniond q(T.rotation());
  if (!q.coeffs().allFinite()) throw core::Error("encode: a pose rotation is not finite");
  q.normalize();
  const double c[4] = {q.w(), q.x(), q.y(), q.z()};
  int largest = 0;
  for (int i = 1; i < 4; ++i) {
    if (std::abs(c[i]) > std::abs(c[largest])) largest = i;
  }
  const double sign = c[largest] < 0.0 ? -1.0 : 1.0;
  put(out, static_cast<std::uint8_t>(largest));
  constexpr double kLimit = std::numeric_limits<Int>::max();
  for (int i = 0; i < 4; ++i) {
    if (i == largest) continue;
    const double v = std::round(sign * c[i] * scale);
    if (!(std::abs(v) <= kLimit)) throw core::Error("encode: quaternion component out of range");
    put(out, static_cast<Int>(v));
  }
  for (int i = 0; i < 3; ++i) put(out, static_cast<float>(t[i]));
}

template <class Int>
Eigen::Isometry3d takePose(const char*& in, double scale) {
  const int largest = take<std::uint8_t>(in);
  check(largest < 4, "pose record: quaternion index beyond 3");
  double c[4];
  double sum = 0.0;
  for (int i = 0; i < 4; ++i) {
    if (i == largest) continue;
    const Int q = take<Int>(in);
    check(q >= -std::numeric_limits<Int>::max(),
          "pose record: a quaternion component below -1/sqrt(2)");
    c[i] = q / scale;
    sum += c[i] * c[i];
  }
  check(sum <= 1.0 + 1e-4, "pose record: not a unit quaternion");
  c[largest] = std::sqrt(std::max(0.0, 1.0 - sum));
  Eigen::Vector3d t;
  for (int i = 0; i < 3; ++i) t[i] = take<float>(in);
  check(t.allFinite(), "pose record: translation not finite");
  const Eigen::Quaterniond q = Eigen::Quaterniond(c[0], c[1], c[2], c[3]).normalized();
  return core::makePose(t, q);
}

void putPose(std::string& out, const Eigen::Isometry3d& T) {
  putPose<std::int16_t>(out, T, kQuaternionScale);
}

Eigen::Isometry3d takePose(const char*& in) {
  return takePose<std::int16_t>(in, kQuaternionScale);
}

void putRotation(std::string& out, const Eigen::Matrix3d& R) {
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 3; ++col) {
      if (!std::isfinite(R(r, col))) throw core::Error("encode: a rotation entry is not finite");
      put(out, quantise(R(r, col), kRotationScale, "relaxed rotation entry (beyond +/-2)"));
    }
  }
}

Eigen::Matrix3d takeRotation(const char*& in) {
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 3; ++col) {
      const std::int16_t q = take<std::int16_t>(in);
      check(q >= -32767, "rotation record: an entry below -2");
      R(r, col) = q / kRotationScale;
    }
  }
  return R;
}

void putCovariance(std::string& out, const core::Matrix6d& covariance) {
  if (!covariance.allFinite()) throw core::Error("encode: a covariance entry is not finite");
  const core::Vector6d sigma = covariance.diagonal().cwiseSqrt();
  for (int i = 0; i < 6; ++i) {
    const double level = (std::log2(sigma[i]) + kLogSigmaOffset) * kLogSigmaScale;
    if (!(level >= 0.0 && level <= 65535.0))
      throw core::Error("encode: a covariance variance is not within 2^-64 .. 2^64");
    put(out, static_cast<std::uint16_t>(std::lround(level)));
  }
  for (int i = 0; i < 6; ++i) {
    for (int j = i + 1; j < 6; ++j) {
      const double rho = std::clamp(covariance(i, j) / (sigma[i] * sigma[j]), -1.0, 1.0);
      put(out, static_cast<std::int16_t>(std::lround(rho * kCorrelationScale)));
    }
  }
}

/// The correlation matrix's eigenvalues are clamped to at least this: a
/// nearly singular covariance can come out of quantisation slightly indefinite.
constexpr double kMinCorrelationEigenvalue = 1e-6;

core::Matrix6d takeCovariance(const char*& in) {
  core::Vector6d sigma;
  for (int i = 0; i < 6; ++i) {
    sigma[i] = std::exp2(take<std::uint16_t>(in) / kLogSigmaScale - kLogSigmaOffset);
  }
  core::Matrix6d correlation = core::Matrix6d::Identity();
  for (int i = 0; i < 6; ++i) {
    for (int j = i + 1; j < 6; ++j) {
      const std::int16_t q = take<std::int16_t>(in);
      check(q >= -32767, "covariance record: a correlation below -1");
      correlation(i, j) = correlation(j, i) = q / kCorrelationScale;
    }
  }
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> eigen(correlation);
  check(eigen.eigenvalues().minCoeff() > -1e-3, "covariance record: not positive semi-definite");
  if (eigen.eigenvalues().minCoeff() < kMinCorrelationEigenvalue) {
    const core::Vector6d clamped = eigen.eigenvalues().cwiseMax(kMinCorrelationEigenvalue);
    correlation = eigen.eigenvectors() * clamped.asDiagonal() * eigen.eigenvectors().transpose();
    const core::Vector6d scale = correlation.diagonal().cwiseSqrt().cwiseInverse();
    correlation = scale.asDiagonal() * correlation * scale.asDiagonal();  // unit diagonal again
  }
  return sigma.asDiagonal() * correlation * sigma.asDiagonal();
}

// ---------------------------------------------------------------- ids and payloads

std::uint64_t keyframeOut(core::KeyframeId id) {
  if (!id.valid() || id.value() > kMaxKeyframe)
    throw core::Error("encode: keyframe id " + std::to_string(id.value()) + " beyond 2^56");
  return id.value();
}

core::KeyframeId keyframeIn(std::uint64_t value, const char* field) {
  if (value > kMaxKeyframe) invalid(std::string(field) + ": keyframe id beyond 2^56");
  return core::KeyframeId(value);
}

std::string payloadOut(const std::vector<std::uint8_t>& bytes, std::size_t bound,
                       const char* what) {
  if (bytes.empty() || bytes.size() > bound)
    throw core::Error(std::string("encode: ") + what + " of " + std::to_string(bytes.size()) +
                      " bytes (expected 1.." + std::to_string(bound) + ")");
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

std::vector<std::uint8_t> payloadIn(const std::string& bytes, std::size_t bound, const char* what) {
  if (bytes.empty() || bytes.size() > bound)
    invalid(std::string(what) + ": " + std::to_string(bytes.size()) + " bytes (expected 1.." +
            std::to_string(bound) + ")");
  return {bytes.begin(), bytes.end()};
}

double finiteIn(double value, const char* what) {
  if (!std::isfinite(value)) invalid(std::string(what) + " not finite");
  return value;
}

template <class Container>
std::string poseRecords(const Container& poses, bool precise = false) {
  if (poses.size() > kMaxEstimates) throw core::Error("encode: more than kMaxEstimates poses");
  std::string out;
  out.reserve(poses.size() * (precise ? kPrecisePoseRecord : kPoseRecord));
  for (const auto& [id, T] : poses) {
    if (precise) {
      putPose<std::int32_t>(out, T, kPreciseQuaternionScale);
    } else {
      putPose(out, T);
    }
  }
  return out;
}

template <class RepeatedIds>
std::vector<std::pair<core::KeyframeId, Eigen::Isometry3d>> posesIn(const RepeatedIds& ids,
                                                                    const std::string& records,
                                                                    const char* what,
                                                                    bool precise = false) {
  if (static_cast<std::size_t>(ids.size()) > kMaxEstimates)
    invalid(std::string(what) + ": more than " + std::to_string(kMaxEstimates) + " poses");
  const std::size_t record = precise ? kPrecisePoseRecord : kPoseRecord;
  if (records.size() != static_cast<std::size_t>(ids.size()) * record)
    invalid(std::string(what) + ": " + std::to_string(records.size()) + " bytes for " +
            std::to_string(ids.size()) + (precise ? " precise" : "") + " pose records");
  std::vector<std::pair<core::KeyframeId, Eigen::Isometry3d>> poses;
  poses.reserve(static_cast<std::size_t>(ids.size()));
  const char* in = records.data();
  for (const std::uint64_t id : ids) {
    poses.emplace_back(
        keyframeIn(id, what),
        precise ? takePose<std::int32_t>(in, kPreciseQuaternionScale) : takePose(in));
  }
  return poses;
}

// ---------------------------------------------------------------- bodies out

void fill(wire::Envelope& e, const Heartbeat& m) {
  wire::Heartbeat& w = *e.mutable_heartbeat();
  w.set_stamp(m.stamp);
  w.set_keyframes(m.keyframes);
  if (m.acks.size() > kMaxAcks) throw core::Error("encode: more than kMaxAcks acknowledgements");
  for (const Ack& a : m.acks) {
    wire::Ack& wa = *w.add_acks();
    wa.set_peer(a.peer.value());
    wa.set_incarnation(a.incarnation);
    wa.set_broadcast(a.broadcast);
    wa.set_unicast(a.unicast);
    wa.set_broadcast_above(a.broadcast_above);
    wa.set_unicast_above(a.unicast_above);
  }
}

void fill(wire::Envelope& e, const DescriptorMessage& m) {
  wire::Descriptor& w = *e.mutable_descriptor();
  w.set_keyframe(keyframeOut(m.keyframe));
  w.set_stamp(m.stamp);
  w.set_descriptor(payloadOut(m.descriptor, kMaxDescriptorBytes, "descriptor"));
  if (m.look_alike) {
    if (!(*m.look_alike >= 0.0F && *m.look_alike <= 1.0F))
      throw core::Error("encode: look-alike distance not within [0, 1]");
    w.set_look_alike(1U + static_cast<std::uint32_t>(std::lround(*m.look_alike * kLookAlikeScale)));
  }
  if (m.resembles.size() > kMaxResemblances) throw core::Error("encode: too many resemblances");
  for (const Resemblance& r : m.resembles) {
    if (!(r.distance >= 0.0F && r.distance <= 1.0F))
      throw core::Error("encode: resemblance distance not within [0, 1]");
    w.add_resembles(keyframeOut(r.keyframe));
    w.add_resembles_distance(static_cast<std::uint32_t>(std::lround(r.distance * kLookAlikeScale)));
  }
  if (!m.odometry) return;
  w.set_previous(keyframeOut(m.odometry->previous));
  putPose(*w.mutable_odometry_pose(), m.odometry->T_previous_keyframe);
  putCovariance(*w.mutable_odometry_covariance(), m.odometry->covariance);
}

void fill(wire::Envelope& e, const LoopCandidate& m) {
  wire::LoopCandidate& w = *e.mutable_loop_candidate();
  w.set_query(keyframeOut(m.query));
  w.set_match(keyframeOut(m.match));
  w.set_yaw(m.yaw);
  w.set_distance(m.distance);
  w.set_cloud(payloadOut(m.cloud, kMaxCloudBytes, "candidate cloud"));
}

void fill(wire::Envelope& e, const LoopMeasurement& m) {
  wire::LoopMeasurement& w = *e.mutable_loop_measurement();
  w.set_query(keyframeOut(m.query));
  w.set_match(keyframeOut(m.match));
  w.set_status(static_cast<std::uint32_t>(m.status));
  if (m.status == LoopStatus::unexplained) w.set_round(m.round);
  if (m.status != LoopStatus::verified) return;
  putPose(*w.mutable_pose(), m.T_match_query);
  putCovariance(*w.mutable_covariance(), m.covariance);
}

void fillState(wire::DgsState& w, const DgsState& m) {
  w.set_round(m.round);
  w.set_stage(static_cast<std::uint32_t>(m.stage));
  w.set_iteration(m.iteration);
  w.set_flags((m.initialised ? 1U : 0U) | (m.converged ? 2U : 0U) | (m.abort ? 4U : 0U) |
              (m.warm ? 8U : 0U));
  w.set_change(m.change);
  if (m.frame) {
    if (!m.frame->valid()) throw core::Error("encode: invalid round frame");
    w.set_frame(m.frame->value() + 1U);
  }
  if (m.progress.size() > kMaxAcks) throw core::Error("encode: more than kMaxAcks group members");
  for (const MemberProgress& p : m.progress) {
    if (!p.robot.valid() || p.iteration < 0 || p.converged_since < -1)
      throw core::Error("encode: invalid group progress");
    wire::MemberProgress& wp = *w.add_progress();
    wp.set_robot(p.robot.value());
    wp.set_iteration(static_cast<std::uint32_t>(p.iteration));
    wp.set_converged_since(p.converged_since);
    wp.set_finished(p.finished);
  }
}

void fill(wire::Envelope& e, const DgsState& m) {
  fillState(*e.mutable_dgs_state(), m);
}

void fill(wire::Envelope& e, const RotationEstimates& m) {
  wire::RotationEstimates& w = *e.mutable_rotation_estimates();
  fillState(*w.mutable_state(), m.state);
  if (m.rotations.size() > kMaxEstimates)
    throw core::Error("encode: more than kMaxEstimates rotations");
  std::string& records = *w.mutable_rotations();
  records.reserve(m.rotations.size() * kRotationRecord);
  for (const auto& [id, R] : m.rotations) {
    w.add_keyframes(keyframeOut(id));
    putRotation(records, R);
  }
}

/// Six varints per increment: rotation vector, translation (PoseEstimates::increments).
void putIncrement(wire::PoseEstimates& w, const Eigen::Isometry3d& D) {
  const Eigen::AngleAxisd aa(D.rotation());
  const Eigen::Vector3d phi = aa.angle() * aa.axis();
  const Eigen::Vector3d t = D.translation();
  if (!phi.allFinite() || !t.allFinite() || t.cwiseAbs().maxCoeff() > kMaxIncrement)
    throw core::Error("encode: a pose increment is not finite or beyond kMaxIncrement");
  for (int i = 0; i < 3; ++i)
    w.add_increments(static_cast<std::int32_t>(std::lround(phi[i] * kIncrementRotationScale)));
  for (int i = 0; i < 3; ++i)
    w.add_increments(static_cast<std::int32_t>(std::lround(t[i] * kIncrementTranslationScale)));
}

void fill(wire::Envelope& e, const PoseEstimates& m) {
  wire::PoseEstimates& w = *e.mutable_pose_estimates();
  fillState(*w.mutable_state(), m.state);
  for (const auto& [id, T] : m.poses) w.add_keyframes(keyframeOut(id));
  if (m.increments) {
    if (m.precise) throw core::Error("encode: pose estimates both precise and increments");
    if (m.poses.size() > kMaxEstimates) throw core::Error("encode: more than kMaxEstimates poses");
    for (const auto& [id, D] : m.poses) putIncrement(w, D);
  } else if (m.precise) {
    w.set_precise_poses(poseRecords(m.poses, true));
  } else {
    w.set_poses(poseRecords(m.poses));
  }
}

void fill(wire::Envelope& e, const SummaryRequest& m) {
  e.mutable_summary_request()->set_what(static_cast<std::uint32_t>(m.what));
}

void fill(wire::Envelope& e, const TrajectorySummary& m) {
  wire::TrajectorySummary& w = *e.mutable_trajectory_summary();
  for (const auto& [id, T] : m.poses) w.add_keyframes(keyframeOut(id));
  w.set_poses(poseRecords(m.poses));
}

void fill(wire::Envelope& e, const MapSummary& m) {
  wire::MapSummary& w = *e.mutable_map_summary();
  w.set_keyframes(m.keyframes);
  w.set_cloud(payloadOut(m.cloud, kMaxCloudBytes, "map cloud"));
}

// ---------------------------------------------------------------- bodies in

Heartbeat bodyIn(const wire::Heartbeat& w) {
  Heartbeat m;
  m.stamp = finiteIn(w.stamp(), "heartbeat stamp");
  m.keyframes = w.keyframes();
  if (static_cast<std::size_t>(w.acks_size()) > kMaxAcks) invalid("heartbeat: too many acks");
  for (const wire::Ack& a : w.acks()) {
    if (a.peer() > kMaxRobot) invalid("heartbeat ack: peer is not a robot id (0..254)");
    m.acks.push_back({core::RobotId(static_cast<std::uint8_t>(a.peer())), a.incarnation(),
                      a.broadcast(), a.unicast(), a.broadcast_above(), a.unicast_above()});
  }
  return m;
}

DescriptorMessage bodyIn(const wire::Descriptor& w) {
  DescriptorMessage m{keyframeIn(w.keyframe(), "descriptor"),
                      finiteIn(w.stamp(), "descriptor stamp"),
                      payloadIn(w.descriptor(), kMaxDescriptorBytes, "descriptor"),
                      std::nullopt,
                      std::nullopt,
                      {}};
  check(w.look_alike() <= 1U + static_cast<std::uint32_t>(kLookAlikeScale),
        "descriptor: look-alike distance beyond 1");
  if (w.look_alike() > 0U)
    m.look_alike = static_cast<float>(static_cast<double>(w.look_alike() - 1U) / kLookAlikeScale);
  check(w.resembles_size() == w.resembles_distance_size(),
        "descriptor: resemblances and their distances differ in number");
  check(static_cast<std::size_t>(w.resembles_size()) <= kMaxResemblances,
        "descriptor: too many resemblances");
  for (int i = 0; i < w.resembles_size(); ++i) {
    check(w.resembles_distance(i) <= static_cast<std::uint32_t>(kLookAlikeScale),
          "descriptor: resemblance distance beyond 1");
    m.resembles.push_back(
        {keyframeIn(w.resembles(i), "descriptor resemblance"),
         static_cast<float>(static_cast<double>(w.resembles_distance(i)) / kLookAlikeScale)});
  }
  if (w.odometry_pose().empty() && w.odometry_covariance().empty()) return m;
  check(w.odometry_pose().size() == kPoseRecord, "descriptor: odometry pose record not 19 bytes");
  check(w.odometry_covariance().size() == kCovarianceRecord,
        "descriptor: odometry covariance record not 42 bytes");
  const char* pose = w.odometry_pose().data();
  const char* covariance = w.odometry_covariance().data();
  m.odometry = OdometryStep{keyframeIn(w.previous(), "descriptor previous keyframe"),
                            takePose(pose), takeCovariance(covariance)};
  return m;
}

LoopCandidate bodyIn(const wire::LoopCandidate& w) {
  check(std::isfinite(w.yaw()) && std::abs(w.yaw()) <= std::numbers::pi_v<float> + 1e-3F,
        "loop candidate: yaw not within [-pi, pi]");
  check(std::isfinite(w.distance()) && w.distance() >= 0.0F && w.distance() <= 1.0F,
        "loop candidate: distance not within [0, 1]");
  return {keyframeIn(w.query(), "loop candidate query"),
          keyframeIn(w.match(), "loop candidate match"), w.yaw(), w.distance(),
          payloadIn(w.cloud(), kMaxCloudBytes, "loop candidate cloud")};
}

LoopMeasurement bodyIn(const wire::LoopMeasurement& w) {
  LoopMeasurement m;
  m.query = keyframeIn(w.query(), "loop measurement query");
  m.match = keyframeIn(w.match(), "loop measurement match");
  check(w.status() < kLoopStatuses, "loop measurement: unknown status");
  m.status = static_cast<LoopStatus>(w.status());
  check(w.round() == 0 || m.status == LoopStatus::unexplained,
        "loop measurement: a round on an answer");
  m.round = w.round();
  if (m.status != LoopStatus::verified) {
    check(w.pose().empty() && w.covariance().empty(), "loop measurement: a refusal with a pose");
    return m;
  }
  check(w.pose().size() == kPoseRecord, "loop measurement: pose record not 19 bytes");
  check(w.covariance().size() == kCovarianceRecord,
        "loop measurement: covariance record not 42 bytes");
  const char* pose = w.pose().data();
  m.T_match_query = takePose(pose);
  const char* covariance = w.covariance().data();
  m.covariance = takeCovariance(covariance);
  return m;
}

DgsState stateIn(const wire::DgsState& w, const char* what) {
  const std::string where(what);
  if (w.stage() >= kOptimisationStages) invalid(where + ": unknown optimisation stage");
  if (w.flags() > 15U) invalid(where + ": unknown flags");
  if (!std::isfinite(w.change()) || w.change() < 0.0F)
    invalid(where + ": change negative or not finite");
  if (static_cast<std::size_t>(w.progress_size()) > kMaxAcks)
    invalid(where + ": too many group members");
  if (w.frame() > kMaxRobot + 1U) invalid(where + ": the round's frame is not a robot id (0..254)");
  DgsState m;
  if (w.frame() > 0U) m.frame = core::RobotId(static_cast<std::uint8_t>(w.frame() - 1U));
  m.round = w.round();
  m.stage = static_cast<OptimisationStage>(w.stage());
  m.iteration = w.iteration();
  m.initialised = (w.flags() & 1U) != 0;
  m.converged = (w.flags() & 2U) != 0;
  m.abort = (w.flags() & 4U) != 0;
  m.warm = (w.flags() & 8U) != 0;
  m.change = w.change();
  for (const wire::MemberProgress& p : w.progress()) {
    if (p.robot() > kMaxRobot) invalid(where + ": a group member is not a robot id (0..254)");
    if (p.iteration() > static_cast<std::uint32_t>(std::numeric_limits<std::int32_t>::max()) ||
        p.converged_since() < -1)
      invalid(where + ": group progress out of range");
    m.progress.push_back({core::RobotId(static_cast<std::uint8_t>(p.robot())),
                          static_cast<std::int32_t>(p.iteration()), p.converged_since(),
                          p.finished()});
  }
  return m;
}

DgsState bodyIn(const wire::DgsState& w) {
  return stateIn(w, "dgs state");
}

RotationEstimates bodyIn(const wire::RotationEstimates& w) {
  const auto count = static_cast<std::size_t>(w.keyframes_size());
  check(count <= kMaxEstimates, "rotation estimates: too many");
  check(w.rotations().size() == count * kRotationRecord,
        "rotation estimates: record bytes do not match the keyframe count");
  RotationEstimates m;
  m.state = stateIn(w.state(), "rotation estimates state");
  m.rotations.reserve(count);
  const char* in = w.rotations().data();
  for (const std::uint64_t id : w.keyframes()) {
    m.rotations.emplace_back(keyframeIn(id, "rotation estimates"), takeRotation(in));
  }
  return m;
}

PoseEstimates bodyIn(const wire::PoseEstimates& w) {
  PoseEstimates m;
  m.state = stateIn(w.state(), "pose estimates state");
  check(static_cast<int>(!w.poses().empty()) + static_cast<int>(!w.precise_poses().empty()) +
                static_cast<int>(!w.increments().empty()) <=
            1,
        "pose estimates: more than one of pose records, precise records and increments");
  if (!w.increments().empty()) {
    if (static_cast<std::size_t>(w.keyframes().size()) > kMaxEstimates)
      invalid("pose estimates: more than " + std::to_string(kMaxEstimates) + " poses");
    if (w.increments().size() != 6 * w.keyframes().size()) {
      invalid("pose estimates: " + std::to_string(w.increments().size()) + " increments for " +
              std::to_string(w.keyframes().size()) + " keyframes (six each)");
    }
    m.increments = true;
    m.poses.reserve(static_cast<std::size_t>(w.keyframes().size()));
    for (int k = 0; k < w.keyframes().size(); ++k) {
      Eigen::Vector3d phi;
      Eigen::Vector3d t;
      for (int i = 0; i < 3; ++i) {
        phi[i] = w.increments(6 * k + i) / kIncrementRotationScale;
        t[i] = w.increments(6 * k + 3 + i) / kIncrementTranslationScale;
      }
      check(phi.norm() <= std::numbers::pi + 1e-6,
            "pose estimates: an increment's rotation beyond pi");
      check(t.cwiseAbs().maxCoeff() <= kMaxIncrement,
            "pose estimates: an increment's translation beyond kMaxIncrement");
      Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
      const double angle = phi.norm();
      if (angle > 0.0) D.linear() = Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix();
      D.translation() = t;
      m.poses.emplace_back(keyframeIn(w.keyframes(k), "pose estimates"), D);
    }
    return m;
  }
  m.precise = !w.precise_poses().empty();
  m.poses = m.precise ? posesIn(w.keyframes(), w.precise_poses(), "pose estimates", true)
                      : posesIn(w.keyframes(), w.poses(), "pose estimates");
  return m;
}

SummaryRequest bodyIn(const wire::SummaryRequest& w) {
  check(w.what() <= 1U, "summary request: unknown summary");
  return {static_cast<SummaryKind>(w.what())};
}

TrajectorySummary bodyIn(const wire::TrajectorySummary& w) {
  return {posesIn(w.keyframes(), w.poses(), "trajectory summary")};
}

MapSummary bodyIn(const wire::MapSummary& w) {
  return {w.keyframes(), payloadIn(w.cloud(), kMaxCloudBytes, "map summary cloud")};
}

Body bodyIn(const wire::Envelope& e) {
  using W = wire::Envelope;
  switch (e.body_case()) {
    case W::kHeartbeat:
      return bodyIn(e.heartbeat());
    case W::kDescriptor:
      return bodyIn(e.descriptor());
    case W::kLoopCandidate:
      return bodyIn(e.loop_candidate());
    case W::kLoopMeasurement:
      return bodyIn(e.loop_measurement());
    case W::kDgsState:
      return bodyIn(e.dgs_state());
    case W::kRotationEstimates:
      return bodyIn(e.rotation_estimates());
    case W::kPoseEstimates:
      return bodyIn(e.pose_estimates());
    case W::kSummaryRequest:
      return bodyIn(e.summary_request());
    case W::kTrajectorySummary:
      return bodyIn(e.trajectory_summary());
    case W::kMapSummary:
      return bodyIn(e.map_summary());
    case W::BODY_NOT_SET:
      break;
  }
  invalid("envelope: no body");
}

Header headerIn(const wire::Envelope& e) {
  if (e.version() != kSchemaVersion)
    throw Invalid{DropReason::wrong_version, "schema version " + std::to_string(e.version()) +
                                                 ", expected " + std::to_string(kSchemaVersion)};
  check(e.sender() <= kMaxRobot, "envelope: sender is not a robot id (0..254)");
  check(e.receiver() <= kMaxRobot + 1, "envelope: receiver is not a robot id (0..254)");
  check(e.incarnation() > 0, "envelope: incarnation 0");
  check(e.sequence() > 0, "envelope: sequence 0");
  Header h;
  h.version = e.version();
  h.sender = core::RobotId(static_cast<std::uint8_t>(e.sender()));
  if (e.receiver() > 0) h.receiver = core::RobotId(static_cast<std::uint8_t>(e.receiver() - 1));
  h.incarnation = e.incarnation();
  h.sequence = e.sequence();
  return h;
}

}  // namespace

std::vector<std::uint8_t> encode(const Message& message) {
  const Header& h = message.header;
  if (!h.sender.valid()) throw core::Error("encode: the sender is not a robot id");
  if (h.receiver && !h.receiver->valid())
    throw core::Error("encode: the receiver is not a robot id");
  wire::Envelope e;
  e.set_version(h.version);
  e.set_sender(h.sender.value());
  e.set_receiver(h.receiver ? h.receiver->value() + 1U : 0U);
  e.set_incarnation(h.incarnation);
  e.set_sequence(h.sequence);
  std::visit([&e](const auto& body) { fill(e, body); }, message.body);
  std::vector<std::uint8_t> bytes(e.ByteSizeLong());
  if (bytes.size() > kMaxMessageBytes)
    throw core::Error("encode: message of " + std::to_string(bytes.size()) + " bytes");
  e.SerializeWithCachedSizesToArray(bytes.data());
  return bytes;
}

Decoded decode(std::span<const std::uint8_t> bytes) {
  Decoded out;
  if (bytes.size() > kMaxMessageBytes) {
    out.reason = DropReason::oversized;
    out.detail =
        std::to_string(bytes.size()) + " bytes, more than " + std::to_string(kMaxMessageBytes);
    return out;
  }
  wire::Envelope e;
  if (!e.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    out.reason = DropReason::malformed;
    out.detail = "not a dcl.wire.Envelope (truncated or corrupt)";
    return out;
  }
  try {
    Header header = headerIn(e);
    out.message = Message{header, bodyIn(e)};
  } catch (const Invalid& failure) {
    out.reason = failure.reason;
    out.detail = failure.detail;
  }
  return out;
}

Body asDelivered(const Body& body) {
  Message m;
  m.header.sender = core::RobotId(0);
  m.header.incarnation = 1;
  m.header.sequence = 1;
  m.body = body;
  const std::vector<std::uint8_t> bytes = encode(m);
  Decoded d = decode(bytes);
  if (!d.message) throw core::Error("a message does not decode as it was encoded: " + d.detail);
  return std::move(d.message->body);
}

}  // namespace dcl::comm
