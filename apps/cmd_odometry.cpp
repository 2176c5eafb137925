// `dcl-slam odometry`: one robot's front-end alone (built-in LiDAR odometry or
// external odometry, keyframes, intra-robot loops), and `dcl-slam bench odometry`.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/eval/rpe.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/pose_graph_g2o.hpp>
#include <dcl/odometry/external_odometry.hpp>
#include <dcl/odometry/lidar_odometry.hpp>
#include <dcl/odometry/local_mapper.hpp>
#include <dcl/sim/sim_source.hpp>

#include "commands.hpp"
#include "front_end.hpp"
#include "option_checks.hpp"
#include "output_folder.hpp"
#include "printing.hpp"

namespace dcl::apps {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

struct OdometryOptions {
  std::string dataset;                   ///< dataset folder
  std::string robot;                     ///< robot name (default: the first)
  std::string out = "out/odometry";      ///< output folder
  std::string external;                  ///< pose file or bag of an external front-end
  std::string external_format = "auto";  ///< tum | kitti | bag | auto
  std::string external_topic;            ///< bag topic of the external front-end
  std::string external_times;            ///< kitti: times file
  bool no_loops = false;                 ///< switch the intra-robot loop closure off
  std::size_t max_frames = 0;            ///< 0: all frames
  std::size_t threads = 0;               ///< 0: all cores
  bool force = false;                    ///< replace --out even when it holds other files
};

/// One robot of a dataset: its scans and, when the dataset has it, its ground truth.
struct RobotData {
  io::DatasetSpec spec;
  std::size_t index = 0;
  std::unique_ptr<io::ScanSource> scans;
  std::optional<core::Trajectory> ground_truth;
};

RobotData openRobot(const std::string& dataset, const std::string& robot) {
  RobotData data{io::readDataset(dataset, datasetReadOptions()), 0, nullptr, std::nullopt};
  if (!robot.empty()) {
    const auto index = data.spec.robotIndex(robot);
    if (!index) throw core::Error("dataset '" + dataset + "' has no robot '" + robot + "'");
    data.index = *index;
  }
  data.scans = sim::openRobotScans(data.spec, data.index);
  if (!data.spec.robots[data.index].ground_truth.empty()) {
    data.ground_truth = io::readGroundTruth(data.spec, data.index);
  }
  return data;
}

/// The first and last stamp of the first `frames` scans.
std::pair<double, double> frameTimes(const io::ScanSource& scans, std::size_t frames) {
  double first = scans.stamp(0), last = first;
  for (std::size_t i = 1; i < frames; ++i) {
    first = std::min(first, scans.stamp(i));
    last = std::max(last, scans.stamp(i));
  }
  return {first, last};
}

/// The odometry of the run: --external's, else the dataset's front-end for the
/// robot, else the built-in one; an external one must cover some of the frames' times.
std::unique_ptr<odometry::Odometry> makeOdometry(const OdometryOptions& o, const AppConfig& config,
                                                 const RobotData& data, std::size_t frames) {
  const io::ScanSource& scans = *data.scans;
  if (o.external.empty()) {
    if (auto front_end = datasetFrontEnd(data.spec, data.index, scans, frames, config.external))
      return front_end;
    return std::make_unique<odometry::LidarOdometry>(config.odometry);
  }
  odometry::ExternalOdometryConfig external = config.external;
  external.file = o.external;
  external.format = o.external_format;
  external.topic = o.external_topic;
  external.times = o.external_times;
  auto odometry =
      std::make_unique<odometry::ExternalOdometry>(readExternalPoses(external), external);
  if (frames > 0) {
    const auto [first, last] = frameTimes(scans, frames);
    odometry->requireOverlap(first, last);
  }
  return odometry;
}

/// What happened to every frame.
struct FrameLog {
  core::Trajectory poses;                                      ///< T_odom_sensor of every frame
  std::vector<odometry::FrameHealth> health;                   ///< per frame
  std::vector<double> milliseconds;                            ///< odometry time per frame
  std::vector<std::optional<core::KeyframeId>> last_keyframe;  ///< latest keyframe at each frame
};

/// The translation error of `T_odom_sensor` against the ground truth re-expressed
/// from its first pose, per metre travelled (a running drift estimate).
std::optional<double> driftPercent(const std::optional<core::Trajectory>& gt, double stamp,
                                   const Eigen::Isometry3d& T_odom_sensor, double distance) {
  if (!gt || gt->empty() || distance < 10.0) return std::nullopt;
  const auto T_world_sensor = gt->at(stamp);
  if (!T_world_sensor) return std::nullopt;
  const Eigen::Isometry3d T_odom_gt = gt->pose(0).inverse() * *T_world_sensor;
  return 100.0 * (T_odom_gt.translation() - T_odom_sensor.translation()).norm() / distance;
}

std::string progressNote(const FrameLog& log, const std::optional<core::Trajectory>& gt,
                         const odometry::LocalMapper& mapper) {
  const std::size_t n = log.poses.size();
  const double distance = log.poses.length();
  std::string note = fmt::format("{:.0f} m, {} keyframes, {} loops", distance,
                                 mapper.keyframes().size(), mapper.loops().size());
  const auto drift = driftPercent(gt, log.poses.stamp(n - 1), log.poses.pose(n - 1), distance);
  if (drift) note += fmt::format(", drift {:.2f} %", *drift);
  return note;
}

FrameLog runFrames(const RobotData& data, odometry::Odometry& odometry,
                   odometry::LocalMapper& mapper, std::size_t frames) {
  FrameLog log;
  core::ProgressBar progress("odometry", frames, "frames");
  std::optional<core::KeyframeId> keyframe;
  for (std::size_t i = 0; i < frames; ++i) {
    const core::PointCloud scan = data.scans->scan(i);
    if (const auto up = data.scans->up(i)) odometry.observeUp(*up);
    const auto start = Clock::now();
    const odometry::OdometryResult result = odometry.process(data.scans->stamp(i), scan);
    log.milliseconds.push_back(
        std::chrono::duration<double, std::milli>(Clock::now() - start).count());
    const odometry::MapperUpdate update =
        result.registered.empty() ? mapper.process(result, scan) : mapper.process(result);
    if (update.keyframe) keyframe = update.keyframe;
    log.poses.push_back(result.stamp, result.T_odom_sensor);
    log.health.push_back(result.health);
    log.last_keyframe.push_back(keyframe);
    progress.update(i + 1, progressNote(log, data.ground_truth, mapper));
  }
  progress.finish();
  return log;
}

/// Every frame's pose moved with its latest keyframe's correction by the local
/// pose graph: T = T_smoothed(k) T_odom(k)^-1 T_odom(frame).
core::Trajectory smoothedFrames(const FrameLog& log, const odometry::LocalMapper& mapper) {
  core::Trajectory out;
  const auto& keyframes = mapper.keyframes();
  const auto& smoothed = mapper.smoothedPoses();
  for (std::size_t i = 0; i < log.poses.size(); ++i) {
    Eigen::Isometry3d T = log.poses.pose(i);
    if (const auto k = log.last_keyframe[i]) {
      const auto index = static_cast<std::size_t>(k->value());
      T = smoothed[index] * keyframes[index].T_odom_keyframe.inverse() * T;
    }
    out.push_back(log.poses.stamp(i), T);
  }
  return out;
}

Json statisticsJson(const eval::Statistics& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std},
          {"min", s.min},   {"max", s.max},   {"count", s.count}};
}

/// ATE (SE(3)-aligned) and the KITTI metric of `estimate` against the ground
/// truth; {"unavailable": why} when they cannot be computed (a robot that has
/// not moved yet cannot be aligned), which leaves the outputs to be written.
Json accuracyJson(const core::Trajectory& estimate, const core::Trajectory& gt) {
  const eval::Association pairs = eval::associateByTimestamp(estimate, gt, 0.01);
  eval::AteResult ate;
  try {
    ate = eval::computeAte(pairs, eval::Alignment::se3);
  } catch (const core::Error& e) {
    return {{"unavailable", e.what()}};
  }
  const auto kitti = eval::computeKittiMetric(pairs);
  Json j = {{"ate_se3_translation_m", statisticsJson(ate.translation_m)},
            {"ate_se3_rotation_deg", statisticsJson(ate.rotation_deg)}};
  if (kitti) {
    j["kitti_translation_percent"] = kitti->translation_percent;
    j["kitti_rotation_deg_per_m"] = kitti->rotation_deg_per_m;
    j["kitti_segments"] = kitti->segments;
  }
  return j;
}

Json framesJson(const FrameLog& log) {
  std::size_t accepted = 0, degenerate = 0, converged = 0, sharp = 0;
  Json problems = Json::object();
  for (const auto& h : log.health) {
    accepted += h.accepted;
    degenerate += h.degenerate;
    converged += h.converged;
    sharp += h.sharp_motion;
    if (!h.problem.empty()) problems[h.problem] = problems.value(h.problem, 0) + 1;
  }
  const eval::Statistics ms = eval::computeStatistics(log.milliseconds);
  return {{"frames", log.health.size()},
          {"accepted", accepted},
          {"converged", converged},
          {"degenerate", degenerate},
          {"sharp_motion", sharp},
          {"problems", problems},
          {"ms_per_frame", statisticsJson(ms)},
          {"frames_per_second", ms.mean > 0 ? 1000.0 / ms.mean : 0.0},
          {"distance_m", log.poses.length()}};
}

Json mapperJson(const odometry::LocalMapper& mapper) {
  const auto& stats = mapper.loopStats();
  return {{"keyframes", mapper.keyframes().size()},
          {"loops", mapper.loops().size()},
          {"loop_queries", stats.queries},
          {"loop_candidates", stats.candidates},
          {"loop_rejected", stats.rejected}};
}

void writeKeyframes(const std::string& folder, const odometry::LocalMapper& mapper) {
  core::Trajectory poses;
  for (std::size_t k = 0; k < mapper.keyframes().size(); ++k) {
    const core::Keyframe& keyframe = mapper.keyframes()[k];
    poses.push_back(keyframe.stamp, mapper.smoothedPoses()[k]);
    if (!keyframe.cloud.empty()) {
      io::writeKittiScan(fmt::format("{}/{:06}.bin", folder, k), keyframe.cloud);
    }
  }
  io::writeTumPoses(folder + "/poses.tum", poses);
  io::writePoseGraph(folder + "/graph.g2o", mapper.graph());
}

void writeOutputs(const OdometryOptions& o, const FrameLog& log,
                  const odometry::LocalMapper& mapper, const Json& metrics) {
  const core::Trajectory smoothed = smoothedFrames(log, mapper);
  io::writeTumPoses(o.out + "/odometry.tum", log.poses);
  io::writeTumPoses(o.out + "/trajectory.tum", smoothed);
  io::writeKittiPoses(o.out + "/trajectory.kitti", smoothed, o.out + "/times.txt");
  writeKeyframes(o.out + "/keyframes", mapper);
  io::writeFileAtomic(o.out + "/metrics.json",
                      [&](std::ostream& s) { s << metrics.dump(2) << "\n"; });
}

void printOdometrySummary(const Json& m) {
  const Json& f = m["frames"];
  fmt::print(
      "{} frames ({} accepted, {} degenerate, {} with a sharp change of motion), {:.1f} m, {:.1f} "
      "ms a frame "
      "({:.0f} Hz)\n",
      f["frames"].get<std::size_t>(), f["accepted"].get<std::size_t>(),
      f["degenerate"].get<std::size_t>(), f["sharp_motion"].get<std::size_t>(),
      f["distance_m"].get<double>(), f["ms_per_frame"]["mean"].get<double>(),
      f["frames_per_second"].get<double>());
  fmt::print("{} keyframes, {} intra-robot loops ({} candidates rejected)\n",
             m["mapper"]["keyframes"].get<std::size_t>(), m["mapper"]["loops"].get<std::size_t>(),
             m["mapper"]["loop_rejected"].get<std::size_t>());
  if (!m.contains("accuracy")) return;
  for (const char* which : {"odometry", "smoothed"}) {
    const Json& a = m["accuracy"][which];
    if (a.contains("unavailable")) {
      fmt::print("{:>9}: no ATE: {}\n", which, a["unavailable"].get<std::string>());
      continue;
    }
    fmt::print("{:>9}: ATE {:.3f} m", which, a["ate_se3_translation_m"]["rmse"].get<double>());
    if (a.contains("kitti_translation_percent")) {
      fmt::print(", KITTI {:.3f} % {:.5f} deg/m", a["kitti_translation_percent"].get<double>(),
                 a["kitti_rotation_deg_per_m"].get<double>());
    }
    fmt::print("\n");
  }
}

void runOdometry(const OdometryOptions& o, const AppConfig& config) {
  OutputFolder out(o.out, o.force);
  out.requireOutside(o.dataset, "the dataset");
  if (!o.external.empty()) out.requireOutside(o.external, "--external");
  const RobotData data = openRobot(o.dataset, o.robot);
  const std::size_t threads = o.threads > 0 ? o.threads : tbb::info::default_concurrency();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  const std::size_t frames =
      o.max_frames > 0 ? std::min(o.max_frames, data.scans->size()) : data.scans->size();
  auto odometry = makeOdometry(o, config, data, frames);
  odometry::LocalMapperConfig mapper_config = config.mapper;
  mapper_config.loop_closure = mapper_config.loop_closure && !o.no_loops;
  odometry::LocalMapper mapper(core::RobotId(static_cast<std::uint8_t>(data.index)), mapper_config);
  fmt::print("robot {} of '{}': {} frames, {} odometry, {} threads\n",
             data.spec.robots[data.index].name, data.spec.name, frames, odometry->name(), threads);
  const FrameLog log = runFrames(data, *odometry, mapper, frames);
  Json metrics = {{"dataset", data.spec.name},
                  {"robot", data.spec.robots[data.index].name},
                  {"odometry", odometry->name()},
                  {"frames", framesJson(log)},
                  {"mapper", mapperJson(mapper)}};
  if (data.ground_truth) {
    metrics["accuracy"] = {
        {"odometry", accuracyJson(log.poses, *data.ground_truth)},
        {"smoothed", accuracyJson(smoothedFrames(log, mapper), *data.ground_truth)}};
  }
  OdometryOptions staged = o;
  staged.out = out.path();
  writeOutputs(staged, log, mapper, metrics);
  out.commit();
  printOdometrySummary(metrics);
  fmt::print("wrote {}/{{trajectory.tum,trajectory.kitti,odometry.tum,keyframes/,metrics.json}}\n",
             o.out);
}

/// The built-in odometry alone over a whole sequence; scan generation is not timed.
void runBenchOdometry(const OdometryOptions& o, bool json, const AppConfig& config) {
  const RobotData data = openRobot(o.dataset, o.robot);
  const std::size_t threads = o.threads > 0 ? o.threads : 1;
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  odometry::LidarOdometry odometry(config.odometry);
  const std::size_t frames =
      o.max_frames > 0 ? std::min(o.max_frames, data.scans->size()) : data.scans->size();
  FrameLog log;
  core::ProgressBar progress("bench odometry", frames, "frames");
  std::size_t levelled = 0;  // frames whose IMU reading the odometry used
  for (std::size_t i = 0; i < frames; ++i) {
    const core::PointCloud scan = data.scans->scan(i);
    if (const auto up = data.scans->up(i)) {
      odometry.observeUp(*up);
      if (config.odometry.use_imu) ++levelled;
    }
    const auto start = Clock::now();
    const auto result = odometry.process(data.scans->stamp(i), scan);
    log.milliseconds.push_back(
        std::chrono::duration<double, std::milli>(Clock::now() - start).count());
    log.poses.push_back(result.stamp, result.T_odom_sensor);
    log.health.push_back(result.health);
    progress.update(i + 1);
  }
  progress.finish();
  Json metrics = {{"dataset", data.spec.name},     {"robot", data.spec.robots[data.index].name},
                  {"sensor", data.spec.sensor},    {"threads", threads},
                  {"imu_readings_used", levelled}, {"frames", framesJson(log)}};
  if (data.ground_truth) metrics["accuracy"] = accuracyJson(log.poses, *data.ground_truth);
  if (json) return fmt::print("{}\n", metrics.dump(2));
  const Json& f = metrics["frames"];
  fmt::print(
      "bench odometry '{}' robot {} ({}), {} threads: {} frames, {:.2f} ms a frame "
      "(median {:.2f}, max {:.2f}), {:.0f} Hz, {}\n",
      data.spec.name, data.spec.robots[data.index].name, data.spec.sensor, threads, frames,
      f["ms_per_frame"]["mean"].get<double>(), f["ms_per_frame"]["median"].get<double>(),
      f["ms_per_frame"]["max"].get<double>(), f["frames_per_second"].get<double>(),
      levelled > 0 ? fmt::format("levelled with the IMU at {} frames", levelled)
                   : std::string("LiDAR only"));
  if (metrics.contains("accuracy") && metrics["accuracy"].contains("kitti_translation_percent")) {
    fmt::print("  drift: KITTI {:.3f} % {:.5f} deg/m, ATE {:.3f} m\n",
               metrics["accuracy"]["kitti_translation_percent"].get<double>(),
               metrics["accuracy"]["kitti_rotation_deg_per_m"].get<double>(),
               metrics["accuracy"]["ate_se3_translation_m"]["rmse"].get<double>());
  }
}

void addRobotOptions(CLI::App& cmd, OdometryOptions& o) {
  cmd.add_option("--dataset", o.dataset, "dataset folder (dataset.yaml)")->required();
  cmd.add_option("--robot", o.robot, "robot name (default: the first)");
  cmd.add_option("--max-frames", o.max_frames, "stop after N frames (0: all)")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd.add_option("--threads", o.threads, "threads for the odometry (0: all cores)")
      ->capture_default_str();
}

}  // namespace

void addBenchOdometryCommand(CLI::App& bench, const AppConfig& config) {
  auto* cmd = bench.add_subcommand(
      "odometry", "time the built-in LiDAR odometry over a whole sequence (generation not timed)");
  auto o = std::make_shared<OdometryOptions>();
  o->threads = 1;
  addRobotOptions(*cmd, *o);
  auto json = std::make_shared<bool>(false);
  cmd->add_flag("--json", *json, "print the result as JSON");
  cmd->callback([o, json, &config] { runBenchOdometry(*o, *json, config); });
}

void addOdometryCommand(CLI::App& app, const AppConfig& config) {
  auto* cmd = app.add_subcommand("odometry", "run one robot's front-end alone");
  auto o = std::make_shared<OdometryOptions>();
  addRobotOptions(*cmd, *o);
  cmd->add_option("--out", o->out, "output folder")->capture_default_str();
  cmd->add_option(
      "--external", o->external,
      "poses of an external front-end (TUM, KITTI, ROS1 bag or ROS 2 MCAP) instead of the "
      "built-in LiDAR odometry");
  cmd->add_option("--external-format", o->external_format, "tum, kitti, bag, mcap or auto")
      ->capture_default_str();
  cmd->add_option("--external-topic", o->external_topic,
                  "bag topic (nav_msgs/Odometry, PoseStamped)");
  cmd->add_option("--external-times", o->external_times, "times file of a KITTI pose file");
  cmd->add_flag("--no-loops", o->no_loops, "no intra-robot loop closure");
  addForceFlag(*cmd, o->force);
  cmd->callback([o, &config] { runOdometry(*o, config); });
}

}  // namespace dcl::apps
