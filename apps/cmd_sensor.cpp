// `dcl-slam bench sensor`: the statistics of real LiDAR sweeps beside those of
// a simulated dataset's sweeps (eval/scan_statistics.hpp), statistic by statistic.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/eval/scan_statistics.hpp>
#include <dcl/io/cloud_file.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/sim/routes.hpp>
#include <dcl/sim/sim_source.hpp>

#include "commands.hpp"

namespace dcl::apps {

namespace {

struct BenchSensorOptions {
  std::string real;
  std::string data;
  std::string dataset;
  std::string robot;
  std::size_t scans = 10;
  bool json = false;
};

/// The statistics of every scan file in `folder` (KITTI .bin, PCD or PLY), by name.
std::vector<eval::ScanStatistics> realSweepStatistics(const std::string& folder) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(folder))
    throw core::Error("--real: '" + folder + "' is not a folder of scans");
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const auto ext = entry.path().extension();
    if (ext == ".bin" || ext == ".pcd" || ext == ".ply") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty())
    throw core::Error("--real: '" + folder + "' holds no scan (.bin, .pcd or .ply)");
  std::vector<eval::ScanStatistics> stats;
  for (const auto& file : files) {
    try {
      stats.push_back(
          eval::measureScanStatistics(io::readCloud(file.string(), {.drop_nan = true})));
    } catch (const core::Error& e) {
      throw core::Error("--real: " + file.string() + ": " + e.what());
    }
  }
  return stats;
}

/// The statistics of `count` scans of one robot of a simulated dataset, evenly
/// spaced along its route.
std::vector<eval::ScanStatistics> simulatedSweepStatistics(const BenchSensorOptions& o,
                                                           const sim::SimWorld& world) {
  const io::DatasetSpec& spec = world.dataset();
  std::size_t robot = 0;
  if (!o.robot.empty()) {
    const auto index = spec.robotIndex(o.robot);
    if (!index)
      throw core::Error("--robot: dataset '" + spec.name + "' has no robot '" + o.robot + "'");
    robot = *index;
  }
  const std::size_t total = world.groundTruth(robot).size();
  const std::size_t count = std::min(o.scans, total);
  std::vector<eval::ScanStatistics> stats;
  for (std::size_t k = 0; k < count; ++k) {
    // The middle of each of `count` equal stretches of the route.
    const std::size_t index = (2 * k + 1) * total / (2 * count);
    stats.push_back(eval::measureScanStatistics(world.scan(robot, index)));
  }
  return stats;
}

/// One line of the vehicle table: a trajectory's name and its attitude.
struct AttitudeLine {
  std::string name;
  eval::AttitudeStatistics attitude;
};

/// The attitude of the real KITTI 00, 05 and 08 drives (LiDAR frame) and of
/// every robot of the simulated dataset.
std::vector<AttitudeLine> attitudeLines(const std::string& data, const sim::SimWorld& world) {
  std::vector<AttitudeLine> lines;
  for (const std::string sequence : {"00", "05", "08"}) {
    const sim::KittiFiles files = sim::kittiFiles(data, sequence);
    lines.push_back({"real KITTI " + sequence, eval::measureAttitude(sim::loadKittiLidarTrajectory(
                                                   files.poses, files.calib, files.times))});
  }
  for (std::size_t r = 0; r < world.robots(); ++r)
    if (world.groundTruth(r).size() >= 50)  // 5 s at least: a shorter drive has no slow part
      lines.push_back({"simulated " + world.dataset().robots[r].name,
                       eval::measureAttitude(world.groundTruth(r))});
  return lines;
}

void runBenchSensor(const BenchSensorOptions& o) {
  if (o.scans == 0) throw core::Error("--scans must be at least 1");
  const auto real = realSweepStatistics(o.real);
  const sim::SimWorld world(io::readDataset(o.dataset, datasetReadOptions()));
  const auto simulated = simulatedSweepStatistics(o, world);
  const auto attitudes = attitudeLines(o.data, world);
  nlohmann::ordered_json vehicle = nlohmann::ordered_json::array();
  for (const auto& line : attitudes)
    vehicle.push_back({{"trajectory", line.name},
                       {"pitch_sigma_deg", line.attitude.pitch_sigma_deg},
                       {"roll_sigma_deg", line.attitude.roll_sigma_deg},
                       {"pitch_p99_deg", line.attitude.pitch_p99_deg},
                       {"roll_p99_deg", line.attitude.roll_p99_deg}});
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  std::size_t inside = 0;
  if (!o.json)
    fmt::print("{:<34} {:>17} {:>17} {:>8}  {}\n", "statistic",
               fmt::format("real ({} scans)", real.size()),
               fmt::format("sim ({} scans)", simulated.size()), "+/-", "sim median in band");
  for (const auto& row : eval::statisticRows()) {
    const auto r = eval::bandOf(row, real);
    const auto s = eval::bandOf(row, simulated);
    // In band: the simulated scans' median within the real scans' band.
    std::vector<double> values;
    for (const auto& stat : simulated) values.push_back(row.value(stat));
    std::nth_element(values.begin(),
                     values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
    const double mid = values[values.size() / 2];
    const bool ok = r.contains(mid, row.tolerance);
    inside += ok;
    rows.push_back({{"statistic", row.name},
                    {"real", {r.lo, r.hi}},
                    {"simulated", {s.lo, s.hi}},
                    {"simulated_median", mid},
                    {"tolerance", row.tolerance},
                    {"in_band", ok}});
    if (!o.json)
      fmt::print("{:<34} {:>8.4f}-{:<8.4f} {:>8.4f}-{:<8.4f} {:>8.3f}  {}\n", row.name, r.lo, r.hi,
                 s.lo, s.hi, row.tolerance, ok ? "yes" : "no");
  }
  if (o.json) {
    fmt::print("{}\n", nlohmann::ordered_json{{"real_scans", real.size()},
                                              {"simulated_scans", simulated.size()},
                                              {"in_band", inside},
                                              {"statistics", rows},
                                              {"vehicle", vehicle}}
                           .dump(2));
    return;
  }
  fmt::print(
      "{} of {} statistics: the simulated scans' median within the real band, widened by +/-\n",
      inside, rows.size());
  fmt::print(
      "\nvehicle attitude, less its 2 s mean (deg)  pitch sigma  roll sigma  pitch p99  roll "
      "p99\n");
  for (const auto& line : attitudes)
    fmt::print("{:<42} {:>11.3f} {:>11.3f} {:>10.3f} {:>9.3f}\n", line.name,
               line.attitude.pitch_sigma_deg, line.attitude.roll_sigma_deg,
               line.attitude.pitch_p99_deg, line.attitude.roll_p99_deg);
}

}  // namespace

void addBenchSensorCommand(CLI::App& bench) {
  auto* cmd = bench.add_subcommand(
      "sensor", "statistics of real LiDAR sweeps beside a simulated dataset's, one by one");
  auto o = std::make_shared<BenchSensorOptions>();
  o->real = (std::filesystem::path(defaultDataDir()) / "lidar_scans/kitti_00/velodyne").string();
  cmd->add_option("--real", o->real, "folder of real scans (.bin, .pcd, .ply)")
      ->capture_default_str();
  o->data = defaultDataDir();
  cmd->add_option("--data", o->data,
                  "the shared data folder with KITTI ground truth (or DCL_DATA_DIR)")
      ->capture_default_str();
  cmd->add_option("--dataset", o->dataset, "simulated dataset folder")->required();
  cmd->add_option("--robot", o->robot, "the robot whose scans to measure (default: the first)");
  cmd->add_option("--scans", o->scans, "scans evenly spaced along its route")
      ->capture_default_str();
  cmd->add_flag("--json", o->json, "print the result as JSON");
  cmd->callback([o] { runBenchSensor(*o); });
}

}  // namespace dcl::apps
