// `dcl-slam simulate`: a simulated dataset from a preset (scans regenerated on
// demand, optionally exported), or a preview picture of one; and
// `dcl-slam bench sim`: how fast a dataset's whole scan stream is generated.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/sim/drifting_odometry.hpp>
#include <dcl/sim/export.hpp>
#include <dcl/sim/lidar_model.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/preview.hpp>
#include <dcl/sim/sim_source.hpp>

#include "commands.hpp"
#include "output_folder.hpp"
#include "printing.hpp"

namespace dcl::apps {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using Json = nlohmann::ordered_json;

struct SimulateOptions {
  std::string preset;                  ///< preset name
  std::string out;                     ///< dataset folder to write
  std::string preview;                 ///< dataset folder to draw
  std::string data;                    ///< the shared data folder (KITTI ground truth)
  std::uint64_t seed = 1;              ///< seeds world, routes and noise
  int robots = 0;                      ///< 0: the preset's count
  std::string sensor;                  ///< "": the preset's sensor
  std::string export_format;           ///< "", kitti or bag
  std::size_t max_scans = 0;           ///< > 0: cut every route to this many scans
  bool no_motion_distortion = false;   ///< scans without motion distortion
  bool no_noise = false;               ///< scans without range noise and dropout
  bool perfect_lasers = false;         ///< every robot's lasers exactly on the published table
  bool no_imu = false;                 ///< no IMU reading of up with the scans
  std::vector<double> odometry_drift;  ///< % and deg/m: a drifting external front-end per robot
  double traffic = 0.0;                ///< moving actors, times the world's own traffic
  bool body_motion = false;            ///< generated routes' vehicles rock on their suspension
  bool force = false;                  ///< replace --out even when it holds other files
};

struct BenchSimOptions {
  std::string dataset;                                                   ///< dataset folder
  std::string robot;                                                     ///< "": every robot
  unsigned threads = std::max(1u, std::thread::hardware_concurrency());  ///< worker threads
  bool json = false;  ///< machine-readable result
};

std::string humanBytes(std::uintmax_t bytes) {
  if (bytes < 10'000) return fmt::format("{} B", bytes);
  if (bytes < 10'000'000) return fmt::format("{:.1f} kB", bytes / 1e3);
  return fmt::format("{:.1f} MB", bytes / 1e6);
}

std::uintmax_t folderBytes(const fs::path& folder) {
  std::uintmax_t bytes = 0;
  for (const auto& e : fs::recursive_directory_iterator(folder)) {
    if (e.is_regular_file()) bytes += e.file_size();
  }
  return bytes;
}

// ---- simulate ----

/// Which lasers the robots carry, in words.
std::string_view lasersOf(const io::SimSpec& sim) {
  if (!sim.noise) return "perfect, without noise";
  if (!sim.calibration_error) return "perfect (on the published beam table)";
  if (sim.shared_unit) return "one unit with calibration errors, carried by every robot";
  return "each robot its own unit with calibration errors";
}

/// Describes the dataset written into `out`, which will be `shown`.
void printSummary(const sim::Preset& preset, const io::DatasetSpec& spec, const std::string& out,
                  const std::string& shown) {
  fmt::print("dataset '{}' ({}): {} world, seed {}, {} at {:.2f} m\n", spec.name,
             preset.description, preset.world, preset.seed, spec.sensor, spec.mount_height);
  fmt::print("  lasers: {}\n", lasersOf(*spec.sim));
  if (spec.sim->imu)
    fmt::print("  imu: every scan with its reading of up (tilt error and noise)\n");
  if (spec.sim->traffic > 0.0)
    fmt::print("  traffic: {} times the {} world's own\n", spec.sim->traffic, preset.world);
  fmt::print("  {:<6} {:>8} {:>10} {:>10} {:>8}\n", "robot", "scans", "length m", "duration s",
             "sensor");
  std::size_t scans = 0;
  for (const sim::Route& r : preset.routes) {
    fmt::print("  {:<6} {:>8} {:>10.1f} {:>10.1f} {:>8}\n", r.name, r.T_world_sensor.size(),
               r.length(), r.duration(), spec.sensor);
    scans += r.T_world_sensor.size();
  }
  fmt::print("  {} robots, {} scans (regenerated on demand); {} on disk in {}\n",
             preset.routes.size(), scans, humanBytes(folderBytes(out)), shown);
}

/// Exports the scans into `out`, which will be `shown`.
void exportScans(const io::DatasetSpec& spec, const std::string& out, const std::string& shown,
                 sim::ExportFormat format) {
  const std::string folder = (fs::path(out) / std::string(sim::toString(format))).string();
  std::unique_ptr<core::ProgressBar> bar;
  const auto start = Clock::now();
  const sim::ExportResult result =
      sim::exportDataset(spec, folder, {.format = format}, [&](std::size_t done, std::size_t n) {
        if (!bar) bar = std::make_unique<core::ProgressBar>("export", n, "scans");
        bar->update(done);
      });
  if (bar) bar->finish();
  fmt::print("exported {} scans ({} points, {}) as {} to {} in {:.1f} s\n", result.scans,
             result.points, humanBytes(result.bytes), sim::toString(format),
             (fs::path(shown) / std::string(sim::toString(format))).string(), secondsSince(start));
}

std::optional<sim::ExportFormat> exportFormat(const std::string& name) {
  if (name.empty()) return std::nullopt;
  const auto format = sim::parseExportFormat(name);
  if (!format) throw core::Error("--export: '" + name + "' is not kitti, bag or mcap");
  return format;
}

/// The first `n` poses of every route (n = 0: all).
void cutRoutes(sim::Preset& preset, std::size_t n) {
  for (sim::Route& route : preset.routes) {
    const core::Trajectory& full = route.T_world_sensor;
    if (n == 0 || full.size() <= n) continue;
    route.T_world_sensor = core::Trajectory(
        {full.stamps().begin(), full.stamps().begin() + static_cast<std::ptrdiff_t>(n)},
        {full.poses().begin(), full.poses().begin() + static_cast<std::ptrdiff_t>(n)});
  }
}

/// Each robot's ground truth as a drifting front-end reports it
/// (odometry/ROBOT.tum), named as the robot's `odometry` in dataset.yaml.
io::DatasetSpec addDriftingOdometry(const std::string& folder, io::DatasetSpec spec,
                                    const SimulateOptions& o) {
  for (std::size_t r = 0; r < spec.robots.size(); ++r) {
    io::RobotSpec& robot = spec.robots[r];
    if (robot.ground_truth.empty()) continue;
    const sim::OdometryDrift drift{.translation_percent = o.odometry_drift[0],
                                   .rotation_deg_per_m = o.odometry_drift[1],
                                   .seed = o.seed * 1000 + r};
    const core::Trajectory reported = sim::driftingOdometry(io::readGroundTruth(spec, r), drift);
    robot.odometry = {.file = "odometry/" + robot.name + ".tum", .format = "tum"};
    io::writeTumPoses((fs::path(folder) / robot.odometry.file).string(), reported);
  }
  io::writeDataset(folder, spec);
  return io::readDataset(folder);
}

void runSimulate(const SimulateOptions& o) {
  const auto format = exportFormat(o.export_format);  // check before the slow part
  sim::Preset preset = sim::makePreset(o.preset, {.data_dir = o.data,
                                                  .seed = o.seed,
                                                  .robots = o.robots,
                                                  .sensor = o.sensor,
                                                  .body_motion = o.body_motion});
  cutRoutes(preset, o.max_scans);
  OutputFolder out(o.out, o.force);
  io::DatasetSpec spec = sim::writeSimDataset(out.path(), preset,
                                              {.motion_distortion = !o.no_motion_distortion,
                                               .noise = !o.no_noise,
                                               .calibration_error = !o.perfect_lasers,
                                               .traffic = o.traffic,
                                               .imu = !o.no_imu});
  if (!o.odometry_drift.empty()) spec = addDriftingOdometry(out.path(), spec, o);
  printSummary(preset, spec, out.path(), out.out());
  if (format) exportScans(spec, out.path(), out.out(), *format);
  out.commit();
}

void runPreview(const std::string& folder) {
  const io::DatasetSpec spec = io::readDataset(folder, datasetReadOptions());
  const sim::SimWorld world(spec);
  const std::string world_png = (fs::path(folder) / "preview_world.png").string();
  const std::string scan_png = (fs::path(folder) / "preview_scan.png").string();
  std::vector<core::Trajectory> routes;
  for (std::size_t r = 0; r < world.robots(); ++r) routes.push_back(world.groundTruth(r));
  sim::writeWorldPreview(world.world(), routes, world_png, {}, &world.simulator().traffic());
  const core::Trajectory& gt = world.groundTruth(0);
  const std::size_t middle = gt.size() / 2;
  sim::writeScanPreview(world.scan(0, middle), scan_png);
  const sim::Traffic& traffic = world.simulator().traffic();
  fmt::print("wrote {} ({} triangles, {} routes{}) and {} (robot {} scan {})\n", world_png,
             world.world().triangleCount(), routes.size(),
             traffic.empty() ? std::string()
                             : fmt::format(", {} cars, {} cyclists, {} pedestrians, {} parked "
                                           "for a while",
                                           traffic.count(sim::ActorKind::car),
                                           traffic.count(sim::ActorKind::cyclist),
                                           traffic.count(sim::ActorKind::pedestrian),
                                           traffic.count(sim::ActorKind::parked_car)),
             scan_png, spec.robots[0].name, middle);
}

void runSimulateCommand(const SimulateOptions& o) {
  if (!o.preview.empty()) {
    if (!o.preset.empty()) throw core::Error("--preview draws an existing dataset: drop --preset");
    return runPreview(o.preview);
  }
  if (o.preset.empty() || o.out.empty()) {
    throw core::Error("simulate needs --preset NAME and --out DIR (or --preview DIR); presets: " +
                      fmt::format("{}", fmt::join(sim::presetNames(), ", ")));
  }
  runSimulate(o);
}

// ---- bench sim ----

/// One scan to generate: robot and index.
struct ScanJob {
  std::size_t robot;
  std::size_t index;
};

std::vector<ScanJob> scanJobs(const sim::SimWorld& world, const std::vector<std::size_t>& robots) {
  std::vector<ScanJob> jobs;
  for (std::size_t r : robots) {
    for (std::size_t i = 0; i < world.groundTruth(r).size(); ++i) jobs.push_back({r, i});
  }
  return jobs;
}

/// Generates every job on `threads` threads; returns the total number of points.
std::size_t generateAll(const sim::SimWorld& world, const std::vector<ScanJob>& jobs,
                        unsigned threads) {
  std::atomic<std::size_t> next{0}, done{0}, points{0};
  std::vector<std::thread> workers;
  for (unsigned t = 0; t < threads; ++t) {
    workers.emplace_back([&] {
      for (std::size_t j = next++; j < jobs.size(); j = next++) {
        points += world.scan(jobs[j].robot, jobs[j].index).size();
        ++done;
      }
    });
  }
  core::ProgressBar bar("scans", jobs.size(), "scans");
  while (done < jobs.size()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    bar.update(done);
  }
  for (auto& w : workers) w.join();
  bar.finish();
  return points;
}

std::vector<std::size_t> benchRobots(const io::DatasetSpec& spec, const std::string& name) {
  std::vector<std::size_t> robots;
  if (name.empty()) {
    for (std::size_t r = 0; r < spec.robots.size(); ++r) robots.push_back(r);
    return robots;
  }
  const auto index = spec.robotIndex(name);
  if (!index) throw core::Error("--robot: dataset '" + spec.name + "' has no robot '" + name + "'");
  return {*index};
}

void runBenchSim(const BenchSimOptions& o) {
  if (o.threads == 0) throw core::Error("--threads must be at least 1");
  const io::DatasetSpec spec = io::readDataset(o.dataset, datasetReadOptions());
  const auto robots = benchRobots(spec, o.robot);
  auto start = Clock::now();
  // One scan per thread, each cast (what is timed), never read from a scan cache.
  const sim::SimWorld world(spec, {.parallel = false, .scan_cache = false});
  const double build_s = secondsSince(start);
  const auto jobs = scanJobs(world, robots);
  start = Clock::now();
  const std::size_t points = generateAll(world, jobs, o.threads);
  const double scan_s = secondsSince(start);
  const double rate = jobs.size() / scan_s;
  // Real time: every robot's sensor delivers rate_hz scans a second, all at once.
  const double realtime = rate / (world.simulator().model().rate_hz * robots.size());
  Json j = {{"dataset", spec.name},
            {"sensor", spec.sensor},
            {"robots", robots.size()},
            {"threads", o.threads},
            {"scans", jobs.size()},
            {"points", points},
            {"world_triangles", world.world().triangleCount()},
            {"world_build_s", build_s},
            {"scan_s", scan_s},
            {"scans_per_s", rate},
            {"ms_per_scan_per_thread", 1e3 * scan_s * o.threads / jobs.size()},
            {"realtime_factor", realtime}};
  if (o.json) return fmt::print("{}\n", j.dump(2));
  fmt::print("bench sim '{}': {} robots, {} {} scans, {} points, {} threads\n", spec.name,
             robots.size(), jobs.size(), spec.sensor, points, o.threads);
  fmt::print("  world: {} triangles built in {:.2f} s\n", world.world().triangleCount(), build_s);
  fmt::print("  scans: {:.2f} s, {:.1f} scans/s ({:.2f} ms a scan a thread), {:.2f}x real time\n",
             scan_s, rate, 1e3 * scan_s * o.threads / jobs.size(), realtime);
}

}  // namespace

void addSimulateCommand(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("simulate", "make a simulated dataset from a preset, or preview one");
  auto o = std::make_shared<SimulateOptions>();
  o->data = defaultDataDir();
  const std::string names = fmt::format("{}", fmt::join(sim::presetNames(), ", "));
  cmd->add_option("--preset", o->preset, "preset: " + names);
  cmd->add_option("--out", o->out, "dataset folder to write (dataset.yaml + ground truth)");
  cmd->add_option("--preview", o->preview,
                  "draw the dataset folder DIR: DIR/preview_world.png and DIR/preview_scan.png");
  cmd->add_option("--seed", o->seed, "seeds world, routes and sensor noise")->capture_default_str();
  cmd->add_option("--robots", o->robots, "number of robots (0: the preset's)")
      ->capture_default_str();
  cmd->add_option("--sensor", o->sensor, "hdl64 or vlp16 (default: the preset's)");
  cmd->add_option("--export", o->export_format,
                  "also write the scans: kitti (.bin), bag (ROS1) or mcap (ROS 2)");
  cmd->add_option("--data", o->data,
                  "the shared data folder with KITTI ground truth (or DCL_DATA_DIR)")
      ->capture_default_str();
  cmd->add_option("--max-scans", o->max_scans, "cut every robot's route to N scans (0: all)")
      ->capture_default_str();
  cmd->add_flag("--no-motion-distortion", o->no_motion_distortion,
                "scans as if the sensor stood still during each sweep");
  cmd->add_flag("--no-noise", o->no_noise,
                "scans without range noise, dropout and calibration error");
  cmd->add_flag("--perfect-lasers", o->perfect_lasers,
                "every robot's lasers exactly where the published beam table says (no "
                "calibration error)");
  cmd->add_flag("--no-imu", o->no_imu,
                "no IMU reading of up with the scans: the robots LiDAR only");
  cmd->add_option("--odometry-drift", o->odometry_drift,
                  "PERCENT,DEG_PER_M: also give each robot an external front-end, its ground truth "
                  "drifting by PERCENT % of the distance and DEG_PER_M deg per metre "
                  "(odometry/ROBOT.tum, dataset.yaml's odometry), e.g. 1,0.01")
      ->delimiter(',')
      ->expected(2)
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--traffic", o->traffic,
                  "moving cars, cyclists and pedestrians, and cars parked for a while: this "
                  "times the world's own traffic (1: a KITTI-like city street; 0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, io::kMaxTraffic));
  cmd->add_flag("--body-motion", o->body_motion,
                "the vehicles of generated routes rock on their suspension as a car does: pitch "
                "on braking, roll in turns, the road's shake (KITTI's routes rock already)");
  addForceFlag(*cmd, o->force);
  cmd->callback([o] { runSimulateCommand(*o); });
}

void addBenchSimCommand(CLI::App& bench) {
  auto* cmd = bench.add_subcommand("sim", "generate a dataset's whole scan stream and time it");
  auto o = std::make_shared<BenchSimOptions>();
  cmd->add_option("--dataset", o->dataset, "simulated dataset folder")->required();
  cmd->add_option("--robot", o->robot, "only this robot (default: all)");
  cmd->add_option("--threads", o->threads, "worker threads, one scan each")->capture_default_str();
  cmd->add_flag("--json", o->json, "print the result as JSON");
  cmd->callback([o] { runBenchSim(*o); });
}

}  // namespace dcl::apps
