#pragma once

// A robot's front-end as its dataset says: an external one's poses (the
// robot's `odometry` entry in dataset.yaml), or the built-in LiDAR odometry.

#include <cstddef>
#include <memory>

#include <dcl/core/trajectory.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/scan_source.hpp>
#include <dcl/odometry/external_odometry.hpp>

namespace dcl::apps {

/// The poses of the external front-end `config` names (file, format, times,
/// topic), checked first (odometry::validate): io::readExternalOdometry, ROS 2
/// bags decoded by dcl::ros. Throws core::FileError naming the file that
/// cannot be read, core::Error for a configuration that breaks a rule.
core::Trajectory readExternalPoses(const odometry::ExternalOdometryConfig& config);

/// Robot `robot`'s external front-end, read with the configuration's `external`
/// section (T_body_sensor, noise model) and checked to cover the stamps of its
/// first `frames` scans (0: all); none when the dataset gives it none. Throws
/// core::FileError naming the file that cannot be read, core::Error when the
/// poses miss the scans.
std::unique_ptr<odometry::Odometry> datasetFrontEnd(
    const io::DatasetSpec& spec, std::size_t robot, const io::ScanSource& scans, std::size_t frames,
    const odometry::ExternalOdometryConfig& external);

}  // namespace dcl::apps
