#include "front_end.hpp"

#include <algorithm>

#include <dcl/io/external_odometry.hpp>
#include <dcl/ros/ros2_bag.hpp>

namespace dcl::apps {

core::Trajectory readExternalPoses(const odometry::ExternalOdometryConfig& config) {
  odometry::validate(config);
  return io::readExternalOdometry(config.file, {.format = config.format,
                                                .times = config.times,
                                                .topic = config.topic,
                                                .read_mcap = &ros2::readMcapTrajectory});
}

std::unique_ptr<odometry::Odometry> datasetFrontEnd(
    const io::DatasetSpec& spec, std::size_t robot, const io::ScanSource& scans, std::size_t frames,
    const odometry::ExternalOdometryConfig& external) {
  const io::FrontEndSpec& f = spec.robots.at(robot).odometry;
  if (f.empty()) return nullptr;
  odometry::ExternalOdometryConfig config = external;
  config.file = spec.resolve(f.file);
  config.format = f.format;
  config.topic = f.topic;
  config.times = f.times.empty() ? std::string() : spec.resolve(f.times);
  auto front_end = std::make_unique<odometry::ExternalOdometry>(readExternalPoses(config), config);
  const std::size_t n = frames > 0 ? std::min(frames, scans.size()) : scans.size();
  if (n > 0) front_end->requireOverlap(scans.stamp(0), scans.stamp(n - 1));
  return front_end;
}

}  // namespace dcl::apps
