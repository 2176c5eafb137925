// Own scans and keyframes: each scan through the front-end and the local
// mapper; each new keyframe described, indexed and sent to the neighbours
// with the odometry step that led to it (stage 1).

#include <algorithm>
#include <memory>
#include <optional>
#include <utility>
#include <variant>

#include <dcl/comm/messages.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>

#include "robot_node_impl.hpp"

namespace dcl::robot {
using detail::odometryFactor;

void RobotNode::Impl::addScan(double stamp, const core::PointCloud& scan,
                              const std::optional<Eigen::Vector3d>& up) {
  count("frames");
  if (up) odometry->observeUp(*up);
  const odometry::OdometryResult result = odometry->process(stamp, scan);
  const odometry::MapperUpdate update =
      result.registered.empty() ? mapper.process(result, scan) : mapper.process(result);
  if (update.loop) count("intra_loops");
  if (update.keyframe) onKeyframe(mapper.keyframes().back());
}

void RobotNode::Impl::onKeyframe(const core::Keyframe& keyframe) {
  count("keyframes");
  messenger.setKeyframes(static_cast<std::uint32_t>(mapper.keyframes().size()));
  auto description =
      std::make_shared<const place::IrisDescriptor>(place::describeIris(keyframe.cloud, iris));
  const auto alikes = index.lookAlikes(*description, keyframe.T_odom_keyframe.translation(),
                                       ownPosition(), index.size());
  index.add(keyframe.id, description);
  own_alike.push_back(alikes.empty() ? 1.0F : alikes.front().second);
  for (const auto& [earlier, distance] : alikes)
    own_alike[earlier.value()] = std::min(own_alike[earlier.value()], distance);
  comm::DescriptorMessage m{keyframe.id,  keyframe.stamp, place::encodeIris(*description),
                            std::nullopt, std::nullopt,   {}};
  if (!alikes.empty()) m.look_alike = alikes.front().second;
  for (const auto& [earlier, distance] : alikes) {
    if (m.resembles.size() == comm::kMaxResemblances) break;
    m.resembles.push_back({earlier, distance});
  }
  if (keyframe.id.value() > 0)
    m.odometry = comm::OdometryStep{core::KeyframeId(keyframe.id.value() - 1),
                                    keyframe.T_previous_keyframe, keyframe.covariance};
  // PCM checks the own chain as the neighbours read it (both sides decide alike).
  m = std::get<comm::DescriptorMessage>(comm::asDelivered(m));
  for (auto& [robot, n] : neighbours)
    for (const comm::Resemblance& r : m.resembles) judgeOwnRepeat(robot, n, r, *description);
  if (m.odometry) {
    const backend::Factor step = odometryFactor(self, keyframe.id, *m.odometry);
    own_chain.push_back(step);
    for (auto& [robot, n] : neighbours) {
      n.pcm.addRobotFactor(step);
      redecideIfRejecting(n);
    }
  }
  messenger.send(std::nullopt, std::move(m), now);
  count("descriptors_sent");
}

/// Where the own odometry puts an own keyframe (the place index's positions).
place::KeyframePosition RobotNode::Impl::ownPosition() const {
  return [this](core::KeyframeId id) {
    return Eigen::Vector3d(mapper.keyframes().at(id.value()).T_odom_keyframe.translation());
  };
}

}  // namespace dcl::robot
