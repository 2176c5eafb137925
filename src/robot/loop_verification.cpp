// Loop verification: a candidate received (stage 2) is registered against
// the own submap around the matched keyframe and the measurement goes back
// (stage 3); a measurement received becomes a loop of the pair.

#include <algorithm>
#include <cstddef>
#include <string>
#include <variant>

#include <dcl/comm/messages.hpp>
#include <dcl/core/error.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/verification.hpp>

#include "robot_node_impl.hpp"

namespace dcl::robot {
namespace {

/// "rejected_low_inlier_share", ... for the counters.
std::string refusalCounter(comm::LoopStatus status) {
  static constexpr const char* kNames[] = {"verified",
                                           "rejected_too_few_points",
                                           "rejected_not_converged",
                                           "rejected_low_inlier_share",
                                           "rejected_high_fitness",
                                           "rejected_degenerate",
                                           "rejected_no_submap",
                                           "rejected_bad_cloud",
                                           "unexplained",
                                           "rejected_symmetric",
                                           "repeated"};
  return kNames[static_cast<std::size_t>(status)];
}

}  // namespace

core::Matrix6d loopCovariance(const core::Matrix6d& registration, const RobotConfig& config) {
  core::Matrix6d covariance = registration;
  covariance.diagonal().head<3>().array() +=
      config.loop_sigma_translation * config.loop_sigma_translation;
  const double tilt = std::max(config.loop_sigma_tilt, config.loop_sigma_rotation);
  covariance.diagonal().tail<3>() += Eigen::Vector3d(
      tilt * tilt, tilt * tilt, config.loop_sigma_rotation * config.loop_sigma_rotation);
  return covariance;
}

/// Stage 2 received: verify against the own submap; stage 3 back.
void RobotNode::Impl::onCandidate(core::RobotId from, const comm::LoopCandidate& c) {
  count("candidates_received");
  comm::LoopMeasurement answer{c.query, c.match, comm::LoopStatus::no_submap};
  if (c.match.value() < mapper.keyframes().size()) {
    answer = verify(c);
  }
  count(refusalCounter(answer.status));
  // Keep the loop as the querying robot will read it, so both hold the same factor.
  answer = std::get<comm::LoopMeasurement>(comm::asDelivered(answer));
  if (answer.status == comm::LoopStatus::verified) addLoop(from, loopFactor(self, from, answer));
  messenger.send(from, answer, now);
}

comm::LoopMeasurement RobotNode::Impl::verify(const comm::LoopCandidate& c) {
  comm::LoopMeasurement answer{c.query, c.match, comm::LoopStatus::bad_cloud};
  core::PointCloud query;
  try {
    query = registration::decodeVerificationCloud(c.cloud);
  } catch (const core::Error&) {
    return answer;
  }
  const registration::VerificationConfig& vc = config.verification;
  const core::PointCloud submap = registration::buildSubmap(mapper.keyframes(), c.match.value(),
                                                            vc.submap_keyframes, vc.voxel_size);
  const registration::VerificationResult v = registration::verifyLoop(query, c.yaw, submap, vc);
  answer.status = v.reason == registration::RejectReason::symmetric
                      ? comm::LoopStatus::symmetric
                      : static_cast<comm::LoopStatus>(v.reason);  // the same order to degenerate
  answer.T_match_query = v.T_candidate_query;
  answer.covariance = loopCovariance(v.covariance, config);
  return answer;
}

/// The loop factor from the verifying robot's keyframe to the querying one's.
backend::Factor RobotNode::Impl::loopFactor(core::RobotId verifier, core::RobotId querier,
                                            const comm::LoopMeasurement& m) {
  backend::Factor f;
  f.from = {verifier, m.match};
  f.to = {querier, m.query};
  f.kind = backend::FactorKind::inter_loop;
  f.T_from_to = m.T_match_query;
  f.information = backend::informationFromCovariance(m.covariance);
  return f;
}

/// Stage 3 received: the neighbour verified one of the own candidates.
void RobotNode::Impl::onMeasurement(core::RobotId from, const comm::LoopMeasurement& m) {
  if (m.status == comm::LoopStatus::unexplained) return onUnexplained(from, m);
  if (m.status == comm::LoopStatus::repeated) return onRepeated(from, m);
  count(m.status == comm::LoopStatus::verified ? "measurements_verified" : "measurements_refused");
  if (m.status != comm::LoopStatus::verified) return;
  addLoop(from, loopFactor(from, self, m));
}

}  // namespace dcl::robot
