#include <charconv>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string_view>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/ros/imu_readings.hpp>
#include <dcl/ros/ros2_bag.hpp>
#include <dcl/sim/lidar_model.hpp>
#include <dcl/sim/sim_source.hpp>

#include "scan_cache.hpp"
#include "world_detail.hpp"

namespace dcl::sim {

namespace {

namespace fs = std::filesystem;

const io::SimSpec& requireSim(const io::DatasetSpec& spec) {
  if (!spec.sim) {
    throw core::Error(
        fmt::format("dataset '{}' has no sim section: its scans are not simulated", spec.name));
  }
  return *spec.sim;
}

/// m: how far from the origin a simulated route may go (KITTI's longest
/// sequences span about 1 km).
constexpr double kMostWorldHalfWidth = 10000.0;
constexpr double kMostWorldHeight = 1000.0;

std::vector<core::Trajectory> readAllGroundTruth(const io::DatasetSpec& spec) {
  std::vector<core::Trajectory> out;
  for (std::size_t r = 0; r < spec.robots.size(); ++r) {
    out.push_back(io::readGroundTruth(spec, r));
    if (!out.back().isSorted()) {
      throw core::Error(fmt::format("dataset '{}': robot '{}': ground-truth stamps decrease",
                                    spec.name, spec.robots[r].name));
    }
    // The world is built over the routes' extent: a pose kilometres off
    // (a typo, or a file in another frame) would build a world without end.
    const core::Trajectory& t = out.back();
    for (std::size_t i = 0; i < t.size(); ++i) {
      const Eigen::Vector3d at = t.pose(i).translation();
      if (at.head<2>().cwiseAbs().maxCoeff() > kMostWorldHalfWidth ||
          std::abs(at.z()) > kMostWorldHeight)
        throw core::Error(fmt::format(
            "dataset '{}': robot '{}': ground-truth pose {} of {} (t = {} s) at ({:.1f}, {:.1f}, "
            "{:.1f}) m is outside the {} x {} km a simulated world spans around the origin "
            "(height within {} m)",
            spec.name, spec.robots[r].name, i + 1, spec.resolve(spec.robots[r].ground_truth),
            t.stamp(i), at.x(), at.y(), at.z(), 2 * kMostWorldHalfWidth / 1000.0,
            2 * kMostWorldHalfWidth / 1000.0, kMostWorldHeight));
    }
  }
  return out;
}

WorldRequest requestOf(const io::DatasetSpec& spec, std::span<const core::Trajectory> routes) {
  return {.routes = routes, .mount_height = spec.mount_height, .seed = spec.sim->seed};
}

LidarModel modelOf(const io::DatasetSpec& spec) {
  LidarModel model = LidarModel::byName(spec.sensor);
  model.mount_height = spec.mount_height;
  return model;
}

ScanOptions scanOptionsOf(const io::SimSpec& sim, const SimWorldOptions& options) {
  return {
      .motion_distortion = sim.motion_distortion, .noise = sim.noise, .parallel = options.parallel};
}

/// The scan cache the environment names (SimWorldOptions::scan_cache); none when unset.
std::unique_ptr<detail::ScanCache> scanCacheOf(const io::DatasetSpec& spec,
                                               const std::vector<core::Trajectory>& ground_truth,
                                               const SimWorldOptions& options) {
  const char* folder = std::getenv(kScanCacheVariable);
  if (!options.scan_cache || folder == nullptr || *folder == '\0') return nullptr;
  std::uint64_t megabytes = 2048;
  if (const char* text = std::getenv(kScanCacheSizeVariable); text != nullptr && *text != '\0') {
    const std::string_view value(text);
    const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), megabytes);
    if (ec != std::errc() || end != value.data() + value.size() || megabytes > (1ULL << 40)) {
      throw core::Error(fmt::format("{}: '{}' is not a whole number of megabytes",
                                    kScanCacheSizeVariable, value));
    }
  }
  return std::make_unique<detail::ScanCache>(folder, detail::simulationKey(spec, ground_truth),
                                             megabytes << 20);
}

/// The IMU's seed beside the LiDAR's `seed` (a unit's or a scan's): its own
/// numbers, so that the scans do not change with it.
std::uint64_t imuSeed(std::uint64_t seed) {
  return detail::splitmix(seed ^ 0x494d5500494d5500ULL);
}

}  // namespace

World generateWorldOfKind(io::WorldKind kind, const WorldRequest& request) {
  switch (kind) {
    case io::WorldKind::campus:
      return generateCampusWorld(request);
    case io::WorldKind::aliasing:
      return generateAliasingWorld(request);
    default:
      return generateCityWorld(request);
  }
}

Traffic generateTrafficOfKind(io::WorldKind kind, const WorldRequest& request, double density) {
  switch (kind) {
    case io::WorldKind::campus:
      return generateTraffic(request, campusStyle(), campusTraffic(), density);
    case io::WorldKind::aliasing:
      return generateTraffic(request, aliasingStyle(), cityTraffic(), density);
    default:
      return generateTraffic(request, cityStyle(), cityTraffic(), density);
  }
}

std::uint64_t scanSeed(std::uint64_t dataset_seed, std::size_t robot, std::size_t index) {
  return detail::splitmix(detail::splitmix(detail::splitmix(dataset_seed) ^ robot) ^ index);
}

std::uint64_t unitSeed(std::uint64_t dataset_seed, std::size_t robot) {
  return detail::splitmix(detail::splitmix(detail::splitmix(dataset_seed) ^ robot) ^
                          ~std::uint64_t{0});  // no scan has index ~0
}

// ---- SimWorld ----

struct SimWorld::Impl {
  io::DatasetSpec spec;
  std::vector<core::Trajectory> ground_truth;
  World world;
  ScanSimulator simulator;
  /// Each robot's LiDAR (the first robot's for all when shared); perfect ones without noise.
  std::vector<BeamCalibration> units;
  ImuModel imu;
  /// Each robot's IMU tilt (the first robot's for all when shared); empty without an IMU.
  std::vector<Eigen::Vector2d> imu_tilts;
  std::unique_ptr<detail::ScanCache> cache;  ///< null without one

  Impl(const io::DatasetSpec& s, std::vector<core::Trajectory> gt, const SimWorldOptions& options)
      : spec(s),
        ground_truth(std::move(gt)),
        world(generateWorldOfKind(requireSim(s).world, requestOf(s, ground_truth))),
        simulator(world, modelOf(s), scanOptionsOf(*s.sim, options),
                  generateTrafficOfKind(s.sim->world, requestOf(s, ground_truth), s.sim->traffic)),
        cache(scanCacheOf(s, ground_truth, options)) {
    for (std::size_t r = 0; r < ground_truth.size(); ++r) {
      const std::size_t unit = s.sim->shared_unit ? 0 : r;
      units.push_back(s.sim->noise && s.sim->calibration_error
                          ? BeamCalibration::draw(simulator.model(), unitSeed(s.sim->seed, unit))
                          : BeamCalibration{});
      if (s.sim->imu) imu_tilts.push_back(drawImuTilt(imu, imuSeed(unitSeed(s.sim->seed, unit))));
    }
  }
};

SimWorld::SimWorld(const io::DatasetSpec& spec, const SimWorldOptions& options) {
  requireSim(spec);
  (void)LidarModel::byName(spec.sensor);  // fail before the slow part
  impl_ = std::make_unique<Impl>(spec, readAllGroundTruth(spec), options);
}

SimWorld::~SimWorld() = default;

core::PointCloud SimWorld::scan(std::size_t robot, std::size_t index) const {
  const core::Trajectory& gt = groundTruth(robot);
  if (index >= gt.size()) {
    throw core::Error(fmt::format("robot '{}': no scan {} (it has {})",
                                  impl_->spec.robots[robot].name, index, gt.size()));
  }
  if (impl_->cache) {
    if (auto cached = impl_->cache->load(robot, index)) return std::move(*cached);
  }
  core::PointCloud scan = impl_->simulator.scan(
      gt, gt.stamp(index), scanSeed(impl_->spec.sim->seed, robot, index), impl_->units[robot]);
  if (impl_->cache) impl_->cache->store(robot, index, scan);
  return scan;
}

std::uint64_t SimWorld::cachedScansRead() const {
  return impl_->cache ? impl_->cache->hits() : 0;
}

std::uint64_t SimWorld::cachedScansStored() const {
  return impl_->cache ? impl_->cache->stores() : 0;
}

std::optional<Eigen::Vector3d> SimWorld::up(std::size_t robot, std::size_t index) const {
  const core::Trajectory& gt = groundTruth(robot);
  if (index >= gt.size()) {
    throw core::Error(fmt::format("robot '{}': no IMU reading {} (it has {})",
                                  impl_->spec.robots[robot].name, index, gt.size()));
  }
  if (impl_->imu_tilts.empty()) return std::nullopt;
  return readUp(impl_->imu, gt.pose(index).rotation(), impl_->imu_tilts[robot],
                imuSeed(scanSeed(impl_->spec.sim->seed, robot, index)));
}

std::size_t SimWorld::robots() const {
  return impl_->ground_truth.size();
}

const BeamCalibration& SimWorld::unit(std::size_t robot) const {
  return impl_->units.at(robot);
}

const core::Trajectory& SimWorld::groundTruth(std::size_t robot) const {
  return impl_->ground_truth.at(robot);
}

const io::DatasetSpec& SimWorld::dataset() const {
  return impl_->spec;
}

const World& SimWorld::world() const {
  return impl_->world;
}

const ScanSimulator& SimWorld::simulator() const {
  return impl_->simulator;
}

// ---- SimScanSource ----

SimScanSource::SimScanSource(std::shared_ptr<const SimWorld> world, std::size_t robot)
    : world_(std::move(world)), robot_(robot) {
  if (robot_ >= world_->robots()) {
    throw core::Error(fmt::format("no robot {} (the dataset has {})", robot_, world_->robots()));
  }
}

std::size_t SimScanSource::size() const {
  return world_->groundTruth(robot_).size();
}

double SimScanSource::stamp(std::size_t i) const {
  if (i >= size())
    throw core::Error(fmt::format("{}: no scan {} (it has {})", describe(), i, size()));
  return world_->groundTruth(robot_).stamp(i);
}

core::PointCloud SimScanSource::scan(std::size_t i) const {
  return world_->scan(robot_, i);
}

std::optional<Eigen::Vector3d> SimScanSource::up(std::size_t i) const {
  return world_->up(robot_, i);
}

std::string SimScanSource::describe() const {
  const io::DatasetSpec& spec = world_->dataset();
  return fmt::format("simulated robot '{}' of dataset '{}'", spec.robots[robot_].name, spec.name);
}

// ---- opening datasets ----

std::unique_ptr<io::ScanSource> openRobotScans(const io::DatasetSpec& spec, std::size_t robot,
                                               std::shared_ptr<const SimWorld> world) {
  const io::ScanSourceSpec& scans = spec.robots.at(robot).scans;
  if (scans.type == io::ScanSourceType::mcap || scans.type == io::ScanSourceType::bag) {
    const std::string file = spec.resolve(scans.file);
    std::unique_ptr<io::ScanSource> source;
    double origin = 0.0;
    std::vector<msg::Imu> imu;
    if (scans.type == io::ScanSourceType::mcap) {
      auto mcap = std::make_unique<ros2::McapScanSource>(file, scans.topic);
      origin = mcap->originStamp();
      source = std::move(mcap);
      if (!scans.imu_topic.empty()) imu = ros2::readMcapImu(file, scans.imu_topic);
    } else {
      auto bag = std::make_unique<io::BagScanSource>(file, scans.topic);
      origin = bag->originStamp();
      source = std::move(bag);
      if (!scans.imu_topic.empty()) imu = ros1::readBagImu(file, scans.imu_topic);
    }
    if (scans.imu_topic.empty()) return source;
    // The readings of up, as a live robot takes them (robot --imu): the one
    // nearest each scan's stamp, within kImuMaxGap.
    const Eigen::Matrix3d R_lidar_imu =
        msg::rotationOfRpy(scans.imu_rpy[0], scans.imu_rpy[1], scans.imu_rpy[2]);
    msg::UpReadings readings;
    for (const msg::Imu& m : imu) (void)readings.add(m, R_lidar_imu);
    return std::make_unique<msg::LevelledScanSource>(std::move(source), std::move(readings), origin,
                                                     kImuMaxGap);
  }
  if (scans.type != io::ScanSourceType::sim) return io::openScanSource(spec, robot);
  if (!world) world = std::make_shared<const SimWorld>(spec);
  return std::make_unique<SimScanSource>(std::move(world), robot);
}

std::vector<std::unique_ptr<io::ScanSource>> openDatasetScans(const io::DatasetSpec& spec,
                                                              const SimWorldOptions& options) {
  std::shared_ptr<const SimWorld> world;
  std::vector<std::unique_ptr<io::ScanSource>> out;
  for (std::size_t r = 0; r < spec.robots.size(); ++r) {
    const bool sim = spec.robots[r].scans.type == io::ScanSourceType::sim;
    if (sim && !world) world = std::make_shared<const SimWorld>(spec, options);
    out.push_back(openRobotScans(spec, r, world));
  }
  return out;
}

// ---- writing ----

io::DatasetSpec writeSimDataset(const std::string& folder, const Preset& preset,
                                const SimDatasetOptions& options) {
  const auto kind = io::parseWorldKind(preset.world);
  if (!kind)
    throw core::Error(fmt::format("preset '{}': unknown world '{}'", preset.name, preset.world));
  (void)LidarModel::byName(preset.sensor);
  io::DatasetSpec spec;
  spec.name = preset.name;
  spec.description = preset.description;
  spec.sensor = preset.sensor;
  spec.mount_height = preset.mount_height;
  spec.sim = io::SimSpec{.world = *kind,
                         .seed = preset.seed,
                         .motion_distortion = options.motion_distortion,
                         .noise = options.noise,
                         .calibration_error = options.calibration_error && preset.calibration_error,
                         .shared_unit = preset.shared_unit,
                         .traffic = options.traffic,
                         .imu = options.imu && preset.imu};
  for (const Route& route : preset.routes) {
    const std::string gt = "ground_truth/" + route.name + ".tum";
    io::writeTumPoses((fs::path(folder) / gt).string(), route.T_world_sensor);
    spec.robots.push_back({.name = route.name, .scans = {}, .ground_truth = gt, .start_time = 0.0});
  }
  io::writeDataset(folder, spec);
  return io::readDataset(folder);
}

}  // namespace dcl::sim
