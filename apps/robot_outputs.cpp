#include "robot_outputs.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

namespace dcl::apps {
namespace {

using Json = nlohmann::ordered_json;

constexpr const char* kReportFile = "robot.json";

Json keyJson(const core::PoseKey& key) {
  return {{"robot", key.robot.value()}, {"keyframe", key.keyframe.value()}};
}

/// robot.json's field `key` of `object` as a T; a missing field or one of
/// the wrong type is named with the file.
template <class T>
T field(const Json& object, const char* key, const std::string& path) {
  if (!object.is_object() || !object.contains(key))
    throw core::FileError({.path = path, .field = key}, "missing");
  try {
    return object.at(key).get<T>();
  } catch (const std::exception& e) {
    throw core::FileError({.path = path, .field = key},
                          std::string("wrong type or value: ") + e.what());
  }
}

core::PoseKey keyOf(const Json& loop, const char* end, const std::string& path) {
  const Json key = field<Json>(loop, end, path);
  const auto robot = field<std::uint8_t>(key, "robot", path);
  const auto keyframe = field<std::uint64_t>(key, "keyframe", path);
  return {core::RobotId(robot), core::KeyframeId(keyframe)};
}

std::vector<RobotReport::Loop> loopsOf(const Json& list, const std::string& path) {
  if (!list.is_array()) throw core::FileError({.path = path, .field = "inter_loops"}, "not a list");
  std::vector<RobotReport::Loop> loops;
  for (const Json& loop : list)
    loops.push_back(
        {keyOf(loop, "from", path), keyOf(loop, "to", path), field<bool>(loop, "accepted", path)});
  return loops;
}

RobotReport reportOf(const Json& j, const std::string& path) {
  RobotReport r;
  r.name = field<std::string>(j, "name", path);
  r.robot = field<std::uint8_t>(j, "robot", path);
  r.dataset = field<std::string>(j, "dataset", path);
  r.transport = field<std::string>(j, "transport", path);
  r.swarm = field<std::string>(j, "swarm", path);
  r.incarnation = field<std::uint32_t>(j, "incarnation", path);
  r.rate = field<double>(j, "rate", path);
  r.epoch = field<double>(j, "epoch", path);
  r.frames = field<std::size_t>(j, "frames", path);
  r.frames_planned = field<std::size_t>(j, "frames_planned", path);
  r.keyframes = field<std::size_t>(j, "keyframes", path);
  r.max_lag = field<double>(j, "max_lag_s", path);
  r.wall_time = field<double>(j, "wall_time_s", path);
  r.duration = field<double>(j, "duration_s", path);
  r.interrupted = field<bool>(j, "interrupted", path);
  r.bytes_sent = field<std::size_t>(j, "bytes_sent", path);
  r.bytes_received = field<std::size_t>(j, "bytes_received", path);
  r.transmit_kBps = field<double>(j, "transmit_kBps", path);
  r.receive_kBps = field<double>(j, "receive_kBps", path);
  r.failed_writes = field<std::size_t>(j, "failed_writes", path);
  r.meter_interval = field<double>(j, "meter_interval_s", path);
  r.sent_over_time =
      field<std::map<std::string, std::vector<std::size_t>>>(j, "sent_over_time", path);
  r.counters = field<std::map<std::string, double>>(j, "counters", path);
  r.inter_loops = loopsOf(field<Json>(j, "inter_loops", path), path);
  r.messenger = field<Json>(j, "messenger", path);
  if (const Json frame = field<Json>(j, "frame", path); !frame.is_null())
    r.frame = field<std::uint8_t>(j, "frame", path);
  if (!(r.meter_interval > 0.0))
    throw core::FileError({.path = path, .field = "meter_interval_s"}, "must be positive");
  return r;
}

template <std::size_t N, class Name>
Json named(const std::array<std::size_t, N>& counts, Name name) {
  Json j = Json::object();
  for (std::size_t k = 0; k < N; ++k) j[std::string(name(k))] = counts[k];
  return j;
}

}  // namespace

Json toJson(const RobotReport& r) {
  Json loops = Json::array();
  for (const RobotReport::Loop& loop : r.inter_loops)
    loops.push_back(
        {{"from", keyJson(loop.from)}, {"to", keyJson(loop.to)}, {"accepted", loop.accepted}});
  return {{"name", r.name},
          {"robot", r.robot},
          {"dataset", r.dataset},
          {"transport", r.transport},
          {"swarm", r.swarm},
          {"incarnation", r.incarnation},
          {"rate", r.rate},
          {"epoch", r.epoch},
          {"frames", r.frames},
          {"frames_planned", r.frames_planned},
          {"keyframes", r.keyframes},
          {"max_lag_s", r.max_lag},
          {"wall_time_s", r.wall_time},
          {"duration_s", r.duration},
          {"interrupted", r.interrupted},
          {"bytes_sent", r.bytes_sent},
          {"bytes_received", r.bytes_received},
          {"transmit_kBps", r.transmit_kBps},
          {"receive_kBps", r.receive_kBps},
          {"failed_writes", r.failed_writes},
          {"meter_interval_s", r.meter_interval},
          {"sent_over_time", r.sent_over_time},
          {"counters", r.counters},
          {"inter_loops", loops},
          {"frame", r.frame ? Json(*r.frame) : Json(nullptr)},
          {"messenger", r.messenger}};
}

Json messengerJson(const comm::MessengerStats& s) {
  const auto kind = [](std::size_t k) { return comm::name(static_cast<comm::MessageKind>(k)); };
  const auto reason = [](std::size_t k) { return comm::name(static_cast<comm::DropReason>(k)); };
  return {
      {"sent", named(s.sent, kind)},           {"sent_bytes", named(s.sent_bytes, kind)},
      {"resent", named(s.resent, kind)},       {"resent_bytes", named(s.resent_bytes, kind)},
      {"delivered", named(s.delivered, kind)}, {"received_bytes", named(s.received_bytes, kind)},
      {"dropped", named(s.dropped, reason)}};
}

void writeRobotOutputs(const std::string& folder, const RobotOutputs& o) {
  std::filesystem::create_directories(folder);
  io::writeTumPoses(folder + "/trajectory.tum", o.estimate);
  io::writeKittiPoses(folder + "/trajectory.kitti", o.estimate, folder + "/times.txt");
  io::writeTumPoses(folder + "/odometry.tum", o.odometry);
  io::writePoseGraph(folder + "/graph.g2o", o.graph);
  const Json report = toJson(o.report);
  io::writeFileAtomic(folder + "/" + kReportFile,
                      [&](std::ostream& out) { out << report.dump(2) << "\n"; });
}

RobotOutputs readRobotOutputs(const std::string& folder) {
  const std::string path = folder + "/" + kReportFile;
  const std::vector<char> text = io::readFile(path);
  const Json j = Json::parse(text.begin(), text.end(), nullptr, false);
  if (j.is_discarded() || !j.is_object())
    throw core::FileError({.path = path}, "not a JSON object");
  RobotOutputs o;
  o.report = reportOf(j, path);
  if (o.report.keyframes == 0) return o;  // the pose files have no line to read
  o.estimate = io::readTumPoses(folder + "/trajectory.tum");
  o.odometry = io::readTumPoses(folder + "/odometry.tum");
  o.graph = io::readPoseGraph(folder + "/graph.g2o");
  if (o.estimate.size() != o.report.keyframes || o.odometry.size() != o.report.keyframes)
    throw core::FileError({.path = folder + "/trajectory.tum"},
                          "holds " + std::to_string(o.estimate.size()) + " poses, odometry.tum " +
                              std::to_string(o.odometry.size()) + ", but robot.json says " +
                              std::to_string(o.report.keyframes) + " keyframes");
  return o;
}

std::uint32_t clockIncarnation() {
  using Tenths = std::chrono::duration<std::int64_t, std::deci>;
  const std::chrono::sys_days epoch{std::chrono::year{2024} / 1 / 1};
  const std::int64_t tenths =
      std::chrono::duration_cast<Tenths>(std::chrono::system_clock::now() - epoch).count();
  if (tenths < 1 || tenths > std::numeric_limits<std::uint32_t>::max())
    throw core::Error(
        "the system clock is outside 2024-01-01..2037-08: cannot derive an incarnation from it");
  return static_cast<std::uint32_t>(tenths);
}

void printFrames(const nlohmann::ordered_json& metrics) {
  std::map<std::string, std::vector<std::string>> frames;
  for (const Json& r : metrics.at("robots"))
    frames[r.value("frame", std::string())].push_back(r.at("name").get<std::string>());
  if (frames.size() < 2) return;
  std::vector<std::string> groups;
  for (const auto& [frame, names] : frames)
    groups.push_back(fmt::format("{}", fmt::join(names, " ")));
  fmt::print("the robots end in {} frames no loop joins: {} (a merged map per frame)\n",
             frames.size(), fmt::join(groups, " | "));
}

nlohmann::ordered_json robotMetricsJson(const eval::RobotRun& run, const eval::RobotMetrics& m) {
  const auto optional = [](const std::optional<double>& value) {
    return value ? nlohmann::ordered_json(*value) : nlohmann::ordered_json(nullptr);
  };
  return {{"name", run.name},
          {"frames", run.frames},
          {"keyframes", run.keyframes},
          {"ate_rmse", optional(m.ate_rmse)},
          {"ate_rmse_odometry_only", optional(m.ate_rmse_odometry_only)},
          {"ate_rmse_joint", optional(m.ate_rmse_joint)},
          {"frame", run.frame},
          {"are_rmse_deg", optional(m.are_rmse_deg)},
          {"are_rmse_deg_odometry_only", optional(m.are_rmse_deg_odometry_only)},
          {"bytes_sent", run.bytes_sent},
          {"bytes_received", run.bytes_received},
          {"transmit_kBps", m.transmit_kBps},
          {"receive_kBps", m.receive_kBps},
          {"intra_loops", run.intra_loops},
          {"inter_loops_accepted", run.inter_loops_accepted},
          {"inter_loops_rejected", run.inter_loops_rejected},
          {"inter_loops_accepted_wrong",
           run.inter_loops_accepted_wrong ? nlohmann::ordered_json(*run.inter_loops_accepted_wrong)
                                          : nlohmann::ordered_json(nullptr)}};
}

}  // namespace dcl::apps
