#include "live_view.hpp"

#include <Eigen/Geometry>
#include <cstring>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/base64.hpp>
#include <dcl/odometry/preprocessing.hpp>

namespace dcl::apps {
namespace {

using JsonMessage = nlohmann::json;  // messages: key order does not matter

constexpr auto kPeriod = std::chrono::milliseconds(250);
constexpr auto kLoopsPeriod = std::chrono::seconds(1);  ///< the loops need the graph copied
constexpr auto kMapPeriod = std::chrono::seconds(3);    ///< every keyframe's cloud moved
constexpr double kMapVoxel = 0.4;  ///< m, the served map keeps one point per voxel of this edge
constexpr int kChannelsPerRobot = 5;

// The JSON Schemas of what the channels carry (Foxglove draws
// foxglove.PosesInFrame by its name; the schema describes the fields).
constexpr const char* kPosesSchema = R"({"type":"object","properties":{
"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},
"frame_id":{"type":"string"},
"poses":{"type":"array","items":{"type":"object","properties":{
"position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},
"orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}}}}})";
// foxglove.PointCloud and foxglove.SceneUpdate: drawn by their names, their
// fields as Foxglove's schemas define them.
constexpr const char* kObjectSchema = R"({"type":"object"})";
constexpr const char* kCountersSchema = R"({"type":"object","properties":{
"time":{"type":"number"},"frames":{"type":"integer"},"keyframes":{"type":"integer"},
"inter_loops":{"type":"integer"},"bytes_sent":{"type":"integer"}}})";

JsonMessage poseJson(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  return {{"position",
           {{"x", T.translation().x()}, {"y", T.translation().y()}, {"z", T.translation().z()}}},
          {"orientation", {{"x", q.x()}, {"y", q.y()}, {"z", q.z()}, {"w", q.w()}}}};
}

/// A foxglove.PointCloud of packed float x, y, z at `pose` in frame map.
JsonMessage pointCloudJson(const JsonMessage& stamp, const Eigen::Isometry3d& pose,
                           const std::vector<Eigen::Vector3f>& points) {
  static_assert(sizeof(Eigen::Vector3f) == 12, "packed float xyz");
  std::vector<std::uint8_t> data(12 * points.size());
  if (!data.empty()) std::memcpy(data.data(), points.data(), data.size());
  JsonMessage fields = JsonMessage::array();
  for (int axis = 0; axis < 3; ++axis)
    fields.push_back({{"name", std::string(1, static_cast<char>('x' + axis))},
                      {"offset", 4 * axis},
                      {"type", 7}});  // FLOAT32
  return {{"timestamp", stamp}, {"frame_id", "map"}, {"pose", poseJson(pose)},
          {"point_stride", 12}, {"fields", fields},  {"data", core::base64(data)}};
}

/// The robot's map as it now stands: every keyframe's cloud at its current
/// estimate, one point per kMapVoxel voxel.
std::vector<Eigen::Vector3f> mapOf(const robot::RobotNode& node) {
  std::vector<Eigen::Vector3d> all;
  for (const core::Keyframe& k : node.keyframes()) {
    const Eigen::Isometry3d T = node.estimate(k.id);
    for (const Eigen::Vector3f& p : k.cloud.points) all.push_back(T * p.cast<double>());
  }
  std::vector<Eigen::Vector3f> kept;
  for (const Eigen::Vector3d& p : odometry::voxelDownsample(all, kMapVoxel))
    kept.push_back(p.cast<float>());
  return kept;
}

JsonMessage stampOf(double seconds) {
  const auto ns = static_cast<std::int64_t>(std::max(0.0, seconds) * 1e9);
  return {{"sec", ns / 1000000000}, {"nsec", ns % 1000000000}};
}

}  // namespace

std::vector<viz::Channel> LiveView::channels(const std::vector<std::string>& robots) {
  std::vector<viz::Channel> out;
  for (const std::string& r : robots) {
    out.push_back({"/" + r + "/path", "foxglove.PosesInFrame", kPosesSchema});
    out.push_back({"/" + r + "/scan", "foxglove.PointCloud", kObjectSchema});
    out.push_back({"/" + r + "/loops", "foxglove.SceneUpdate", kObjectSchema});
    out.push_back({"/" + r + "/counters", "dcl_slam.Counters", kCountersSchema});
    out.push_back({"/" + r + "/map", "foxglove.PointCloud", kObjectSchema});
  }
  return out;
}

LiveView::LiveView(std::uint16_t port, const std::vector<std::string>& robots, double wait)
    : robots_(robots.size()),
      server_("dcl-slam", port, channels(robots)),
      scans_published_(robots.size(), 0) {
  // On stderr: stdout keeps what --json promises.
  fmt::print(stderr,
             "live view: ws://127.0.0.1:{} (Foxglove or Lichtblick: open a connection, Foxglove "
             "WebSocket)\n",
             server_.port());
  std::fflush(stderr);
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait);
  while (server_.clients() == 0 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

std::size_t LiveView::channel(std::size_t robot, std::size_t kind) {
  return kChannelsPerRobot * robot + kind;
}

bool LiveView::due() const {
  return std::chrono::steady_clock::now() - last_ >= kPeriod;
}

void LiveView::update(const swarm::SwarmStatus& status, bool now) {
  if (!now && !due()) return;
  const auto wall = std::chrono::steady_clock::now();
  const bool loops_due = now || wall - last_loops_ >= kLoopsPeriod;
  const bool map_due = now || wall - last_map_ >= kMapPeriod;
  last_ = wall;
  if (loops_due) last_loops_ = wall;
  if (map_due) last_map_ = wall;
  const auto stamp_ns = static_cast<std::uint64_t>(std::max(0.0, status.time) * 1e9);
  const JsonMessage stamp = stampOf(status.time);
  for (std::size_t r = 0; r < robots_ && r < status.nodes.size(); ++r) {
    const robot::RobotNode& node = *status.nodes[r];
    const auto& keyframes = node.keyframes();
    JsonMessage poses = JsonMessage::array();
    for (const core::Keyframe& k : keyframes) poses.push_back(poseJson(node.estimate(k.id)));
    server_.publish(
        channel(r, 0), stamp_ns,
        JsonMessage{{"timestamp", stamp}, {"frame_id", "map"}, {"poses", poses}}.dump());
    // The newest keyframe's scan where the robot is now thought to have taken it.
    if (!keyframes.empty() && keyframes.size() != scans_published_[r]) {
      scans_published_[r] = keyframes.size();
      const core::Keyframe& k = keyframes.back();
      server_.publish(channel(r, 1), stamp_ns,
                      pointCloudJson(stamp, node.estimate(k.id), k.cloud.points).dump());
    }
    if (map_due && !keyframes.empty() && server_.subscribed(channel(r, 4)))
      server_.publish(channel(r, 4), stamp_ns,
                      pointCloudJson(stamp, Eigen::Isometry3d::Identity(), mapOf(node)).dump());
    // The accepted inter-robot loops, a line each between its two keyframes.
    if (loops_due) {
      const backend::PoseGraph graph = node.graph();
      JsonMessage points = JsonMessage::array();
      for (const robot::InterLoop& loop : node.interLoops()) {
        if (!loop.accepted || !graph.hasNode(loop.factor.from) || !graph.hasNode(loop.factor.to))
          continue;
        for (const auto& key : {loop.factor.from, loop.factor.to}) {
          const Eigen::Vector3d p = graph.estimate(key).translation();
          points.push_back({{"x", p.x()}, {"y", p.y()}, {"z", p.z()}});
        }
      }
      JsonMessage line = {{"type", 2},  // LINE_LIST
                          {"pose", poseJson(Eigen::Isometry3d::Identity())},
                          {"thickness", 0.3},
                          {"scale_invariant", false},
                          {"points", points},
                          {"color", {{"r", 0.17}, {"g", 0.63}, {"b", 0.17}, {"a", 1.0}}},
                          {"colors", JsonMessage::array()},
                          {"indices", JsonMessage::array()}};
      JsonMessage entity = {{"timestamp", stamp},
                            {"frame_id", "map"},
                            {"id", status.robots[r].name + "/loops"},
                            {"lifetime", {{"sec", 0}, {"nsec", 0}}},
                            {"frame_locked", false},
                            {"metadata", JsonMessage::array()},
                            {"lines", JsonMessage::array({line})}};
      for (const char* none :
           {"arrows", "cubes", "spheres", "cylinders", "triangles", "texts", "models"})
        entity[none] = JsonMessage::array();
      server_.publish(channel(r, 2), stamp_ns,
                      JsonMessage{{"deletions", JsonMessage::array()},
                                  {"entities", JsonMessage::array({entity})}}
                          .dump());
    }
    const swarm::RobotProgress& p = status.robots[r];
    server_.publish(channel(r, 3), stamp_ns,
                    JsonMessage{{"time", status.time},
                                {"frames", p.frames},
                                {"keyframes", p.keyframes},
                                {"inter_loops", p.inter_loops},
                                {"bytes_sent", p.bytes_sent}}
                        .dump());
  }
}

}  // namespace dcl::apps
